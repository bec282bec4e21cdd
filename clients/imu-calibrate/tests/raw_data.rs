//! End-to-end test of raw data without preprocessing: the hand-held-raw scenario (an
//! uncompensated unit with half-g accel offsets, 5-9 deg/s gyro offsets and percent scale
//! errors, held still by a trembling hand for only 3 s per pose, each pose tilted off its
//! nominal by up to 3 degrees) through the daemon's offline pipeline, and as imu-sim's own text
//! export (two files of raw counts), calibrated with `--reference-free` from a neutral model:
//! every still pose is found (the gyro offset does not make them rate plateaus), the accel fit
//! starts from the closed-form ellipsoid, and every fitted parameter is within 3 standard
//! errors of the truth.

use std::path::{Path, PathBuf};
use std::process::Command;

/// Bias, scale and misalignment of both triads, starting at zero, with the truth's noise terms
/// (as imu-noise would give them) so that the bias standard errors carry the bias wander.
const MODEL: &str = r#"
format = "imud-calibration/1"
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

/// The hand-held-raw scenario recorded through the daemon's offline pipeline into `dir`.
fn record_hand_held_raw(dir: &Path) -> PathBuf {
    let truth_model = repo_path("config/models/raw-uncompensated.toml");
    let mut sim = imu_sim::SimOptions::from_files(
        &repo_path("config/scenarios/hand-held-raw.toml"),
        Some(&truth_model),
    )
    .unwrap();
    sim.seed = 23;
    let mut c = imud::config::Config::default();
    c.log.dir = dir.join("log");
    c.name = "raw".into();
    imud::offline::record(sim, &c).unwrap().files.remove(0)
}

/// Runs `imu-calibrate INPUT... --reference-free` from a neutral model against the truth and
/// checks what both tests check: every pose found, the offsets estimated and said, every
/// parameter within 3 standard errors of the truth.
fn calibrate_and_check(dir: &Path, inputs: &[&std::ffi::OsStr]) {
    let truth_model = repo_path("config/models/raw-uncompensated.toml");
    let model = dir.join("model.toml");
    std::fs::write(&model, MODEL).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_imu-calibrate"))
        .args(inputs)
        .args(["--reference-free", "--latitude-deg", "40"])
        .args(["--gravity-m-s2", "9.80665", "--model"])
        .arg(&model)
        .arg("--truth")
        .arg(&truth_model)
        .arg("--json")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let fit = &j["fit"];
    // A first still position and 40 poses of 3 s: all found and used.
    assert_eq!(
        fit["poses"].as_array().unwrap().len(),
        41,
        "{}",
        fit["poses"]
    );
    assert_eq!(fit["moves"].as_array().unwrap().len(), 40);
    let notes = fit["notes"].to_string();
    // The gyro offset was estimated (truth: 5.0, -9.0, 6.5 deg/s) and said.
    assert!(notes.contains("the gyro reads [5.0"), "{notes}");
    assert!(notes.contains("-9.0"), "{notes}");
    assert!(notes.contains("started from the ellipsoid"), "{notes}");
    let rows = j["truth_comparison"].as_array().unwrap();
    let mut fitted = 0;
    for r in rows {
        let name = format!("{} {}", r["triad"], r["name"]);
        if let Some(z) = r["error_in_se"].as_f64() {
            fitted += 1;
            assert!(z.abs() < 3.0, "{name}: {r}");
        } else {
            // Only the accel's gauge is held.
            assert!(
                name.starts_with("\"accel\"") && name.contains("misalignment"),
                "{name} not fitted: {r}"
            );
        }
    }
    assert_eq!(fitted, 9 + 12, "{rows:?}");
}

#[test]
fn hand_held_raw_poses_calibrate_without_preprocessing() {
    let dir = tempfile::tempdir().unwrap();
    let rec = record_hand_held_raw(dir.path());
    calibrate_and_check(dir.path(), &[rec.as_os_str()]);
}

#[test]
fn raw_counts_in_two_whitespace_text_files_calibrate_with_one_command() {
    // The same scenario exported by imu-sim as another tool would export a recording: accel
    // and gyro in two files of whitespace-separated `t x y z`, the device's unsigned 16-bit
    // counts around 32768, no header (the first line is data), extension .txt.
    let dir = tempfile::tempdir().unwrap();
    let mut sim = imu_sim::SimOptions::from_files(
        &repo_path("config/scenarios/hand-held-raw.toml"),
        Some(&repo_path("config/models/raw-uncompensated.toml")),
    )
    .unwrap();
    sim.seed = 23;
    let hand = sim.scenario.hand;
    assert!(
        hand.tremor_deg > 0.0 && hand.tilt_noise_deg >= 3.0,
        "{hand:?}"
    );
    let out = imu_sim::export::export_text(
        &sim,
        &dir.path().join("export"),
        imu_sim::export::ExportUnits::RawCounts,
    )
    .unwrap();
    let first = std::fs::read_to_string(&out.accel).unwrap();
    let first = first.lines().next().unwrap();
    assert!(
        first.split_whitespace().count() == 4 && first.starts_with("0.000000 "),
        "{first}"
    );
    let accel_unit = format!("counts:{}@32768", out.accel_count_m_s2);
    let gyro_unit = format!("counts:{}@32768", out.gyro_count_rad_s);
    calibrate_and_check(
        dir.path(),
        &[
            out.accel.as_os_str(),
            "--gyro-csv".as_ref(),
            out.gyro.as_os_str(),
            "--csv-accel".as_ref(),
            accel_unit.as_ref(),
            "--csv-gyro".as_ref(),
            gyro_unit.as_ref(),
        ],
    );
}
