//! End-to-end tests of the imu-analyze binary on simulated recordings: JSON, SVG and HTML
//! outputs, and exit codes.

use std::path::{Path, PathBuf};
use std::process::Command;

const SCENARIO: &str = r#"
name = "cli"
description = "shocks then index-table steps"
rate-hz = 100.0
latitude-deg = 40.0

[[segment]]
kind = "static"
orientation = { z = "up", x = "north" }
duration-s = 5.0

[[segment]]
kind = "impacts"
axis = "z"
count = 5
period-s = 1.0
peak-g = 3.0
width-ms = 40.0

[[segment]]
kind = "index-table"
axis = "z"
step-deg = 30.0
positions = 4
dwell-s = 3.0
move-s = 1.5

[[segment]]
kind = "static"
duration-s = 5.0
"#;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_imu-analyze"))
}

fn record(dir: &Path) -> (PathBuf, PathBuf) {
    let scenario = dir.join("s.toml");
    std::fs::write(&scenario, SCENARIO).unwrap();
    let model =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/models/example-3dm-gx1.toml");
    let mut sim = imu_sim::SimOptions::from_files(&scenario, Some(&model)).unwrap();
    sim.seed = 5;
    let truth = dir.join("truth.mcap");
    sim.truth_out = Some(truth.clone());
    let mut c = imud::config::Config::default();
    c.log.dir = dir.join("log");
    c.name = "t".into();
    let out = imud::offline::record(sim, &c).unwrap();
    (out.files[0].clone(), truth)
}

#[test]
fn impact_and_dynamic_write_json_svg_and_html() {
    let dir = tempfile::tempdir().unwrap();
    let (rec, truth) = record(dir.path());
    let plots = dir.path().join("plots");
    let html = dir.path().join("impact.html");
    let out = bin()
        .args(["impact", rec.to_str().unwrap(), "--json", "--plot"])
        .arg(&plots)
        .arg("--html")
        .arg(&html)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["events"].as_array().unwrap().len(), 5);
    assert!(plots.join("impact-01.svg").exists());
    let page = std::fs::read_to_string(&html).unwrap();
    assert!(
        page.contains("<svg") && !page.contains("http://example") && page.contains("Impact test")
    );

    let out = bin()
        .args([
            "dynamic",
            rec.to_str().unwrap(),
            "--reference",
            truth.to_str().unwrap(),
            "--json",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(v["raw"]["growth_deg_s"].as_f64().unwrap() > 0.3);

    // A constant temperature: the thermal test says the data cannot decide.
    let out = bin()
        .args(["thermal", rec.to_str().unwrap(), "--bin-s", "2", "--plot"])
        .arg(&plots)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("cannot support or rule out"), "{text}");
    assert!(plots.join("thermal-01.svg").exists());
    // In JSON, the same recommendation with its code beside it.
    let out = bin()
        .args(["thermal", rec.to_str().unwrap(), "--bin-s", "2", "--json"])
        .output()
        .unwrap();
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(
        v["recommendation_codes"],
        serde_json::json!(["range_too_small"])
    );
    assert!(
        text.contains(v["recommendation"].as_str().unwrap()),
        "{text}"
    );
}

#[test]
fn missing_input_and_no_temperature_exit_codes() {
    let out = bin()
        .args(["thermal", "/nonexistent/x.mcap"])
        .output()
        .unwrap();
    assert_ne!(out.status.code(), Some(0));
    assert!(String::from_utf8_lossy(&out.stderr).contains("/nonexistent/x.mcap"));
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("a.csv");
    std::fs::write(
        &csv,
        "t,ax,ay,az,gx,gy,gz\n0,0,0,1,0,0,0\n0.01,0,0,1,0,0,0\n",
    )
    .unwrap();
    let out = bin()
        .args(["thermal", csv.to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(65),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stderr).contains("no temperature"));
}
