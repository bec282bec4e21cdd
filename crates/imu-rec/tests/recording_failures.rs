//! The recorder when things go wrong: queue overflow, an unusable directory, write errors (a
//! simulated full disk and a real full tmpfs) with recovery, and a writer process killed with
//! SIGKILL (the file readable up to its last flush).

mod recording_common;

use std::fs::File;
use std::io::{self, BufRead, BufReader, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicI64, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;

use imu_rec::recording::{
    LogRecord, Recorder, RecorderStats, RecordingSink, SinkOpener, list_recordings, read_recording,
};
use recording_common::*;

/// Records the recorder has accounted for: written or dropped.
fn accounted(s: &RecorderStats) -> u64 {
    s.written + s.dropped_queue_full + s.dropped_not_logging
}

struct Gate {
    state: Mutex<(bool, bool)>, // (open, a write is waiting)
    cv: Condvar,
}

impl Gate {
    fn open(&self) {
        self.state.lock().unwrap().0 = true;
        self.cv.notify_all();
    }
}

struct GateGuard(Arc<Gate>);

impl Drop for GateGuard {
    fn drop(&mut self) {
        self.0.open();
    }
}

struct GateSink {
    file: File,
    gate: Arc<Gate>,
}

impl Write for GateSink {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let mut state = self.gate.state.lock().unwrap();
        while !state.0 {
            state.1 = true;
            self.gate.cv.notify_all();
            state = self.gate.cv.wait(state).unwrap();
        }
        drop(state);
        self.file.write(buf)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.file.flush()
    }
}

impl Seek for GateSink {
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        self.file.seek(pos)
    }
}

#[test]
fn a_full_queue_drops_and_counts_without_blocking_the_caller() {
    let dir = tempfile::tempdir().unwrap();
    let gate = Arc::new(Gate {
        state: Mutex::new((true, false)),
        cv: Condvar::new(),
    });
    let opener: SinkOpener = {
        let gate = gate.clone();
        Box::new(move |path: &Path| {
            let file = File::options().write(true).create_new(true).open(path)?;
            Ok(Box::new(GateSink {
                file,
                gate: gate.clone(),
            }) as Box<dyn RecordingSink>)
        })
    };
    let mut config = test_config(dir.path());
    config.queue_capacity = 8;
    let rec = Recorder::start_with_sink(config, Vec::new(), opener).unwrap();
    // Dropped before `rec` if an assertion fails, so the writer can finish instead of hanging.
    let _reopen = GateGuard(gate.clone());
    gate.state.lock().unwrap().0 = false;
    assert!(rec.log(LogRecord::Raw(raw(0))));
    // The writer flushes that record and stalls in the sink; from here on it takes nothing
    // from the queue.
    {
        let mut state = gate.state.lock().unwrap();
        while !state.1 {
            state = gate.cv.wait(state).unwrap();
        }
    }
    for seq in 1..=8 {
        assert!(rec.log(LogRecord::Raw(raw(seq))), "record {seq} fits");
    }
    for seq in 9..14 {
        assert!(
            !rec.log(LogRecord::Raw(raw(seq))),
            "record {seq} must be dropped"
        );
    }
    let stalled = rec.stats();
    assert_eq!(stalled.dropped_queue_full, 5);
    // Record 0 is in the writer's hands (stalled mid-write or mid-flush), not in the queue.
    assert!(stalled.written <= 1);
    gate.open();
    let stats = rec.finish().unwrap();
    assert_eq!((stats.written, stats.dropped_queue_full), (9, 5));
    assert_eq!(accounted(&stats), 14);
    let file = &list_recordings(dir.path(), "test").unwrap()[0];
    let seqs: Vec<u64> = read_recording(file)
        .unwrap()
        .raw
        .iter()
        .map(|s| s.seq)
        .collect();
    assert_eq!(seqs, (0..9).collect::<Vec<_>>());
}

#[test]
fn an_unusable_directory_starts_without_logging_and_counts_drops() {
    let dir = tempfile::tempdir().unwrap();
    let not_a_dir = dir.path().join("plain-file");
    std::fs::write(&not_a_dir, b"x").unwrap();
    let rec = Recorder::start(test_config(&not_a_dir), Vec::new()).unwrap();
    let stats = rec.stats();
    assert!(!stats.logging);
    let err = stats.last_error.unwrap();
    assert!(
        err.contains("plain-file") && err.contains("cannot create"),
        "{err}"
    );
    assert!(rec.log(LogRecord::Raw(raw(0))));
    let stats = rec.finish().unwrap();
    assert_eq!((stats.written, stats.dropped_not_logging), (0, 1));
    assert_eq!(stats.files_started, 0);
}

/// A sink on a disk with `budget` bytes left: writes beyond it fail as a full disk does.
struct BudgetSink {
    file: File,
    budget: Arc<AtomicI64>,
}

impl Write for BudgetSink {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let left = self.budget.load(Ordering::SeqCst);
        if left <= 0 {
            return Err(io::Error::new(
                io::ErrorKind::StorageFull,
                "no space left on device (simulated)",
            ));
        }
        let n = buf.len().min(left as usize);
        let n = self.file.write(&buf[..n])?;
        self.budget.fetch_sub(n as i64, Ordering::SeqCst);
        Ok(n)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.file.flush()
    }
}

impl Seek for BudgetSink {
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        self.file.seek(pos)
    }
}

/// Pseudo-random (incompressible) bytes, so a disk fills at a predictable pace.
fn noise_bytes(seed: u64, n: usize) -> Vec<u8> {
    let mut x = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    (0..n)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x as u8
        })
        .collect()
}

fn big_frame(seq: u64) -> LogRecord {
    LogRecord::RawFrame {
        t_host_wall_ns: T0_WALL_NS + seq * DT_NS,
        t_host_monotonic_ns: seq,
        stream_offset: seq * 1000,
        accepted: false,
        reject_reason: Some("garbage".into()),
        bytes: noise_bytes(seq, 1000).into(),
    }
}

/// Logs raw samples and big frames from `*seq` on until logging stops; returns the stats then.
fn log_until_logging_stops(rec: &Recorder, seq: &mut u64, logged: &mut u64) -> RecorderStats {
    for _ in 0..10_000 {
        for _ in 0..10 {
            assert!(rec.log(LogRecord::Raw(raw(*seq))));
            assert!(rec.log(big_frame(*seq)));
            *seq += 1;
            *logged += 2;
        }
        wait_until("the queue drains", || accounted(&rec.stats()) == *logged);
        let stats = rec.stats();
        if !stats.logging {
            return stats;
        }
    }
    panic!("the disk never filled up");
}

/// What the file that hit the full disk must hold: a gap-free prefix of what was logged, at
/// least everything flushed before the failure, and no summary.
fn check_failed_file(path: &Path, flushed_before_failure: u64) {
    let got = read_recording(path).unwrap();
    assert!(
        got.stopped_early.is_some(),
        "a file that hit a full disk has no footer"
    );
    for (i, s) in got.raw.iter().enumerate() {
        assert_eq!(*s, raw(i as u64), "raw samples must be a gap-free prefix");
    }
    assert!(
        (got.raw.len() + got.frames.len()) as u64 >= flushed_before_failure,
        "{} + {} records in the file, {flushed_before_failure} were flushed",
        got.raw.len(),
        got.frames.len()
    );
}

#[test]
fn a_full_disk_stops_logging_loudly_and_logging_resumes_when_space_returns() {
    let dir = tempfile::tempdir().unwrap();
    let budget = Arc::new(AtomicI64::new(60_000));
    let opened = Arc::new(AtomicU64::new(0));
    let opener: SinkOpener = {
        let (budget, opened) = (budget.clone(), opened.clone());
        Box::new(move |path: &Path| {
            opened.fetch_add(1, Ordering::SeqCst);
            let file = File::options().write(true).create_new(true).open(path)?;
            Ok(Box::new(BudgetSink {
                file,
                budget: budget.clone(),
            }) as Box<dyn RecordingSink>)
        })
    };
    let rec =
        Recorder::start_with_sink(test_config(dir.path()), device_metadata(), opener).unwrap();
    let first_file = rec.stats().current_file.unwrap();
    let (mut seq, mut logged) = (0, 0);
    let failed = log_until_logging_stops(&rec, &mut seq, &mut logged);
    let err = failed.last_error.clone().unwrap();
    let first_name = first_file.file_name().unwrap().to_str().unwrap();
    assert!(
        err.contains(first_name) && err.contains("no space left on device (simulated)"),
        "{err}"
    );
    assert_eq!(failed.current_file, None);

    // Still full: retries fail.
    let attempts = opened.load(Ordering::SeqCst);
    wait_until("two more attempts", || {
        opened.load(Ordering::SeqCst) >= attempts + 2
    });
    // Records keep being accepted, never blocking, and are counted as dropped.
    for _ in 0..30 {
        assert!(rec.log(LogRecord::Raw(raw(seq))));
        seq += 1;
        logged += 1;
    }
    wait_until("the queue drains", || accounted(&rec.stats()) == logged);
    let during = rec.stats();
    assert!(!during.logging);
    assert_eq!(during.files_started, 1);
    assert!(during.dropped_not_logging >= 30);

    // Space returns: the next retry starts a new file.
    budget.store(100_000_000, Ordering::SeqCst);
    wait_until("logging resumes", || rec.stats().logging);
    let resumed = rec.stats();
    assert_eq!(resumed.files_started, 2);
    let markers = mixed(10_000, 50);
    log_all(&rec, &markers);
    logged += markers.len() as u64;
    let stats = rec.finish().unwrap();
    assert_eq!(accounted(&stats), logged);
    assert_eq!(stats.written, stats.flushed);

    // Two files: the failed attempts in between left nothing behind.
    let files = list_recordings(dir.path(), "test").unwrap();
    assert_eq!(files.len(), 2, "{files:?}");
    assert_eq!(files[0], first_file);
    check_failed_file(&files[0], failed.flushed);
    let second = read_recording(&files[1]).unwrap();
    assert_eq!(second.stopped_early, None);
    assert_eq!(second.metadata["imud.device"]["serial"], "1234");
    assert_same_messages(&second, &expected(&markers, "imu_link"));
}

/// A small tmpfs mounted for one test (needs root); unmounted on drop.
struct Tmpfs {
    dir: tempfile::TempDir,
}

impl Tmpfs {
    fn mount(size: &str) -> Result<Tmpfs, String> {
        let dir = tempfile::tempdir().map_err(|e| e.to_string())?;
        let out = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs"])
            .arg(dir.path())
            .output()
            .map_err(|e| e.to_string())?;
        if !out.status.success() {
            return Err(String::from_utf8_lossy(&out.stderr).trim().to_string());
        }
        Ok(Tmpfs { dir })
    }

    fn path(&self) -> &Path {
        self.dir.path()
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount")
            .arg("-l")
            .arg(self.dir.path())
            .status();
    }
}

/// Writes `path` until the file system is full; returns the bytes written.
fn fill(path: &Path, at_most: usize) -> usize {
    let mut f = File::create(path).unwrap();
    let block = vec![0xA5u8; 4096];
    let mut n = 0;
    while n < at_most {
        match f.write(&block) {
            Ok(0) | Err(_) => break,
            Ok(k) => n += k,
        }
    }
    let _ = f.sync_all();
    n
}

#[test]
fn a_real_full_tmpfs_stops_logging_and_logging_resumes_when_space_returns() {
    let fs = match Tmpfs::mount("1m") {
        Ok(fs) => fs,
        Err(why) => {
            // The simulated full disk above covers the logic; this one needs mount rights.
            eprintln!("skipping the real full-disk test: cannot mount a tmpfs ({why})");
            return;
        }
    };
    let ballast = fs.path().join("ballast");
    assert!(fill(&ballast, 1024 * 1024 - 200 * 1024) > 0);
    let logs = fs.path().join("logs");
    let rec = Recorder::start(test_config(&logs), device_metadata()).unwrap();
    assert!(rec.stats().logging, "{:?}", rec.stats().last_error);
    let first_file = rec.stats().current_file.unwrap();
    let (mut seq, mut logged) = (0, 0);
    let failed = log_until_logging_stops(&rec, &mut seq, &mut logged);
    let err = failed.last_error.clone().unwrap();
    assert!(
        err.contains(first_file.to_str().unwrap()) && err.contains("No space left on device"),
        "{err}"
    );

    // Take whatever is left too, so that retries certainly fail.
    let filler = fs.path().join("filler");
    fill(&filler, usize::MAX);
    std::thread::sleep(Duration::from_millis(200)); // several retry intervals
    for _ in 0..30 {
        assert!(rec.log(LogRecord::Raw(raw(seq))));
        seq += 1;
        logged += 1;
    }
    wait_until("the queue drains", || accounted(&rec.stats()) == logged);
    let during = rec.stats();
    assert!(!during.logging);
    assert_eq!(during.files_started, 1);
    assert!(during.dropped_not_logging >= 30);

    std::fs::remove_file(&ballast).unwrap();
    std::fs::remove_file(&filler).unwrap();
    wait_until("logging resumes", || rec.stats().logging);
    assert_eq!(rec.stats().files_started, 2);
    let markers = mixed(10_000, 50);
    log_all(&rec, &markers);
    logged += markers.len() as u64;
    let stats = rec.finish().unwrap();
    assert_eq!(accounted(&stats), logged);

    // Two files: the failed attempts in between left nothing behind.
    let files = list_recordings(&logs, "test").unwrap();
    assert_eq!(files.len(), 2, "{files:?}");
    assert_eq!(files[0], first_file);
    check_failed_file(&files[0], failed.flushed);
    let second = read_recording(&files[1]).unwrap();
    assert_eq!(second.stopped_early, None);
    assert_same_messages(&second, &expected(&markers, "imu_link"));
}

const CHILD_DIR_ENV: &str = "IMUD_RECORDING_KILL_CHILD_DIR";
const CHILD_RECORDS: u64 = 300;

/// Not a test of its own: the body of the child process that
/// `a_writer_killed_with_sigkill_leaves_a_file_readable_up_to_its_last_flush` starts (this test
/// binary run again with this test selected) and kills. Without the variable it does nothing.
#[test]
fn kill_test_child_process() {
    let Some(dir) = std::env::var_os(CHILD_DIR_ENV) else {
        return;
    };
    let mut config = test_config(Path::new(&dir));
    config.flush_interval = Duration::from_millis(50);
    let rec = Recorder::start(config, device_metadata()).unwrap();
    for seq in 0..CHILD_RECORDS {
        rec.log(LogRecord::Raw(raw(seq)));
        rec.log(frame(seq));
    }
    wait_until("everything is flushed", || {
        rec.stats().flushed == 2 * CHILD_RECORDS
    });
    println!("FLUSHED {CHILD_RECORDS}");
    io::stdout().flush().unwrap();
    // Keep logging like a running daemon until the parent kills us (bounded, in case it dies).
    for seq in CHILD_RECORDS..CHILD_RECORDS + 100_000 {
        rec.log(LogRecord::Raw(raw(seq)));
        rec.log(frame(seq));
        std::thread::sleep(Duration::from_micros(500));
    }
    std::mem::forget(rec);
}

/// Kills the child if the test fails before it does.
struct ChildGuard(std::process::Child);

impl Drop for ChildGuard {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
fn a_writer_killed_with_sigkill_leaves_a_file_readable_up_to_its_last_flush() {
    use std::os::unix::process::ExitStatusExt;
    let dir = tempfile::tempdir().unwrap();
    let mut child = ChildGuard(
        Command::new(std::env::current_exe().unwrap())
            .args([
                "--exact",
                "kill_test_child_process",
                "--nocapture",
                "--test-threads=1",
            ])
            .env(CHILD_DIR_ENV, dir.path())
            .stdout(Stdio::piped())
            .spawn()
            .unwrap(),
    );
    let child = &mut child.0;
    let stdout = BufReader::new(child.stdout.take().unwrap());
    let mut flushed = None;
    for line in stdout.lines() {
        let line = line.unwrap();
        // libtest prints the test's name on the same line first.
        if let Some((_, n)) = line.split_once("FLUSHED ") {
            flushed = Some(n.trim().parse::<u64>().unwrap());
            break;
        }
    }
    let flushed = flushed.expect("the child never reported its flush");
    // Let it write on (part of a chunk, likely), then kill it without warning.
    std::thread::sleep(Duration::from_millis(120));
    child.kill().unwrap();
    let status = child.wait().unwrap();
    assert_eq!(status.signal(), Some(9), "{status:?}");

    let files: Vec<PathBuf> = list_recordings(dir.path(), "test").unwrap();
    assert_eq!(files.len(), 1);
    let got = read_recording(&files[0]).unwrap();
    assert!(
        got.stopped_early.is_some(),
        "a killed writer leaves no footer"
    );
    assert!(
        got.raw.len() as u64 >= flushed,
        "{} < {flushed}",
        got.raw.len()
    );
    for (i, s) in got.raw.iter().enumerate() {
        assert_eq!(*s, raw(i as u64));
    }
    let frames = expected(
        &(0..got.frames.len() as u64).map(frame).collect::<Vec<_>>(),
        "",
    );
    assert!(got.frames.len() as u64 >= flushed);
    assert_eq!(got.frames, frames.frames);
    assert_eq!(got.metadata["imud.device"]["serial"], "1234");

    // Python mcap's non-seeking reader gets the same gap-free prefix.
    if let Some(out) = run_peer(
        "recording_read.py",
        &[files[0].as_os_str(), std::ffi::OsStr::new("--stream")],
    ) {
        let seqs: Vec<u64> = out["messages"]["/imu/raw"]
            .as_array()
            .unwrap()
            .iter()
            .map(|r| r["seq"].as_u64().unwrap())
            .collect();
        assert_eq!(seqs, (0..got.raw.len() as u64).collect::<Vec<_>>());
    }
}
