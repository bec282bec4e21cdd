//! Soak tier in scaled time: a day of a simulated MIP unit at 1 kHz through imud's offline path
//! (`imud::offline::record`, what `imud --sim SCENARIO --offline` runs): the real decode,
//! calibration, health monitor and MCAP logging with size rotation, fed as fast as the CPU
//! allows. The pipeline cannot tell: its clock is the samples' own stamps (the scenario's
//! device clock and a synthetic host clock), and nothing in it waits on the wall clock.
//! Shared-memory publishing is not on this path (the real-time soak, `soak.rs`, covers it).
//!
//! The recording runs in a process of its own (`soak_offline_record`), so its resident memory
//! is the recorder's alone; meanwhile this test reads back each rotated file as soon as the
//! recorder has closed it, checks it and deletes it, so a day's 12 GB never sit on the disk at
//! once: when two closed files wait for the read-back, the recording is paused (SIGSTOP, then
//! SIGCONT once they are read; in scaled time the pipeline cannot tell), so at most three files
//! are on the disk.
//!
//! `IMUD_SOAK_OFFLINE_S` seconds of scenario (600 by default: CI's short version; BENCHMARKS.md
//! records the 24 h equivalent, 86,400 s). Checks: every sample of the truth (sample k at
//! k ms of device time, k = 0..N-1) recorded exactly once, in order, none counted lost or
//! dropped; resident memory flat after warm-up; every rotated file complete (summary, chunk
//! index, statistics agreeing with a read of every record by our reader; Python `mcap` reads
//! every file's summary and every message of the first and last file).

use std::io::Read;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use imu_bus::recording::{RecordedMessage, for_each_record, list_recordings};
use imud_e2e::{rss_kib, summary_with_chunk_index};

/// The simulated unit's rate.
const RATE_HZ: f64 = 1000.0;
/// Resident memory may move by this much after warm-up (allocator noise, the recorder's buffers
/// reaching their working size); a leak of 8 bytes per sample would exceed it within 10 minutes
/// of scenario time.
const RSS_BOUND_KIB: u64 = 8192;
/// The instance name, the recordings' file name prefix.
const PREFIX: &str = "soak-offline";
/// The recording is paused while this many files (the open one included) are on the disk.
const MAX_FILES: usize = 3;

/// Sends `signal` (`STOP`, `CONT`) to the recording process `pid`.
fn signal(pid: u32, signal: &str) {
    let status = Command::new("kill")
        .arg(format!("-{signal}"))
        .arg(pid.to_string())
        .status()
        .unwrap();
    assert!(status.success(), "kill -{signal} {pid}: {status}");
}

/// Bytes of the files in `dir` now (a file deleted while listed counts nothing).
fn disk_bytes(dir: &Path) -> u64 {
    std::fs::read_dir(dir).map_or(0, |d| {
        d.filter_map(|e| e.ok()?.metadata().ok())
            .map(|m| m.len())
            .sum()
    })
}

/// Python `mcap` reads `file`'s summary (which fails without footer or summary) and chunk
/// index, and with `whole` every message through that index: the file's message count (its
/// statistics, or the messages read), or `None` when Python `mcap` is missing.
fn python_count(file: &Path, whole: bool) -> Option<u64> {
    let script = "import sys\nfrom mcap.reader import make_reader\n\
                  p, whole = sys.argv[1], sys.argv[2] == 'whole'\n\
                  with open(p, 'rb') as f:\n\
                  \x20   r = make_reader(f)\n\
                  \x20   s = r.get_summary()\n\
                  \x20   assert s is not None and s.chunk_indexes, p + ': no summary or index'\n\
                  \x20   print(sum(1 for _ in r.iter_messages()) if whole \
                  else s.statistics.message_count)\n";
    let out = Command::new("python3")
        .args(["-c", script])
        .arg(file)
        .arg(if whole { "whole" } else { "summary" })
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
        panic!("Python mcap on {}: {err}", file.display());
    }
    Some(String::from_utf8_lossy(&out.stdout).trim().parse().unwrap())
}

/// What the read-back has established so far, file by file in rotation order.
#[derive(Debug, Default)]
struct ReadBack {
    /// The next sample expected (every one before it was recorded once, in order).
    next_seq: u64,
    /// Device time of sample 0, ns.
    t0_device_ns: Option<u64>,
    /// The most the daemon's status counted lost or dropped from the log.
    lost: u64,
    /// Each file read: its size and message count.
    files: Vec<(u64, u64)>,
    /// Files Python `mcap` read (0 when it is missing).
    python_files: usize,
}

impl ReadBack {
    /// Reads the closed file `f` with our reader (every record against the truth; its summary,
    /// chunk index and statistics against that read) and Python `mcap` (every message when
    /// `whole`), then deletes it.
    fn check_and_delete(&mut self, f: &Path, whole: bool) {
        let size = std::fs::metadata(f).unwrap().len();
        let stats = summary_with_chunk_index(f).stats.expect("statistics");
        let read = for_each_record(f, |m| match m {
            RecordedMessage::Raw(r) => {
                assert_eq!(
                    r.seq,
                    self.next_seq,
                    "{}: samples recorded once, in order",
                    f.display()
                );
                // The truth: sample k at k ms of the device's clock.
                let t0 = *self.t0_device_ns.get_or_insert(r.t_device_ns);
                // (within 1 us: the device clock is stamped from float seconds, rounded to ns;
                // a missing or repeated sample is 1 ms off).
                let off_ns = (r.t_device_ns - t0).abs_diff(r.seq * 1_000_000);
                assert!(off_ns <= 1_000, "seq {}: {off_ns} ns off the truth", r.seq);
                self.next_seq += 1;
            }
            RecordedMessage::Status { status, .. } => {
                self.lost = self.lost.max(status.samples_lost + status.log_drops);
            }
            _ => {}
        })
        .unwrap();
        assert!(
            read.unfinished.is_none() && read.stopped_early.is_none(),
            "{}: {read:?}",
            f.display()
        );
        assert_eq!(stats.message_count, read.n_messages, "{}", f.display());
        if let Some(n) = python_count(f, whole || self.files.is_empty()) {
            assert_eq!(
                n,
                stats.message_count,
                "{}: Python mcap's count",
                f.display()
            );
            self.python_files += 1;
        }
        self.files.push((size, stats.message_count));
        std::fs::remove_file(f).unwrap();
    }
}

/// The recording process, killed if the test ends before it does (a failed check must not
/// leave it filling the disk).
struct Recording(Child);

impl Drop for Recording {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
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
    std::fs::create_dir_all(&logs).unwrap();
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
    // A sample is about 1 KiB of records before compression (rotation counts the open chunk
    // uncompressed): about a dozen files at the short length, one every 9 minutes of the day.
    let rotate_mib = (soak_s / 12).clamp(8, 512);
    let config = tmp.path().join("soak-offline.toml");
    std::fs::write(
        &config,
        format!(
            "name = \"{PREFIX}\"\n[log]\ndir = \"{}\"\nrotate-size-mib = {rotate_mib}\n\
             [health]\nenabled = true\n",
            logs.display()
        ),
    )
    .unwrap();

    // The read-back: every file but the newest is closed (the recorder finishes a file before
    // it opens the next); once the recording has ended, the newest is too.
    let (ended, recording_ended) = mpsc::channel::<()>();
    let (checker_alive, checker_gone) = mpsc::channel::<()>();
    let checker_logs = logs.clone();
    let checker = std::thread::spawn(move || {
        let _alive = checker_alive;
        let mut read_back = ReadBack::default();
        loop {
            let finished = !matches!(
                recording_ended.recv_timeout(Duration::from_millis(500)),
                Err(mpsc::RecvTimeoutError::Timeout)
            );
            let files = list_recordings(&checker_logs, PREFIX).unwrap();
            let closed = if finished {
                files.len()
            } else {
                files.len().saturating_sub(1)
            };
            for (i, f) in files[..closed].iter().enumerate() {
                read_back.check_and_delete(f, finished && i + 1 == closed);
            }
            if finished {
                return read_back;
            }
        }
    });

    let started = Instant::now();
    let mut recording = Recording(
        Command::new(env!("CARGO_BIN_EXE_soak_offline_record"))
            .arg(&scenario)
            .arg(&config)
            .stdout(Stdio::piped())
            .spawn()
            .unwrap(),
    );
    let pid = recording.0.id();
    // Resident memory and disk use, sampled every second of the run (the checker's channel's
    // timeout is the tick; it closes early only if a check failed).
    let (mut rss, mut peak_disk) = (Vec::new(), 0u64);
    let (mut paused_since, mut paused_s) = (None::<Instant>, 0.0);
    let status = loop {
        if let Some(status) = recording.0.try_wait().unwrap() {
            break status;
        }
        if let Some(kib) = rss_kib(pid) {
            rss.push((started.elapsed().as_secs_f64(), kib));
        }
        peak_disk = peak_disk.max(disk_bytes(&logs));
        let on_disk = list_recordings(&logs, PREFIX).unwrap().len();
        match paused_since {
            None if on_disk >= MAX_FILES => {
                signal(pid, "STOP");
                paused_since = Some(Instant::now());
            }
            Some(t) if on_disk < MAX_FILES => {
                signal(pid, "CONT");
                paused_s += t.elapsed().as_secs_f64();
                paused_since = None;
            }
            _ => {}
        }
        if !matches!(
            checker_gone.recv_timeout(Duration::from_secs(1)),
            Err(mpsc::RecvTimeoutError::Timeout)
        ) {
            // A check failed: stop the recording and report the failure.
            drop(recording);
            std::panic::resume_unwind(checker.join().unwrap_err());
        }
    };
    let run_s = started.elapsed().as_secs_f64();
    let mut out = String::new();
    recording
        .0
        .stdout
        .take()
        .unwrap()
        .read_to_string(&mut out)
        .unwrap();
    assert!(status.success(), "the recording failed: {status}");
    assert_eq!(out.trim(), format!("samples {n_samples}"));
    drop(ended);
    let read_back = checker
        .join()
        .unwrap_or_else(|e| std::panic::resume_unwind(e));
    let checked_s = started.elapsed().as_secs_f64();

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
    assert!(read_back.files.len() >= 2, "no rotation: {read_back:?}");
    assert_eq!(
        read_back.next_seq, n_samples,
        "every sample of the truth recorded"
    );
    assert_eq!(
        read_back.lost, 0,
        "the daemon's status counted samples lost or log drops"
    );
    let total_bytes: u64 = read_back.files.iter().map(|f| f.0).sum();
    // RSS every tenth of the run, for the record.
    let step = (rss.len() / 10).max(1);
    let timeline: Vec<String> = rss
        .iter()
        .step_by(step)
        .map(|(t, kib)| format!("{t:.0} s: {:.1}", *kib as f64 / 1024.0))
        .collect();
    eprintln!(
        "offline soak: {soak_s} s of scenario ({n_samples} samples at 1 kHz) recorded in \
         {run_s:.0} s (paused {paused_s:.0} s for the read-back), all read back by \
         {checked_s:.0} s; {} files, {:.2} GB, {} messages \
         (Python mcap read {} of them); peak disk {:.2} GB; recorder RSS (MiB) {}; spread \
         {spread:?} KiB after {:.0} s",
        read_back.files.len(),
        total_bytes as f64 / 1e9,
        read_back.files.iter().map(|f| f.1).sum::<u64>(),
        read_back.python_files,
        peak_disk as f64 / 1e9,
        timeline.join(", "),
        run_s / 4.0
    );
}
