//! Soak tier: `imud --sim` on a simulated MIP unit streaming at 1 kHz in real time, with logging
//! (rotating files), publishing and the health monitor on, for `IMUD_SOAK_S` seconds (120 by
//! default: CI's short version; BENCHMARKS.md records the long run and its command). Checks:
//! every sample published reaches a subscriber with no gap in `seq`, the daemon drops or fails
//! to publish none and counts no loss beyond the samples the simulated unit skipped (its truth
//! file's gaps), its resident memory stays flat after warm-up, and every rotated file has its
//! summary and chunk index, together holding every sample exactly once.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use imu_bus::RawSample;
use imu_bus::mcap_read::for_each_message;
use imu_bus::recording::read_recording;
use imu_bus::shm::Subscription;
use imud_e2e::{rss_kib, summary_with_chunk_index};

/// The simulated unit's rate.
const RATE_HZ: f64 = 1000.0;
/// Resident memory may move by this much after warm-up (allocator noise, buffers reaching their
/// working size); a leak of one allocation per sample or per record would exceed it within
/// seconds at 1 kHz.
const RSS_BOUND_KIB: u64 = 4096;

fn imud() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let path = exe.parent().unwrap().parent().unwrap().join("imud");
    assert!(
        path.exists(),
        "{} is missing: build it first (cargo build -p imud)",
        path.display()
    );
    path
}

struct Daemon(Child);

impl Drop for Daemon {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn recordings(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            let n = p.file_name().unwrap().to_string_lossy().into_owned();
            n.ends_with(".mcap") && !n.contains("truth")
        })
        .collect();
    files.sort();
    files
}

/// Samples the simulated unit skipped, from the gaps between its truth file's data records.
fn truth_gaps(dir: &Path) -> u64 {
    let truth: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.to_string_lossy().ends_with(".mcap") && p.to_string_lossy().contains("truth"))
        .collect();
    assert_eq!(
        truth.len(),
        1,
        "one truth file in {}: {truth:?}",
        dir.display()
    );
    let (mut gaps, mut last_t_s) = (0u64, None::<f64>);
    imu_bus::truth::read_truth_streaming(
        &truth[0],
        |s| {
            if imu_bus::truth::is_data_command(s.command) {
                if let Some(t) = last_t_s {
                    gaps += ((s.t_s - t) * RATE_HZ).round().max(1.0) as u64 - 1;
                }
                last_t_s = Some(s.t_s);
            }
        },
        |_| {},
    )
    .unwrap();
    assert!(
        last_t_s.is_some(),
        "no data record in {}",
        truth[0].display()
    );
    gaps
}

#[test]
fn imud_at_1_khz_loses_nothing_keeps_its_memory_and_rotates_intact_files() {
    let soak_s: f64 = std::env::var("IMUD_SOAK_S")
        .ok()
        .map_or(120.0, |s| s.parse().expect("IMUD_SOAK_S is seconds"));
    let warm_up_s = (soak_s / 4.0).max(10.0);
    let rotate_s = (soak_s / 4.0).max(10.0);
    let tmp = tempfile::tempdir().unwrap();
    let logs = tmp.path().join("logs");
    let scenario = tmp.path().join("soak.toml");
    std::fs::write(
        &scenario,
        format!(
            "name = \"soak\"\nrate-hz = {RATE_HZ}\n[device]\nprotocol = \"mip\"\n\
             [[segment]]\nkind = \"static\"\norientation = {{ x = \"north\", z = \"up\" }}\n"
        ),
    )
    .unwrap();
    let config = tmp.path().join("imud.toml");
    std::fs::write(
        &config,
        format!(
            "[log]\ndir = \"{}\"\nrotate-size-mib = 0\nrotate-interval-s = {rotate_s}\n\
             [publish]\nsubscriber-buffer = 4096\n[health]\nenabled = true\n",
            logs.display()
        ),
    )
    .unwrap();
    let name = format!("soak-{}", std::process::id());
    let stderr = tmp.path().join("imud.stderr");
    let child = Command::new(imud())
        .args(["--name", &name, "--config"])
        .arg(&config)
        .arg("--sim")
        .arg(&scenario)
        .env_remove("IMUD_CONFIG")
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&stderr).unwrap())
        .spawn()
        .unwrap();
    let pid = child.id();
    let mut daemon = Daemon(child);

    let mut raw = Subscription::<RawSample>::open(&name, Duration::from_secs(30)).unwrap();
    let mut status =
        Subscription::<imu_bus::DaemonStatus>::open(&name, Duration::from_secs(30)).unwrap();
    let started = Instant::now();
    let mut batch = Vec::with_capacity(4096);
    let (mut first_seq, mut last_seq) = (None, 0u64);
    let mut rss: Vec<(f64, u64)> = Vec::new();
    let mut next_rss_s = 0.0;
    let mut last_status = None;
    while started.elapsed().as_secs_f64() < soak_s {
        batch.clear();
        raw.wait_into(Duration::from_millis(100), &mut batch)
            .unwrap();
        if let (None, Some(s)) = (first_seq, batch.first()) {
            first_seq = Some(s.seq);
        }
        if let Some(s) = batch.last() {
            last_seq = s.seq;
        }
        let mut statuses = Vec::new();
        status.drain_into(&mut statuses).unwrap();
        if let Some(s) = statuses.pop() {
            last_status = Some(s);
        }
        let t = started.elapsed().as_secs_f64();
        if t >= next_rss_s {
            rss.push((t, rss_kib(pid).expect("imud runs")));
            next_rss_s += 1.0;
        }
    }
    // The final status (published about once a second) covers all but the last second.
    let deadline = Instant::now() + Duration::from_secs(5);
    while Instant::now() < deadline {
        if let Some(s) = status.wait(Duration::from_millis(200)).unwrap().pop() {
            last_status = Some(s);
            break;
        }
    }
    Command::new("kill")
        .args(["-TERM", &pid.to_string()])
        .status()
        .unwrap();
    let exit = daemon.0.wait().unwrap();
    let log = std::fs::read_to_string(&stderr).unwrap_or_default();
    assert!(exit.success(), "imud exited with {exit}: {log}");

    // The figures, before any check (a long run's record, pass or fail): RSS every tenth of
    // the run.
    let first_seq = first_seq.expect("samples arrived");
    let received = raw.received();
    let skipped_by_device = truth_gaps(&logs);
    let step = (rss.len() / 10).max(1);
    let timeline: Vec<String> = rss
        .iter()
        .step_by(step)
        .map(|(t, kib)| format!("{t:.0} s: {:.1}", *kib as f64 / 1024.0))
        .collect();
    eprintln!(
        "soak: {soak_s} s, {received} samples received (seq {first_seq}..={last_seq}, {} missed \
         at the subscriber); last status {last_status:?}; the device skipped \
         {skipped_by_device}; imud RSS (MiB) {}",
        raw.missed(),
        timeline.join(", ")
    );

    // Every sample reached the subscriber, at the unit's rate.
    assert_eq!(raw.missed(), 0, "seq gaps at the subscriber");
    assert_eq!(received, last_seq - first_seq + 1);
    // (less the samples the simulated unit skipped: they never reached the link, see below).
    let expected = (soak_s - 2.0) * RATE_HZ - skipped_by_device as f64;
    assert!(
        received as f64 >= expected,
        "{received} samples in {soak_s} s: {log}"
    );

    // The daemon dropped and failed to publish nothing, and it counted as lost no sample the
    // device sent: the simulated unit, like a real one, skips a sample when the host leaves its
    // link backlog full (a loaded machine can), and its truth file holds only the samples it
    // sent, so a skip is a gap there. imud's count, from the device's timestamps, must not
    // exceed those gaps (its last status may miss the final second's).
    let s = last_status.expect("a status arrived");
    assert_eq!((s.log_drops, s.publish_drops), (0, 0), "{s:?}");
    assert!(
        s.samples_lost <= skipped_by_device,
        "imud counted {} lost, the device skipped {skipped_by_device}: {s:?}",
        s.samples_lost
    );

    // Resident memory flat after warm-up: the spread of the samples after it within the bound.
    let after: Vec<u64> = rss
        .iter()
        .filter(|(t, _)| *t >= warm_up_s)
        .map(|r| r.1)
        .collect();
    assert!(after.len() >= 5, "{rss:?}");
    let spread = after.iter().max().unwrap() - after.iter().min().unwrap();
    assert!(
        spread <= RSS_BOUND_KIB,
        "RSS after warm-up moved {spread} KiB: {rss:?}"
    );

    // Rotation happened, and each file is complete: its summary's message count equals what a
    // read of every record finds, and it has a chunk index.
    let files = recordings(&logs);
    assert!(
        files.len() as f64 >= (soak_s / rotate_s).floor(),
        "{} files for {soak_s} s rotating every {rotate_s} s",
        files.len()
    );
    let mut seqs = Vec::new();
    for f in &files {
        let summary = summary_with_chunk_index(f);
        let report = for_each_message(f, |_, _, _| Ok(())).unwrap();
        assert!(report.unfinished.is_none(), "{}: {report:?}", f.display());
        let stats = summary.stats.expect("statistics");
        assert_eq!(stats.message_count, report.n_messages, "{}", f.display());
        let rec = read_recording(f).unwrap();
        seqs.extend(rec.raw.iter().map(|r| r.seq));
    }
    // Together the files hold every sample once, in order, including all the subscriber saw.
    assert!(
        seqs.windows(2).all(|w| w[1] == w[0] + 1),
        "recorded seq not contiguous"
    );
    assert!(
        seqs.first().is_some_and(|&f| f <= first_seq),
        "{:?}",
        seqs.first()
    );
    assert!(
        seqs.last().is_some_and(|&l| l >= last_seq),
        "{:?}",
        seqs.last()
    );
    eprintln!(
        "soak: {soak_s} s, {received} samples received, {} recorded in {} files, RSS {:?} KiB \
         (spread {spread} KiB after {warm_up_s} s)",
        seqs.len(),
        files.len(),
        (rss.first().map(|r| r.1), rss.last().map(|r| r.1))
    );
}
