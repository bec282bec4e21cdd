//! The exit codes every imud tool shares (imu-cli): a missing input file exits 66 naming the
//! file, a non-finite number for a float flag is a usage error (64) refused at parse time, and
//! --help exits 0.

use std::process::Command;

fn run(args: &[&str]) -> (Option<i32>, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_imu-analyze"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn a_missing_input_file_exits_66() {
    let (code, stderr) = run(&["thermal", "/nonexistent/rec.mcap"]);
    assert_eq!(code, Some(66), "{stderr}");
    assert!(stderr.starts_with("imu-analyze: error: "), "{stderr}");
    assert!(stderr.contains("/nonexistent/rec.mcap"), "{stderr}");
}

#[test]
fn non_finite_float_flags_are_usage_errors() {
    let (code, stderr) = run(&["thermal", "/nonexistent/rec.mcap", "--bin-s", "inf"]);
    assert_eq!(code, Some(64), "{stderr}");
    assert!(stderr.contains("not a finite number"), "{stderr}");
    assert_eq!(run(&["--help"]).0, Some(0));
}

#[test]
fn health_options_out_of_range_are_usage_errors_and_a_missing_calibration_is_named() {
    let (code, stderr) = run(&["health", "/nonexistent/rec.mcap", "--latitude-deg", "95"]);
    assert_eq!(code, Some(64), "{stderr}");
    assert!(stderr.contains("latitude 95 deg"), "{stderr}");
    let (code, stderr) = run(&["health", "/nonexistent/rec.mcap", "--false-alarm-p", "1.5"]);
    assert_eq!(code, Some(64), "{stderr}");
    assert!(stderr.contains("false-alarm p 1.5"), "{stderr}");
    let (code, stderr) = run(&[
        "health",
        "/nonexistent/rec.mcap",
        "--calibration",
        "/nonexistent/cal.toml",
    ]);
    assert_eq!(code, Some(66), "{stderr}");
    assert!(stderr.contains("/nonexistent/cal.toml"), "{stderr}");
}
