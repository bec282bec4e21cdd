//! End-to-end noise test through the real recording path: the simulator's device core and the
//! daemon's offline recorder write a 30-minute static MCAP recording with the example 3DM-GX1
//! truth model; we read it back with `input::read_any`, compute OADEV and fit the IEEE terms.
//! Thirty minutes pin down the white noise N (asserted to 10%); B and K need the 6-hour test
//! (`noise_truth.rs`), which generates its series directly for speed.

use std::path::PathBuf;

use imu_analysis::Source;
use imu_analysis::input::{CsvOptions, read_any};
use imu_model::Calibration;
use imu_stats::allan::{Kind, Options, TauSet, deviation};
use imu_stats::noise_terms::fit_terms;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

#[test]
fn thirty_minute_recording_white_noise_matches_the_truth_model() {
    let dir = tempfile::tempdir().unwrap();
    let truth_path = repo().join("config/models/example-3dm-gx1.toml");
    let scenario = dir.path().join("static-30min.toml");
    std::fs::write(
        &scenario,
        r#"name = "static-30min"
description = "30 min level and still"
rate-hz = 100.0
latitude-deg = 40.0

[temperature]
kind = "constant"
value-c = 25.0

[[segment]]
kind = "static"
orientation = { roll-deg = 0.0, pitch-deg = 0.0, yaw-deg = 0.0 }
duration-s = 1800.0
label = "static 30 min"
"#,
    )
    .unwrap();
    let mut sim = imu_sim::SimOptions::from_files(&scenario, Some(&truth_path)).unwrap();
    sim.seed = 11;
    sim.truth_out = None;
    let mut config = imud::config::Config::default();
    config.log.dir = dir.path().join("log");
    config.name = "noise".into();
    let report = imud::offline::record(sim, &config).unwrap();
    let series = read_any(&report.files[0], Source::Corrected, &CsvOptions::default()).unwrap();
    let rate_hz = series.sample_rate_hz();
    assert!((rate_hz - 100.0).abs() < 0.5, "rate {rate_hz}");

    let truth = Calibration::from_toml_str(&std::fs::read_to_string(&truth_path).unwrap(), "truth")
        .unwrap();
    let opts = Options {
        taus: TauSet::PerDecade(8),
        ..Options::default()
    };
    for (sensor, data, white) in [
        (
            "accel",
            &series.accel_m_s2,
            truth.accel.noise.unwrap().white_density,
        ),
        (
            "gyro",
            &series.gyro_rad_s,
            truth.gyro.noise.unwrap().white_density,
        ),
    ] {
        for axis in 0..3 {
            let y: Vec<f64> = data.iter().map(|v| v[axis]).collect();
            let curve = deviation(Kind::Oadev, &y, 1.0 / rate_hz, &opts).unwrap();
            let t = fit_terms(&curve).unwrap();
            let n = t.n_u_per_sqrt_hz.value;
            assert!(
                (n / white[axis] - 1.0).abs() < 0.10,
                "{sensor}[{axis}]: N {n:e} vs truth {:e} ({t:?})",
                white[axis]
            );
        }
    }
}
