//! Soak tier in scaled time: a day of a simulated MIP unit at 1 kHz through imud's offline path
//! (`imud::offline::record`, what `imud --sim SCENARIO --offline` runs): the real decode,
//! calibration, health monitor and MCAP logging with size rotation, fed as fast as the CPU
//! allows. The pipeline cannot tell: its clock is the samples' own stamps (the scenario's
//! device clock and a synthetic host clock), and nothing in it waits on the wall clock.
//! Shared-memory publishing is not on this path (the real-time soak, `soak.rs`, covers it).
//!
//! `IMUD_SOAK_OFFLINE_S` seconds of scenario (600 by default: CI's short version; BENCHMARKS.md
//! records the 24 h equivalent, 86,400 s). Checks: every sample of the truth (sample k at
//! k ms of device time, k = 0..N-1) recorded exactly once, in order, none counted lost or
//! dropped; resident memory flat after warm-up; every rotated file complete (summary, chunk
//! index, statistics agreeing with a read of every record, by our reader and by Python `mcap`).

use std::path::PathBuf;
use std::process::Command;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use imu_bus::mcap_read::for_each_message;
use imu_bus::recording::{RecordedMessage, for_each_record};

/// The simulated unit's rate.
const RATE_HZ: f64 = 1000.0;
/// Resident memory may move by this much after warm-up (allocator noise, the recorder's buffers
/// reaching their working size); a leak of 8 bytes per sample would exceed it within 10 minutes
/// of scenario time.
const RSS_BOUND_KIB: u64 = 8192;

fn rss_kib() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// Python `mcap` reads every file's summary (which fails without footer or summary) and chunk
/// index, and every message of the first and last file through that index: the message count
/// of each file (its statistics, or the messages read), or `None` when Python `mcap` is missing.
fn python_counts(files: &[PathBuf]) -> Option<Vec<u64>> {
    let script = "import sys\nfrom mcap.reader import make_reader\n\
                  paths = sys.argv[1:]\n\
                  for i, p in enumerate(paths):\n\
                  \x20   with open(p, 'rb') as f:\n\
                  \x20       r = make_reader(f)\n\
                  \x20       s = r.get_summary()\n\
                  \x20       assert s is not None and s.chunk_indexes, p + ': no summary or index'\n\
                  \x20       whole = i == 0 or i == len(paths) - 1\n\
                  \x20       n = sum(1 for _ in r.iter_messages()) if whole \
                  else s.statistics.message_count\n\
                  \x20       print(n)\n";
    let out = Command::new("python3")
        .args(["-c", script])
        .args(files)
        .output()
        .ok()?;
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        if err.contains("No module named") {
            assert!(
                std::env::var_os("IMUD_REQUIRE_PEERS").is_none(),
                "Python mcap missing: {err}"
            );
            return None;
        }
        panic!("Python mcap: {err}");
    }
    Some(
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .map(|l| l.trim().parse().unwrap())
            .collect(),
    )
}

#[test]
fn a_scaled_day_at_1_khz_loses_nothing_keeps_its_memory_and_rotates_intact_files() {
    let soak_s: u64 = std::env::var("IMUD_SOAK_OFFLINE_S").ok().map_or(600, |s| {
        s.parse().expect("IMUD_SOAK_OFFLINE_S is whole seconds")
    });
    assert!(soak_s >= 120 && soak_s.is_multiple_of(24), "{soak_s}");
    let n_samples = soak_s * RATE_HZ as u64;
    let tmp = tempfile::tempdir().unwrap();
    let logs = tmp.path().join("logs");
    // Rest and motion (random poses: 20 s still, 4 s moving) so the health monitor has still
    // windows to judge all day.
    let scenario = tmp.path().join("soak.toml");
    std::fs::write(
        &scenario,
        format!(
            "name = \"soak-offline\"\nrate-hz = {RATE_HZ}\n[device]\nprotocol = \"mip\"\n\
             [[segment]]\nkind = \"random-poses\"\ncount = {}\ndwell-s = 20.0\nmove-s = 4.0\n",
            soak_s / 24
        ),
    )
    .unwrap();
    let sim = imu_sim::SimOptions::from_files(&scenario, None).unwrap();
    // A sample is about 1 KiB of records before compression (rotation counts the open chunk
    // uncompressed): about a dozen files at the short length, one every 9 minutes of the day.
    let rotate_mib = (soak_s / 12).clamp(8, 512);
    let config = imud::config::Config::from_toml_str(
        &format!(
            "name = \"soak-offline\"\n[log]\ndir = \"{}\"\nrotate-size-mib = {rotate_mib}\n\
         [health]\nenabled = true\n",
            logs.display()
        ),
        "soak-offline.toml",
    )
    .unwrap();

    // Resident memory, sampled every second of the run (the channel's timeout is the tick).
    let (stop, ticks) = mpsc::channel::<()>();
    let sampler = std::thread::spawn(move || {
        let start = Instant::now();
        let mut rss = Vec::new();
        while let Err(mpsc::RecvTimeoutError::Timeout) = ticks.recv_timeout(Duration::from_secs(1))
        {
            rss.push((start.elapsed().as_secs_f64(), rss_kib().unwrap_or(0)));
        }
        rss
    });
    let started = Instant::now();
    let report = imud::offline::record(sim, &config).unwrap();
    let run_s = started.elapsed().as_secs_f64();
    drop(stop);
    let rss = sampler.join().unwrap();
    assert_eq!(report.samples, n_samples);

    // Flat after warm-up (the first quarter of the run).
    let after: Vec<u64> = rss
        .iter()
        .filter(|(t, _)| *t >= run_s / 4.0)
        .map(|r| r.1)
        .collect();
    let spread = after
        .iter()
        .max()
        .zip(after.iter().min())
        .map(|(a, b)| a - b);
    assert!(
        spread.is_none_or(|s| s <= RSS_BOUND_KIB),
        "RSS after warm-up moved {spread:?} KiB: {rss:?}"
    );

    // Every file complete; together every sample of the truth once, in order.
    let files: Vec<PathBuf> = report.files.clone();
    assert!(files.len() >= 2, "no rotation: {files:?}");
    let (mut next_seq, mut t0_device_ns) = (0u64, None::<u64>);
    let mut lost = 0;
    let mut counts = Vec::new();
    for f in &files {
        let bytes = std::fs::read(f).unwrap();
        let summary = mcap::Summary::read(&bytes)
            .unwrap()
            .unwrap_or_else(|| panic!("{}: no summary", f.display()));
        assert!(
            !summary.chunk_indexes.is_empty(),
            "{}: no chunk index",
            f.display()
        );
        let stats = summary.stats.expect("statistics");
        drop(bytes);
        let read = for_each_record(f, |m| match m {
            RecordedMessage::Raw(r) => {
                assert_eq!(
                    r.seq,
                    next_seq,
                    "{}: samples recorded once, in order",
                    f.display()
                );
                // The truth: sample k at k ms of the device's clock.
                let t0 = *t0_device_ns.get_or_insert(r.t_device_ns);
                // (within 1 us: the device clock is stamped from float seconds, rounded to ns;
                // a missing or repeated sample is 1 ms off).
                let off_ns = (r.t_device_ns - t0).abs_diff(r.seq * 1_000_000);
                assert!(off_ns <= 1_000, "seq {}: {off_ns} ns off the truth", r.seq);
                next_seq += 1;
            }
            RecordedMessage::Status { status, .. } => {
                lost = lost.max(status.samples_lost + status.log_drops);
            }
            _ => {}
        })
        .unwrap();
        assert!(read.unfinished.is_none(), "{}: {read:?}", f.display());
        let all = for_each_message(f, |_, _, _| Ok(())).unwrap();
        assert_eq!(stats.message_count, all.n_messages, "{}", f.display());
        counts.push(stats.message_count);
    }
    let python = python_counts(&files);
    if let Some(p) = &python {
        assert_eq!(p, &counts, "Python mcap's message counts");
    }
    assert_eq!(next_seq, n_samples, "every sample of the truth recorded");
    assert_eq!(
        lost, 0,
        "the daemon's status counted samples lost or log drops"
    );
    eprintln!(
        "offline soak: {soak_s} s of scenario ({n_samples} samples at 1 kHz) in {run_s:.0} s, \
         {} files (read by Python mcap: {}), RSS {:?} -> {:?} KiB (spread {spread:?} \
         KiB after {:.0} s)",
        files.len(),
        python.is_some(),
        rss.first().map(|r| r.1),
        rss.last().map(|r| r.1),
        run_s / 4.0
    );
}
