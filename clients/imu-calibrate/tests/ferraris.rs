//! End-to-end test of the Ferraris procedure (`--plan config/plans/ferraris.toml`): a hand
//! session of six faces and a full turn about each axis, simulated through the daemon's offline
//! pipeline, calibrated with one command and no time windows. Faces and turns are recognised
//! from the data; every parameter of the base model is recovered within 3 standard errors, and
//! the turns give the gyro scale to the precision the sensor's noise allows.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The truth: the paper's base model on both triads, with the 3DM-GX1-like noise.
const TRUTH: &str = r#"
format = "imud-calibration/1"
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
quantization-lsb = [2.1e-3, 2.1e-3, 2.1e-3]
[gyro.misalignment]
xy = -0.9e-3
xz = 1.3e-3
yx = 0.6e-3
yz = -1.0e-3
zx = 0.4e-3
zy = 1.1e-3
[gyro.scale]
value = [2.0e-2, -1.5e-2, 3.0e-2]
[gyro.bias]
value = [8.7e-3, -6.1e-3, 1.05e-2]
[gyro.noise]
white-density = [1.0e-3, 1.0e-3, 1.0e-3]
quantization-lsb = [2.6e-4, 2.6e-4, 2.6e-4]
"#;

fn repo_path(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
}

#[test]
fn a_ferraris_session_calibrates_with_one_command() {
    let dir = tempfile::tempdir().unwrap();
    let truth_model = dir.path().join("truth.toml");
    std::fs::write(&truth_model, TRUTH).unwrap();
    let mut sim = imu_sim::SimOptions::from_files(
        &repo_path("config/scenarios/ferraris.toml"),
        Some(&truth_model),
    )
    .unwrap();
    sim.seed = 5;
    let mut c = imud::config::Config::default();
    c.log.dir = dir.path().join("log");
    c.name = "fer".into();
    let out = imud::offline::record(sim, &c).unwrap();
    // The shipped plan, with the simulator's gravity (standard, whatever its latitude).
    let plan = dir.path().join("ferraris.toml");
    let shipped = std::fs::read_to_string(repo_path("config/plans/ferraris.toml")).unwrap();
    std::fs::write(&plan, format!("{shipped}gravity-m-s2 = 9.80665\n")).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_imu-calibrate"))
        .arg(&out.files[0])
        .arg("--plan")
        .arg(&plan)
        .arg("--truth")
        .arg(&truth_model)
        .arg("--json")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    // ferraris.toml: nine rests (six faces, three of them twice around a turn), three turns.
    assert_eq!(j["recordings"][0]["static_segments"], 9, "{j}");
    assert_eq!(j["recordings"][0]["rate_plateaus"], 3, "{j}");
    let notes = j["fit"]["notes"].to_string();
    assert!(
        notes.contains("6 distinct: +x, +y, +z, -x, -y, -z"),
        "{notes}"
    );
    assert!(notes.contains("3 full turn(s)"), "{notes}");
    let rows = j["truth_comparison"].as_array().unwrap();
    assert_eq!(rows.len(), 24, "{rows:?}");
    for r in rows {
        let name = format!("{} {}", r["triad"], r["name"]);
        let z = r["error_in_se"].as_f64().unwrap_or(f64::NAN);
        assert!(z.abs() < 3.0, "{name}: {r}");
        // One turn fixes a gyro scale to ~1e-3 (the angle's noise over 360 deg); a turn whose
        // mean were weighted by the spread of the rate through it would give ~4e-2.
        if name.contains("gyro") && name.contains("scale") {
            let se = r["std_error"].as_f64().unwrap();
            assert!(se < 3e-3, "{name}: {r}");
        }
    }
}
