//! A misbehaving test device written in Python (`tests/python/faulty_*.py`, independent of
//! imu-sim) on a real pseudo-terminal, with the imud binary on it for a while: the session the
//! link-fault tests of both protocols run.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use imu_bus::recording::{Recording, read_recording};

/// A child process killed (and reaped) when dropped.
pub struct Killed(pub Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Sends SIGTERM and waits.
pub fn terminate(child: &mut Killed) -> std::process::ExitStatus {
    let ok = Command::new("kill")
        .args(["-TERM", &child.0.id().to_string()])
        .status()
        .expect("kill")
        .success();
    assert!(ok);
    child.0.wait().expect("wait")
}

/// What one session gave: imud's recording, the device's JSON report, imud's log.
pub struct Session {
    pub rec: Recording,
    pub report: serde_json::Value,
    pub log: String,
}

/// What to run.
pub struct Setup<'a> {
    /// The device script in tests/python.
    pub script: &'a str,
    /// The instance name (made unique per process here).
    pub name: &'a str,
    pub device_args: &'a [&'a str],
    pub imud_args: &'a [&'a str],
    /// Extra imud configuration (TOML), after `[publish] enabled = false`.
    pub config: &'a str,
    /// The log line that says the start-up is done.
    pub ready: &'a str,
    /// How long imud streams after that, s.
    pub stream_s: f64,
}

/// The device, then imud on it until `stream_s` after `ready` appears in its log; both are
/// stopped with SIGTERM and must exit cleanly.
pub fn run(s: &Setup<'_>) -> Session {
    let dir = tempfile::tempdir().expect("tmp");
    let link = dir.path().join("imu0");
    let report = dir.path().join("report.json");
    let script = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/python")
        .join(s.script);
    let mut device = Killed(
        Command::new("python3")
            .arg(&script)
            .arg("--link")
            .arg(&link)
            .arg("--report")
            .arg(&report)
            .args(s.device_args)
            .stdout(Stdio::null())
            .spawn()
            .expect("python3 runs the test device"),
    );
    let deadline = Instant::now() + Duration::from_secs(10);
    while !link.exists() {
        assert!(Instant::now() < deadline, "the test device did not start");
        std::thread::sleep(Duration::from_millis(20));
    }
    let config = dir.path().join("imud.toml");
    std::fs::write(&config, format!("[publish]\nenabled = false\n{}", s.config)).expect("config");
    let log_path = dir.path().join("imud.stderr");
    let mut imud = Killed(
        Command::new(env!("CARGO_BIN_EXE_imud"))
            .arg("--config")
            .arg(&config)
            .args(["--name", &format!("{}-{}", s.name, std::process::id())])
            .arg("--device")
            .arg(&link)
            .arg("--log-dir")
            .arg(dir.path().join("logs"))
            .args(s.imud_args)
            .env("IMUD_LOG", "info")
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&log_path).expect("log"))
            .spawn()
            .expect("imud"),
    );
    let log = || std::fs::read_to_string(&log_path).unwrap_or_default();
    let deadline = Instant::now() + Duration::from_secs(60);
    while !log().contains(s.ready) {
        assert!(Instant::now() < deadline, "no start-up: {}", log());
        std::thread::sleep(Duration::from_millis(50));
    }
    std::thread::sleep(Duration::from_secs_f64(s.stream_s));
    assert!(terminate(&mut imud).success(), "{}", log());
    assert!(terminate(&mut device).success());
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).expect("report")).expect("json");
    let files: Vec<PathBuf> = std::fs::read_dir(dir.path().join("logs"))
        .expect("logs")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "mcap"))
        .collect();
    assert_eq!(files.len(), 1, "{files:?}");
    let rec = read_recording(&files[0]).expect("recording");
    Session {
        rec,
        report,
        log: log(),
    }
}
