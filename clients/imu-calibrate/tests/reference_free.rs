//! End-to-end test of `imu-calibrate --reference-free`: the shipped hand-held multi-pose
//! scenario through the daemon's offline pipeline, calibrated without any reference; the JSON
//! says what was fitted, every fitted parameter is within 3 standard errors of the truth model
//! (in the body frame the accelerometer defines), the calibration file loads, and the
//! procedure flags exclude each other.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// What to fit: bias, scale, misalignment and the scale nonlinearity the truth hides, for the
/// accel; bias, scale, misalignment for the gyro. The noise terms (as imu-noise would give them)
/// widen the bias standard errors by the bias wander over the recording.
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

fn repo_path(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
}

fn imu_calibrate(args: &[&std::ffi::OsStr]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_imu-calibrate"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn reference_free_json_and_calibration_file() {
    let dir = tempfile::tempdir().unwrap();
    let truth_model = repo_path("config/models/example-3dm-gx1.toml");
    let mut sim = imu_sim::SimOptions::from_files(
        &repo_path("config/scenarios/multi-pose.toml"),
        Some(&truth_model),
    )
    .unwrap();
    sim.seed = 17;
    let mut c = imud::config::Config::default();
    c.log.dir = dir.path().join("log");
    c.name = "t".into();
    let out = imud::offline::record(sim, &c).unwrap();
    let model = dir.path().join("model.toml");
    std::fs::write(&model, MODEL).unwrap();
    let cal_path = dir.path().join("cal.toml");

    let o = imu_calibrate(&[
        out.files[0].as_os_str(),
        "--reference-free".as_ref(),
        "--latitude-deg".as_ref(),
        "40".as_ref(),
        // The simulator's gravity is standard, whatever its latitude.
        "--gravity-m-s2".as_ref(),
        "9.80665".as_ref(),
        "--model".as_ref(),
        model.as_os_str(),
        "--truth".as_ref(),
        truth_model.as_os_str(),
        "-o".as_ref(),
        cal_path.as_os_str(),
        "--json".as_ref(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["procedure"], "reference-free");
    let fit = &j["fit"];
    // multi-pose.toml: a first still position and 36 random poses.
    assert_eq!(
        fit["poses"].as_array().unwrap().len(),
        37,
        "{}",
        fit["poses"]
    );
    assert_eq!(fit["moves"].as_array().unwrap().len(), 36);
    assert_eq!(fit["gravity_m_s2"], 9.80665);
    let notes = fit["notes"].to_string();
    assert!(notes.contains("gauge"), "{notes}");
    assert!(notes.contains("latitude 40"), "{notes}");
    assert_eq!(fit["accel"]["residual_unit"], "m/s^2");
    assert_eq!(fit["gyro"]["residual_unit"], "rad");

    let rows = j["truth_comparison"].as_array().unwrap();
    let mut fitted = 0;
    for r in rows {
        let name = format!("{} {}", r["triad"], r["name"]);
        eprintln!("{name:<44} err/SE {}", r["error_in_se"]);
        match r["error_in_se"].as_f64() {
            Some(z) => {
                fitted += 1;
                assert!(z.abs() < 3.0, "{name}: {r}");
            }
            // Held: the accel's gauge (upper-triangle misalignment), and at most the cubic
            // nonlinearity (absent from the truth, weakly separated from the scale).
            None => assert!(
                [
                    "misalignment.xy",
                    "misalignment.xz",
                    "misalignment.yz",
                    "cubic"
                ]
                .iter()
                .any(|h| name.contains(h))
                    && name.starts_with("\"accel\""),
                "{name} not fitted: {r}"
            ),
        }
    }
    // accel 3 + 3 + 3 + 6 (minus <= 3 cubic), gyro 3 + 3 + 6.
    assert!(fitted >= 12 + 12, "{fitted} of {}", rows.len());

    let cal = imu_model::Calibration::load(&cal_path).unwrap();
    assert!(
        cal.provenance
            .procedure
            .as_deref()
            .unwrap()
            .contains("reference-free multi-pose"),
        "{:?}",
        cal.provenance
    );
    assert_eq!(cal.provenance.inputs.len(), 1);
    assert!(cal.provenance.notes.as_deref().unwrap().contains("gauge"));
    assert!(cal.accel.has(imu_model::EffectKind::ScaleNonlinearity));
    assert!(cal.gyro.scale.as_ref().unwrap().std_error.is_some());

    // The table output says the same in words.
    let o = imu_calibrate(&[
        out.files[0].as_os_str(),
        "--reference-free".as_ref(),
        "--truth".as_ref(),
        truth_model.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let table = String::from_utf8(o.stdout).unwrap();
    assert!(
        table.contains("reference-free: 37 still poses, 36 moves"),
        "{table}"
    );
    assert!(
        table.contains("body frame the accelerometer defines"),
        "{table}"
    );
    // Without --gravity-m-s2 or --latitude-deg the tool says it assumed standard gravity.
    assert!(table.contains("9.80665 m/s^2 (standard"), "{table}");
}

#[test]
fn exactly_one_procedure() {
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("rec.mcap");
    std::fs::write(&rec, b"").unwrap();
    let stderr = |args: &[&str]| {
        let mut all: Vec<&std::ffi::OsStr> = vec![rec.as_os_str()];
        all.extend(args.iter().map(|a| std::ffi::OsStr::new(*a)));
        let o = imu_calibrate(&all);
        assert!(!o.status.success(), "{args:?} was accepted");
        String::from_utf8(o.stderr).unwrap()
    };
    let e = stderr(&["--reference", "t.mcap", "--reference-free"]);
    assert!(e.contains("cannot be used with"), "{e}");
    let e = stderr(&[]);
    assert!(
        e.contains("--reference") && e.contains("--reference-free"),
        "{e}"
    );
    let e = stderr(&["--reference", "t.mcap", "--gravity-m-s2", "9.8"]);
    assert!(e.contains("--reference-free"), "{e}");
}
