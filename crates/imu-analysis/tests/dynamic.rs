//! Truth-based tests of the dynamic analysis: 30-degree index-table steps through the daemon's
//! offline pipeline; timing offset recovery, raw drift equal to the truth gyro bias, and the
//! drop in drift when the calibration equals the truth model.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use imu_analysis::characterize::dynamic::{DynamicOptions, Reference, analyze, compare};
use imu_analysis::input::{Source, read_mcap};

const SCENARIO: &str = r#"
name = "dynamic-short"
description = "index-table steps for tests"
rate-hz = 100.0
latitude-deg = 40.0

[[segment]]
kind = "static"
orientation = { z = "up", x = "north" }
duration-s = 10.0

[[segment]]
kind = "index-table"
axis = "z"
step-deg = 30.0
positions = 12
dwell-s = 5.0
move-s = 1.5

[[segment]]
kind = "static"
duration-s = 10.0
"#;

fn model_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/models/example-3dm-gx1.toml")
}

#[test]
fn offset_drift_and_calibration() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("scenario.toml");
    std::fs::write(&scenario, SCENARIO).unwrap();
    let mut sim = imu_sim::SimOptions::from_files(&scenario, Some(&model_path())).unwrap();
    sim.seed = 21;
    let truth_path = dir.path().join("truth.mcap");
    sim.truth_out = Some(truth_path.clone());
    let mut c = imud::config::Config::default();
    c.log.dir = dir.path().join("log");
    c.name = "t".into();
    // The daemon corrects with the truth model itself: a perfect calibration.
    c.calibration.path = Some(model_path());
    let out = imud::offline::record(sim, &c).unwrap();
    let truth = imu_rec::truth::read_truth(&truth_path).unwrap();
    let reference = Reference::from_truth(&truth, "truth");
    let raw = read_mcap(&out.files[0], Source::Raw, None).unwrap();
    let corrected = read_mcap(&out.files[0], Source::Corrected, None).unwrap();
    let opts = DynamicOptions::default();
    let r_raw = analyze(&raw, &reference, &opts).unwrap();
    let r_cor = analyze(&corrected, &reference, &opts).unwrap();
    assert!(r_raw.rate_correlation > 0.9 && r_raw.sign > 0.0);
    assert!(r_raw.reference_travel_deg > 300.0);

    // Raw drift = gyro z bias + g-sensitivity (z up) + the Earth rate on z at 40 deg latitude.
    let earth_z = 7.292_115e-5 * 40f64.to_radians().sin();
    let predicted_deg_s = (1.05e-2 + 2.2e-5 * 9.806_65 + earth_z).to_degrees();
    assert!(
        (r_raw.growth_deg_s - predicted_deg_s).abs() < 0.05 * predicted_deg_s,
        "raw growth {} deg/s vs {predicted_deg_s}",
        r_raw.growth_deg_s
    );
    let report = compare(&reference, Some(r_raw.clone()), Some(r_cor.clone()));
    let f = report.growth_reduction_factor.unwrap();
    assert!(
        f > 10.0,
        "calibration only reduces the growth {f}x: {}",
        report.summary
    );

    // Shift the reference clock by 30 ms (as a CSV of the table angle): the analysis finds it.
    let shift_s = 0.030;
    let mut csv = String::from("time_s,angle_deg\n");
    let mut last_t = f64::NEG_INFINITY;
    for (t, a) in reference.t_s.iter().zip(&reference.angle_rad) {
        // Temperature polls share a time stamp with a data sample in the truth file.
        if *t > last_t {
            writeln!(csv, "{:.6},{:.9}", t + shift_s, a.to_degrees()).unwrap();
            last_t = *t;
        }
    }
    let csv_path = dir.path().join("angle.csv");
    std::fs::write(&csv_path, csv).unwrap();
    let shifted = Reference::read_csv(&csv_path).unwrap();
    let r_shift = analyze(&raw, &shifted, &opts).unwrap();
    let found = r_shift.reference_delay_s - r_raw.reference_delay_s;
    assert!(
        (found - shift_s).abs() < 3e-3,
        "found {found} s, shifted {shift_s} s"
    );
    // Once the offset is removed the drift is the same.
    assert!((r_shift.growth_deg_s - r_raw.growth_deg_s).abs() < 0.01 * r_raw.growth_deg_s);
}
