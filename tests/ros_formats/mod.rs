//! Shared by each offline client's `tests/ros_formats.rs` (included with `#[path]`): one of our
//! recordings (the shipped index-table session, recorded through imud's offline pipeline)
//! converted by Python `rosbags` (`tests/python/write_ros_logs.py convert`) into a rosbag2 MCAP
//! bag, a rosbag2 sqlite3 bag and a ROS 1 bag, and the client's `--json` on each compared:
//! the three must be identical once the input's own name is taken out.

#![allow(dead_code)] // each client uses its part

use std::path::{Path, PathBuf};
use std::process::Command;

/// The repository root.
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The shipped index-table session (12 positions), recorded without a calibration, so its
/// corrected stream (what a converted bag carries) is the device's reading.
pub fn record(dir: &Path) -> PathBuf {
    let scenario = repo().join("config/scenarios/index-table-12pos.toml");
    imud::offline::record_session(dir, "rec", &scenario, None, 5, None)
        .unwrap()
        .recording
}

/// The recording as a rosbag2 MCAP directory, a rosbag2 sqlite3 directory and a ROS 1 bag
/// (lz4 chunks), written by Python `rosbags`; `None` when the peer is unavailable and that is
/// allowed (fails under IMUD_REQUIRE_PEERS).
pub fn convert(recording: &Path, dir: &Path) -> Option<[PathBuf; 3]> {
    let script = repo().join("tests/python/write_ros_logs.py");
    let prefix = dir.join("robot");
    let unavailable = |why: String| {
        assert!(
            std::env::var_os("IMUD_REQUIRE_PEERS").is_none(),
            "Python peer unavailable: {why} (python3 -m pip install -r requirements-dev.txt)"
        );
        eprintln!("skipping the format test (install requirements-dev.txt): {why}");
        None
    };
    match Command::new("python3")
        .arg(&script)
        .arg("convert")
        .arg(recording)
        .arg(&prefix)
        .output()
    {
        Ok(out) if out.status.success() => Some([
            dir.join("robot-mcap"),
            dir.join("robot-db3"),
            dir.join("robot.bag"),
        ]),
        Ok(out) if out.status.code() == Some(77) => {
            unavailable(String::from_utf8_lossy(&out.stderr).trim().to_string())
        }
        Ok(out) => panic!(
            "{} failed: {}",
            script.display(),
            String::from_utf8_lossy(&out.stderr)
        ),
        Err(e) => unavailable(format!("cannot run python3: {e}")),
    }
}

/// Runs `exe PRE INPUT ARGS` and returns its `--json` output with every mention of
/// the input's path (and of the directory holding it) replaced by `INPUT`, and every
/// `sha256` value (the input file's hash) replaced by its key.
pub fn json_of(
    exe: &str,
    pre: &[&std::ffi::OsStr],
    input: &Path,
    args: &[&std::ffi::OsStr],
) -> serde_json::Value {
    let out = Command::new(exe)
        .args(pre)
        .arg(input)
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{exe} {} failed: {}",
        input.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text)
        .unwrap_or_else(|e| panic!("{exe} --json is not JSON ({e}): {text}"));
    normalize(v, input)
}

fn normalize(v: serde_json::Value, input: &Path) -> serde_json::Value {
    use serde_json::Value;
    match v {
        Value::String(s) => {
            // The files a directory stands for are listed under it; longest first.
            let mut names = vec![input.display().to_string()];
            if let Ok(entries) = std::fs::read_dir(input) {
                for e in entries.flatten() {
                    names.push(e.path().display().to_string());
                }
            }
            names.sort_by_key(|n| std::cmp::Reverse(n.len()));
            let mut s = s;
            for n in names {
                s = s.replace(&n, "INPUT");
            }
            Value::String(s)
        }
        Value::Array(a) => Value::Array(a.into_iter().map(|x| normalize(x, input)).collect()),
        Value::Object(o) => Value::Object(
            o.into_iter()
                .map(|(k, x)| {
                    let x = if k.contains("sha256") || k.contains("created") {
                        Value::String(k.clone())
                    } else {
                        normalize(x, input)
                    };
                    (k, x)
                })
                .collect(),
        ),
        other => other,
    }
}

/// Asserts the tool's normalized `--json` (`exe PRE INPUT ARGS`) is the same for every input.
pub fn assert_same(
    exe: &str,
    pre: &[&std::ffi::OsStr],
    inputs: &[PathBuf],
    args: &[&std::ffi::OsStr],
) {
    let first = json_of(exe, pre, &inputs[0], args);
    for input in &inputs[1..] {
        let other = json_of(exe, pre, input, args);
        assert!(
            first == other,
            "{exe}: {} and {} differ:\n{}\n---\n{}",
            inputs[0].display(),
            input.display(),
            serde_json::to_string_pretty(&first).unwrap(),
            serde_json::to_string_pretty(&other).unwrap()
        );
    }
}
