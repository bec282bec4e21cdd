//! End-to-end test of `imu-calibrate`: a simulated index-table + rate-table recording through
//! the daemon's offline pipeline, calibrated against the simulator's truth; the written file
//! loads, and every fitted parameter is within 3 standard errors of the truth model.

use std::path::{Path, PathBuf};
use std::process::Command;

/// 2 x 6 static positions (60-degree steps), then rate plateaus on each axis.
const SCENARIO: &str = r#"
name = "calibration-short"
rate-hz = 100.0
latitude-deg = 40.0

[[segment]]
kind = "static"
orientation = { x = "north", z = "up" }
duration-s = 20.0

[[segment]]
kind = "index-table"
axis = "x"
step-deg = 60.0
positions = 6
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
step-deg = 60.0
positions = 6
dwell-s = 20.0
move-s = 3.0

[[segment]]
kind = "static"
orientation = { z = "up", x = "north" }
move-s = 5.0
duration-s = 10.0

[[segment]]
kind = "rate-steps"
axis = "z"
rates-deg-s = [40, 80, 0, -40, -80, 0]
dwell-s = 10.0
accel-deg-s2 = 40.0

[[segment]]
kind = "static"
orientation = { x = "up", y = "north" }
move-s = 5.0
duration-s = 10.0

[[segment]]
kind = "rate-steps"
axis = "x"
rates-deg-s = [40, 80, 0, -40, -80, 0]
dwell-s = 10.0
accel-deg-s2 = 40.0

[[segment]]
kind = "static"
orientation = { y = "up", z = "north" }
move-s = 5.0
duration-s = 10.0

[[segment]]
kind = "rate-steps"
axis = "y"
rates-deg-s = [40, 80, 0, -40, -80, 0]
dwell-s = 10.0
accel-deg-s2 = 40.0
"#;

/// What to fit: the paper's accel model plus the quadratic nonlinearity the truth hides, and
/// the gyro model with g-sensitivity.
const MODEL: &str = r#"
format = "imud-calibration/1"
[accel.bias]
value = [0.0, 0.0, 0.0]
[accel.scale]
value = [0.0, 0.0, 0.0]
[accel.misalignment]
[accel.scale-nonlinearity]
quadratic = [0.0, 0.0, 0.0]
cubic = [0.0, 0.0, 0.0]
[gyro.bias]
value = [0.0, 0.0, 0.0]
[gyro.scale]
value = [0.0, 0.0, 0.0]
[gyro.misalignment]
[gyro.g-sensitivity]
matrix = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]
# Noise terms as a noise characterisation (imu-noise) would give them: they widen the bias
# standard errors by the bias wander over the recording.
[accel.noise]
white-density = [1.5e-3, 1.5e-3, 1.8e-3]
bias-instability = [1.27e-3, 9.8e-4, 4.2e-4]
bias-instability-tau-max-s = 1000.0
random-walk = [2.0e-5, 2.0e-5, 2.0e-5]
quantization-lsb = [2.1e-3, 2.1e-3, 2.1e-3]
[gyro.noise]
white-density = [1.0e-3, 1.0e-3, 1.0e-3]
bias-instability = [2.4e-4, 2.4e-4, 2.4e-4]
bias-instability-tau-max-s = 1000.0
random-walk = [1.0e-5, 1.0e-5, 1.0e-5]
quantization-lsb = [2.6e-4, 2.6e-4, 2.6e-4]
"#;

fn model_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/models/example-3dm-gx1.toml")
}

#[test]
fn calibrates_a_simulated_recording_within_its_standard_errors() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("scenario.toml");
    std::fs::write(&scenario, SCENARIO).unwrap();
    let mut sim = imu_sim::SimOptions::from_files(&scenario, Some(&model_path())).unwrap();
    sim.seed = 17;
    let truth_path = dir.path().join("truth.mcap");
    sim.truth_out = Some(truth_path.clone());
    let mut c = imud::config::Config::default();
    c.log.dir = dir.path().join("log");
    c.name = "t".into();
    let out = imud::offline::record(sim, &c).unwrap();
    let model = dir.path().join("model.toml");
    std::fs::write(&model, MODEL).unwrap();
    let cal_path = dir.path().join("cal.toml");

    let run = |json: bool| {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_imu-calibrate"));
        cmd.arg(&out.files[0])
            .arg("--reference")
            .arg(&truth_path)
            .arg("--model")
            .arg(&model)
            .arg("--truth")
            .arg(model_path())
            .arg("-o")
            .arg(&cal_path);
        if json {
            cmd.arg("--json");
        }
        let o = cmd.output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8(o.stdout).unwrap()
    };
    let table = run(false);
    eprintln!("{table}");
    assert!(table.contains("fitted vs truth"));
    assert!(table.contains("rate plateaus"));

    let j: serde_json::Value = serde_json::from_str(&run(true)).unwrap();
    let rows = j["truth_comparison"].as_array().unwrap();
    let mut fitted = 0;
    for r in rows {
        let name = format!("{} {}", r["triad"], r["name"]);
        if let Some(z) = r["error_in_se"].as_f64() {
            fitted += 1;
            assert!(z.abs() < 3.0, "{name}: {r}");
        } else {
            // Only the cubic nonlinearity may be unobservable with 60-degree steps.
            assert!(name.contains("cubic"), "{name} not fitted: {r}");
        }
    }
    // accel 3+3+6+6 (minus <= 2 cubic), gyro 3+3+6+9.
    assert!(fitted >= 16 + 21, "{fitted} of {}", rows.len());
    assert!(
        j["fit"]["segmentation"]["segments"]
            .as_array()
            .unwrap()
            .len()
            >= 12 + 12
    );

    let cal = imu_model::Calibration::load(&cal_path).unwrap();
    assert!(cal.gyro.has(imu_model::EffectKind::GSensitivity));
    assert!(cal.accel.residual_rms.is_some());
    let inputs = &cal.provenance.inputs;
    assert_eq!(inputs.len(), 2);
    // Each input's hash equals what coreutils' sha256sum says of the file.
    for input in inputs {
        let out = Command::new("sha256sum").arg(&input.path).output().unwrap();
        let want = String::from_utf8_lossy(&out.stdout);
        let want = want.split_whitespace().next().unwrap();
        assert_eq!(input.sha256.as_deref(), Some(want), "{}", input.path);
    }
    assert!(cal.provenance.created.as_ref().unwrap().ends_with('Z'));
}
