//! End-to-end test of `imu-diagnose`: a short simulated index-table session whose truth hides a
//! gyro g-sensitivity is recorded through the daemon's offline pipeline; the ladder must add
//! gyro g-sensitivity, write a calibration imud loads and an HTML report with the ladder and
//! charts, and `--add gyro:g-sensitivity` must bring the gyro residual down.

use std::path::{Path, PathBuf};
use std::process::Command;

use imu_model::{Calibration, EffectKind};

/// The truth every test starts from: bias, scale and misalignment on both triads (the base
/// model's effects), with the example 3DM-GX1's coloured noise.
const BASE_TRUTH: &str = r#"
format = "imud-calibration/1"
id = "diagnose-base"

[accel.misalignment]
xy = 1.2e-3
xz = -0.8e-3
yx = 0.5e-3
yz = 1.5e-3
zx = -1.1e-3
zy = 0.7e-3
[accel.scale]
value = [1.2e-3, -0.8e-3, 1.5e-3]
[accel.bias]
value = [0.25, -0.18, 0.32]
[accel.noise]
white-density = [1.5e-3, 1.5e-3, 1.8e-3]
bias-instability = [1.27e-3, 9.8e-4, 4.2e-4]
bias-instability-tau-max-s = 1000.0
random-walk = [2.0e-5, 2.0e-5, 2.0e-5]
quantization-lsb = [2.1e-3, 2.1e-3, 2.1e-3]

[gyro.misalignment]
xy = -0.9e-3
xz = 1.3e-3
yx = 0.6e-3
yz = -1.0e-3
zx = 0.4e-3
zy = 1.1e-3
[gyro.scale]
value = [2.0e-3, -1.5e-3, 3.0e-3]
[gyro.bias]
value = [8.7e-3, -6.1e-3, 1.05e-2]
[gyro.noise]
white-density = [1.0e-3, 1.0e-3, 1.0e-3]
bias-instability = [2.4e-4, 2.4e-4, 2.4e-4]
bias-instability-tau-max-s = 1000.0
random-walk = [1.0e-5, 1.0e-5, 1.0e-5]
quantization-lsb = [2.6e-4, 2.6e-4, 2.6e-4]
"#;

/// Index table about x, then about y: 2 x 12 positions at 30 degrees, 20 s each (paper 3.1.2).
const INDEX_TABLE: &str = r#"
name = "index-table-diagnose"
rate-hz = 100.0
latitude-deg = 40.0

[[segment]]
kind = "static"
orientation = { x = "north", z = "up" }
duration-s = 20.0

[[segment]]
kind = "index-table"
axis = "x"
step-deg = 30.0
positions = 12
dwell-s = 20.0
move-s = 3.0

[[segment]]
kind = "static"
orientation = { y = "north", z = "up" }
move-s = 5.0
duration-s = 20.0

[[segment]]
kind = "index-table"
axis = "y"
step-deg = 30.0
positions = 12
dwell-s = 20.0
move-s = 3.0
"#;

/// The hidden effect: gyro g-sensitivity (rad/s per m/s^2).
const HIDDEN: &str = "[gyro.g-sensitivity]\nmatrix = [[1.5e-4, 0.0, 0.5e-4], [0.0, -1.2e-4, 0.0], [0.6e-4, 0.0, 2.0e-4]]\n";

/// The model under test: bias + scale + misalignment on both triads.
const MODEL: &str = r#"
format = "imud-calibration/1"
id = "base"
[accel.bias]
value = [0.0, 0.0, 0.0]
[accel.scale]
value = [0.0, 0.0, 0.0]
[accel.misalignment]
[gyro.bias]
value = [0.0, 0.0, 0.0]
[gyro.scale]
value = [0.0, 0.0, 0.0]
[gyro.misalignment]
"#;

/// Records the scenario with the hidden effect; returns (recording, truth, model file).
fn record(dir: &Path) -> (PathBuf, PathBuf, PathBuf) {
    let scenario_path = dir.join("scenario.toml");
    std::fs::write(&scenario_path, INDEX_TABLE).unwrap();
    let truth_path = dir.join("truth-model.toml");
    std::fs::write(&truth_path, format!("{BASE_TRUTH}\n{HIDDEN}")).unwrap();
    let mut sim = imu_sim::SimOptions::from_files(&scenario_path, Some(&truth_path)).unwrap();
    sim.seed = 11;
    let truth_out = dir.join("truth.mcap");
    sim.truth_out = Some(truth_out.clone());
    let mut c = imud::config::Config::default();
    c.log.dir = dir.join("log");
    c.name = "t".into();
    let out = imud::offline::record(sim, &c).unwrap();
    let model = dir.join("model.toml");
    std::fs::write(&model, MODEL).unwrap();
    (out.files[0].clone(), truth_out, model)
}

fn run(args: &[&std::ffi::OsStr]) -> serde_json::Value {
    let out = Command::new(env!("CARGO_BIN_EXE_imu-diagnose"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "imu-diagnose failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

fn gyro_rms(j: &serde_json::Value) -> f64 {
    let axes = j["diagnoses"][1]["axes"].as_array().unwrap();
    let sq: f64 = axes
        .iter()
        .map(|a| a["residual_rms"].as_f64().unwrap().powi(2))
        .sum();
    sq.sqrt()
}

#[test]
fn ladder_finds_the_hidden_gyro_g_sensitivity() {
    let dir = tempfile::tempdir().unwrap();
    let (rec, truth, model) = record(dir.path());
    let cal_path = dir.path().join("cal.toml");
    let report = dir.path().join("r.html");

    let j = run(&[
        "ladder".as_ref(),
        rec.as_os_str(),
        "--reference".as_ref(),
        truth.as_os_str(),
        "-o".as_ref(),
        cal_path.as_os_str(),
        "--report".as_ref(),
        report.as_os_str(),
        "--json".as_ref(),
    ]);
    let steps = j["steps"].as_array().unwrap();
    let added: Vec<&serde_json::Value> = steps
        .iter()
        .map(|s| &s["added"])
        .filter(|a| !a.is_null())
        .collect();
    assert!(
        added.contains(&&serde_json::json!(["gyro", "g-sensitivity"])),
        "ladder added {added:?}"
    );
    for s in steps {
        for t in ["accel", "gyro"] {
            assert_eq!(s[t]["residual_rms"].as_array().unwrap().len(), 3);
            assert_eq!(s[t]["noise_floor_rms"].as_array().unwrap().len(), 3);
        }
    }
    let cal = Calibration::load(&cal_path).unwrap();
    assert!(cal.gyro.has(EffectKind::GSensitivity), "{cal:?}");
    assert_eq!(
        cal.provenance.procedure.as_deref(),
        Some("imu-diagnose ladder")
    );
    let html = std::fs::read_to_string(&report).unwrap();
    assert!(html.contains("The ladder"), "no ladder in the report");
    assert!(html.contains("g-sensitivity"));
    assert!(html.contains("<svg"));

    // Diagnose the base model, then with the hidden effect added.
    let base = run(&[
        rec.as_os_str(),
        "--reference".as_ref(),
        truth.as_os_str(),
        "--model".as_ref(),
        model.as_os_str(),
        "--json".as_ref(),
    ]);
    assert_eq!(
        base["diagnoses"][1]["consistent"], false,
        "{}",
        base["verdict"]
    );
    assert_eq!(
        base["candidates"]
            .as_array()
            .unwrap()
            .iter()
            .find(|c| c["triad"] == "gyro")
            .unwrap()["effect"],
        "g-sensitivity"
    );
    let with = run(&[
        rec.as_os_str(),
        "--reference".as_ref(),
        truth.as_os_str(),
        "--model".as_ref(),
        model.as_os_str(),
        "--add".as_ref(),
        "gyro:g-sensitivity".as_ref(),
        "--json".as_ref(),
    ]);
    let (before, after) = (gyro_rms(&base), gyro_rms(&with));
    assert!(
        with["diagnoses"][1]["consistent_with_drift"] == true || after < 0.5 * before,
        "gyro residual {before:.3e} -> {after:.3e}: {}",
        with["verdict"]
    );
}

#[test]
fn bad_add_is_a_clear_error() {
    let out = Command::new(env!("CARGO_BIN_EXE_imu-diagnose"))
        .args([
            "rec.mcap",
            "--reference",
            "t.mcap",
            "--add",
            "gyro:no-such-effect",
        ])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("unknown effect"), "{err}");
}
