//! The input forms at the command line: the text files of one session given in any order (read
//! as one recording in time order, the gap between them warned about and named in `--json`),
//! and a rosbag2 directory with two IMU topics (an error listing both without `--topic`, the
//! chosen topic named in `--json` with it).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn run(args: &[&std::ffi::OsStr]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_imu-noise"))
        .args(args)
        .output()
        .unwrap()
}

/// Whitespace-separated text, no header, `%` comments: samples `ks` at 100 Hz with
/// deterministic noise of sd 0.01 (white noise N = 1e-3 per sqrt(Hz)).
fn write_part(path: &Path, ks: std::ops::Range<u64>) {
    let mut state: u64 = 7 + ks.start;
    let mut noise = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.01 * 12f64.sqrt()
    };
    let mut s = String::from("% t ax ay az gx gy gz\n");
    for k in ks {
        s += &format!(
            "{:.2} {} {} {} {} {} {}\n",
            k as f64 / 100.0,
            noise(),
            noise(),
            9.81 + noise(),
            noise(),
            noise(),
            noise()
        );
    }
    std::fs::write(path, s).unwrap();
}

#[test]
fn text_files_of_one_session_are_one_recording_with_the_gap_named() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("part1.dat"), dir.path().join("part2.dat"));
    write_part(&a, 0..10_000);
    write_part(&b, 10_200..20_000);
    let out = run(&[b.as_os_str(), a.as_os_str(), "--json".as_ref()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("2.010 s gap (200 samples missing) at 99.990 s between"),
        "{stderr}"
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    for axis in v.as_array().unwrap() {
        let input = &axis["input"];
        let files: Vec<PathBuf> = input["files"]
            .as_array()
            .unwrap()
            .iter()
            .map(|f| PathBuf::from(f.as_str().unwrap()))
            .collect();
        assert_eq!(files, vec![a.clone(), b.clone()], "time order");
        assert_eq!(input["gaps"].as_array().unwrap().len(), 1);
        assert_eq!(input["gaps"][0]["missing_samples"], 200);
        assert!(input["topic"].is_null());
        // The noise of the joined series is still the truth's (19 800 samples).
        let n = axis["fit"]["n_u_per_sqrt_hz"]["value"].as_f64().unwrap();
        assert!((n / 1e-3 - 1.0).abs() < 0.1, "{axis}");
    }
}

/// The rosbag2 directory written by Python `rosbags` (tests/python/write_rosbag2.py); `None`
/// when the peer is unavailable and that is allowed (fails under IMUD_REQUIRE_PEERS).
fn write_bag(dir: &Path, n: u64) -> Option<PathBuf> {
    let script = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../tests/python"))
        .join("write_rosbag2.py");
    let bag = dir.join("bag");
    let out = Command::new("python3")
        .arg(&script)
        .arg(&bag)
        .arg(n.to_string())
        .arg("1700000000000000000")
        .output();
    let why = match out {
        Ok(o) if o.status.success() => return Some(bag),
        Ok(o) if o.status.code() == Some(77) => String::from_utf8_lossy(&o.stderr).into_owned(),
        Ok(o) => panic!("write_rosbag2.py: {}", String::from_utf8_lossy(&o.stderr)),
        Err(e) => format!("cannot run python3: {e}"),
    };
    assert!(
        std::env::var_os("IMUD_REQUIRE_PEERS").is_none(),
        "Python peer unavailable: {why}"
    );
    eprintln!("skipping the rosbag2 test (install requirements-dev.txt): {why}");
    None
}

#[test]
fn a_rosbag2_directory_needs_a_topic_when_it_has_two() {
    let dir = tempfile::tempdir().unwrap();
    let Some(bag) = write_bag(dir.path(), 3000) else {
        return;
    };
    let out = run(&[bag.as_os_str(), "--json".as_ref()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(65), "{stderr}");
    assert!(
        stderr.contains("several IMU topics (sensor_msgs Imu): /imu/a (1500 messages), /imu/b (1500 messages); choose one with --topic"),
        "{stderr}"
    );
    let out = run(&[
        bag.as_os_str(),
        "--topic".as_ref(),
        "/imu/b".as_ref(),
        "--json".as_ref(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let input = &v[0]["input"];
    assert_eq!(input["topic"], "/imu/b");
    assert_eq!(
        input["files"],
        serde_json::json!([
            bag.join("bag_0.mcap").display().to_string(),
            bag.join("bag_1.mcap").display().to_string()
        ])
    );
    assert_eq!(v[0]["sample_rate_hz"].as_f64().map(f64::round), Some(100.0));
}
