//! Recordings every reader opens after a crash: a real `imud --sim` process is killed with
//! SIGKILL, then started again; the restart repairs the killed recording (and the simulator's
//! truth file) so that Python `mcap`'s default `make_reader(f).iter_messages()` and `rosbags`
//! read it, with every record the killed file held. `imud recover FILE` does the same on
//! demand, and shares the tools' exit codes.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use imu_bus::mcap_read::for_each_message;
use imu_bus::recording::read_recording;
use imu_bus::recover::is_finished;

fn imud() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_imud"));
    c.env("IMUD_LOG", "info").env_remove("IMUD_CONFIG");
    c
}

fn start_sim(dir: &Path, name: &str, stderr: &Path) -> Child {
    imud()
        .args(["--sim", "--name", name])
        .arg("--log-dir")
        .arg(dir)
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(stderr).unwrap())
        .spawn()
        .unwrap()
}

fn signal(child: &Child, sig: &str) {
    let ok = Command::new("kill")
        .args([sig, &child.id().to_string()])
        .status()
        .unwrap()
        .success();
    assert!(ok);
}

fn mcaps(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|d| d.map(|e| e.unwrap().path()).collect())
        .unwrap_or_default();
    v.sort();
    v
}

/// Polls `cond` until it holds; fails after a generous deadline (bounds a hang, measures
/// nothing).
fn wait_until(what: &str, mut cond: impl FnMut() -> bool) {
    let deadline = Instant::now() + Duration::from_secs(60);
    while !cond() {
        assert!(Instant::now() < deadline, "timed out waiting until {what}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Runs a Python peer script from tests/python on `file` and parses its JSON. A missing peer
/// (exit 77) skips locally but fails under CI (`IMUD_REQUIRE_PEERS`).
fn python_peer(script: &str, file: &Path) -> Option<serde_json::Value> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/python")
        .join(script);
    match Command::new("python3").arg(&path).arg(file).output() {
        Ok(o) if o.status.success() => Some(serde_json::from_slice(&o.stdout).expect("peer JSON")),
        other => {
            let why = format!("{other:?}");
            assert!(
                std::env::var_os("IMUD_REQUIRE_PEERS").is_none(),
                "{script} failed: {why}"
            );
            eprintln!("skipping the {script} peer check: {why}");
            None
        }
    }
}

fn total_count(out: &serde_json::Value) -> u64 {
    out["count"]
        .as_object()
        .unwrap()
        .values()
        .map(|v| v.as_u64().unwrap())
        .sum()
}

#[test]
fn after_kill_9_a_restart_repairs_the_recording_for_every_reader() {
    let dir = tempfile::tempdir().unwrap();
    let logs = dir.path().join("logs");
    let name = format!("recover-{}", std::process::id());
    let mut first = start_sim(&logs, &name, &dir.path().join("first.stderr"));
    let recording = || {
        mcaps(&logs)
            .into_iter()
            .find(|p| !p.to_string_lossy().contains("truth"))
    };
    wait_until("the recording holds flushed samples", || {
        recording().is_some_and(|f| read_recording(&f).is_ok_and(|r| r.raw.len() >= 150))
    });
    signal(&first, "-KILL");
    first.wait().unwrap();
    let killed = mcaps(&logs);
    assert_eq!(killed.len(), 2, "a recording and a truth file: {killed:?}");
    let rec_path = recording().unwrap();
    let before = read_recording(&rec_path).unwrap();
    let tolerant = for_each_message(&rec_path, |_, _, _| Ok(())).unwrap();
    let unfinished = tolerant
        .unfinished
        .clone()
        .expect("a killed file has no footer");
    assert!(unfinished.footer_missing, "{unfinished:?}");
    for f in &killed {
        assert!(!is_finished(f).unwrap(), "{}", f.display());
    }
    // What users hit before the repair: the default reader fails on the unfinished file.
    if let Some(out) = python_peer("recording_default_read.py", &rec_path) {
        assert!(!out["error"].is_null(), "{out}");
    }

    let second_log = dir.path().join("second.stderr");
    let mut second = start_sim(&logs, &name, &second_log);
    wait_until(
        "the restart repaired the killed files and started anew",
        || mcaps(&logs).len() >= 4,
    );
    signal(&second, "-TERM");
    let status = second.wait().unwrap();
    let log = std::fs::read_to_string(&second_log).unwrap();
    assert!(status.success(), "{status}: {log}");
    assert!(
        log.contains(&format!("{}: repaired: ", rec_path.display())),
        "{log}"
    );

    for f in &killed {
        assert!(
            is_finished(f).unwrap(),
            "{} not repaired: {log}",
            f.display()
        );
    }
    let leftovers: Vec<PathBuf> = mcaps(&logs)
        .into_iter()
        .filter(|p| !p.to_string_lossy().ends_with(".mcap"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
    let after = read_recording(&rec_path).unwrap();
    assert_eq!(after.stopped_early, None);
    assert_eq!(after.raw, before.raw, "every record the killed file held");
    assert_eq!(after.frames, before.frames);
    assert_eq!(after.metadata, before.metadata);

    let Some(out) = python_peer("recording_default_read.py", &rec_path) else {
        return;
    };
    assert!(out["error"].is_null(), "{out}");
    assert_eq!(total_count(&out), tolerant.n_messages);
    assert_eq!(
        out["last_log_time_ns"].as_u64(),
        unfinished.last_log_time_ns
    );
    let seqs: Vec<u64> = before.raw.iter().map(|s| s.seq).collect();
    assert_eq!(out["raw_seq"], serde_json::json!(seqs));
    if let Some(bag) = python_peer("recording_rosbags.py", &rec_path) {
        assert_eq!(bag["raw_seq"], serde_json::json!(seqs));
    }
}

#[test]
fn imud_recover_repairs_a_file_and_shares_the_exit_codes() {
    let dir = tempfile::tempdir().unwrap();
    let logs = dir.path().join("logs");
    let name = format!("recover-cmd-{}", std::process::id());
    let mut sim = start_sim(&logs, &name, &dir.path().join("sim.stderr"));
    let recording = || {
        mcaps(&logs)
            .into_iter()
            .find(|p| !p.to_string_lossy().contains("truth"))
    };
    wait_until("the recording holds flushed samples", || {
        recording().is_some_and(|f| read_recording(&f).is_ok_and(|r| r.raw.len() >= 50))
    });
    signal(&sim, "-KILL");
    sim.wait().unwrap();
    let file = recording().unwrap();
    let n_before = read_recording(&file).unwrap().raw.len();

    let out = imud()
        .arg("recover")
        .arg(&file)
        .arg("--keep-original")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{out:?}");
    assert!(
        stdout.starts_with(&format!("{}: repaired: ", file.display())),
        "{stdout}"
    );
    assert!(stdout.contains("original kept as"), "{stdout}");
    assert!(is_finished(&file).unwrap());
    assert_eq!(read_recording(&file).unwrap().raw.len(), n_before);
    let orig = PathBuf::from(format!("{}.orig", file.display()));
    assert!(
        !is_finished(&orig).unwrap(),
        "the original is kept as it was"
    );

    let again = imud().arg("recover").arg(&file).output().unwrap();
    assert!(again.status.success());
    assert!(String::from_utf8_lossy(&again.stdout).contains("finished already"));

    let missing = imud()
        .args(["recover", "/nonexistent/rec.mcap"])
        .output()
        .unwrap();
    assert_eq!(missing.status.code(), Some(66), "{missing:?}");
    let stderr = String::from_utf8_lossy(&missing.stderr);
    assert!(
        stderr.starts_with("imud: error: /nonexistent/rec.mcap"),
        "{stderr}"
    );
    let config = imud()
        .args(["--config", "/nonexistent/imud.toml", "--print-config"])
        .output()
        .unwrap();
    assert_eq!(config.status.code(), Some(66), "{config:?}");
    let usage = imud().args(["--baud", "fast"]).output().unwrap();
    assert_eq!(usage.status.code(), Some(64), "{usage:?}");
}
