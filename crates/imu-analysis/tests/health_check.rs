//! The offline health check against the daemon and against the truth: the check of a recording's
//! corrected stream gives exactly the still windows, residuals, p-values and states the daemon
//! reported live on it (`/imud/health`), and a calibration whose biases (or accel scales) are
//! off by known vectors is found off by them, within the uncertainty the check reports, which
//! matches the scatter over seeds.

use std::path::{Path, PathBuf};

use imu_analysis::health::{CheckOptions, check_series};
use imu_analysis::input::{CsvOptions, Source, read_any};
use imu_model::Calibration;
use imu_model::units::STANDARD_GRAVITY_M_S2;
use imu_rec::recording::read_recording;
use imu_rec::sample::health_state;
use imu_sim::SimOptions;
use imud::config::Config;

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(path)
}

/// The offline path's synthetic monotonic time of the first sample, ns.
const MONO_ORIGIN_NS: u64 = 1_000_000_000_000;

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a.is_nan() && b.is_nan()) || (a - b).abs() <= tol * a.abs().max(b.abs()).max(1.0)
}

#[test]
fn the_offline_check_reproduces_the_daemons_live_reports() {
    let dir = tempfile::tempdir().unwrap();
    let model = repo("config/models/example-3dm-gx1.toml");
    let mut sim =
        SimOptions::from_files(&repo("config/scenarios/health-knock.toml"), None).unwrap();
    sim.seed = 7;
    let mut config = Config {
        name: "knock".into(),
        ..Config::default()
    };
    config.log.dir = dir.path().join("rec");
    config.calibration.path = Some(model.clone());
    config.health.latitude_deg = Some(40.0);
    config.health.gravity_m_s2 = Some(STANDARD_GRAVITY_M_S2);
    let out = imud::offline::record(sim, &config).unwrap();
    assert_eq!(out.files.len(), 1, "{:?}", out.files);
    let live = read_recording(&out.files[0]).unwrap().health;
    let series = read_any(&out.files[0], Source::Corrected, &CsvOptions::default()).unwrap();
    let calibration = Calibration::load(&model).unwrap();
    let check = check_series(&series, Some(&calibration), &config.health.check_options());
    // The knock at 250 s is seen: the daemon's reports are not all `ok`.
    assert!(
        live.iter().any(|r| r.accel_state == health_state::DEGRADED),
        "the knock was not flagged live"
    );
    assert!(live.len() >= 20, "{} live reports", live.len());
    assert_eq!(check.windows.len(), live.len());
    for (i, (w, r)) in check.windows.iter().zip(&live).enumerate() {
        let start_s = (r.window_start_ns - MONO_ORIGIN_NS) as f64 * 1e-9;
        let duration_s = (r.t_sample_ns - r.window_start_ns) as f64 * 1e-9;
        assert!(
            (w.start_s - start_s).abs() < 1e-9,
            "window {i}: {w:?} {r:?}"
        );
        assert!((w.duration_s - duration_s).abs() < 1e-9, "window {i}");
        let pairs = [
            (w.accel_residual_m_s2, r.accel_residual_m_s2),
            (w.accel_std_m_s2, r.accel_expected_std_m_s2),
            (w.gyro_magnitude_residual_rad_s, r.gyro_residual_rad_s),
            (
                w.gyro_vertical_residual_rad_s,
                r.gyro_vertical_residual_rad_s,
            ),
            (
                (w.gyro_std_rad_s.iter().map(|s| s * s).sum::<f64>() / 3.0).sqrt(),
                r.gyro_expected_std_rad_s,
            ),
            (w.accel_p, r.accel_p),
            (w.gyro_p, r.gyro_p),
        ];
        for (k, (a, b)) in pairs.into_iter().enumerate() {
            assert!(close(a, b, 1e-9), "window {i}, value {k}: {a} vs {b}");
        }
        assert_eq!(
            w.accel_state,
            health_state::name(r.accel_state),
            "window {i}"
        );
        assert_eq!(w.gyro_state, health_state::name(r.gyro_state), "window {i}");
    }
    assert_eq!(check.noise_source, "tables");
    assert!(check.rejections >= 1);
    assert!(check.accel_offset_3d, "25 orientations make a 3-D offset");
}

/// Twelve rests of 30 s in orientations spanning space, 3 s moves between them.
const SCENARIO: &str = r#"
name = "health-offset"
rate-hz = 100.0
latitude-deg = 40.0

[[segment]]
kind = "static"
duration-s = 30.0
"#;

const ORIENTATIONS: [(f64, f64, f64); 11] = [
    (25.0, 13.4, -37.9),
    (-13.6, -40.0, -48.4),
    (-40.0, 12.3, -102.7),
    (-12.4, 40.0, -154.9),
    (90.0, 0.0, 20.0),
    (0.0, 90.0, 75.0),
    (-90.0, 0.0, 130.0),
    (0.0, -90.0, -60.0),
    (180.0, 0.0, 10.0),
    (40.0, 1.5, -158.7),
    (2.0, -25.0, 47.0),
];

/// `text` with a bias line `key = [..]` of table `table` shifted by `by`.
fn shifted(text: &str, table: &str, by: [f64; 3]) -> String {
    let start = text.find(&format!("[{table}]")).unwrap();
    let at = start + text[start..].find("value = [").unwrap();
    let end = at + text[at..].find(']').unwrap();
    let old: Vec<f64> = text[at + "value = [".len()..end]
        .split(',')
        .map(|v| v.trim().parse().unwrap())
        .collect();
    let new = format!(
        "value = [{:e}, {:e}, {:e}]",
        old[0] + by[0],
        old[1] + by[1],
        old[2] + by[2]
    );
    format!("{}{}{}", &text[..at], new, &text[end + 1..])
}

/// The offline check of SCENARIO's rests over ORIENTATIONS, simulated from the example model
/// and corrected with `calibration_text`, for seeds 1..=10.
fn checks_over_seeds(calibration_text: &str) -> Vec<imu_analysis::health::HealthCheck> {
    let dir = tempfile::tempdir().unwrap();
    let mut scenario = SCENARIO.to_string();
    for (r, p, y) in ORIENTATIONS {
        scenario.push_str(&format!(
            "\n[[segment]]\nkind = \"static\"\norientation = {{ roll-deg = {r}, pitch-deg = {p}, yaw-deg = {y} }}\nmove-s = 3.0\nduration-s = 30.0\n"
        ));
    }
    let truth = std::fs::read_to_string(repo("config/models/example-3dm-gx1.toml")).unwrap();
    let cal_path = dir.path().join("off.toml");
    std::fs::write(&cal_path, calibration_text).unwrap();
    let calibration = Calibration::load(&cal_path).unwrap();
    let options = CheckOptions::at(Some(40.0), 0.0, Some(STANDARD_GRAVITY_M_S2), 1e-4);
    (1..=10u64)
        .map(|seed| {
            let session = imud::offline::record_session_text(
                dir.path(),
                &format!("s{seed}"),
                &scenario,
                Some(&truth),
                seed,
                Some(&cal_path),
            )
            .unwrap();
            let series = read_any(
                &session.recording,
                Source::Corrected,
                &CsvOptions::default(),
            )
            .unwrap();
            let c = check_series(&series, Some(&calibration), &options);
            // Every rest but the last, which the recording ends before motion closes it (as
            // live).
            assert_eq!(c.windows.len(), ORIENTATIONS.len(), "seed {seed}");
            std::fs::remove_dir_all(session.recording.parent().unwrap()).unwrap();
            c
        })
        .collect()
}

/// Asserts that each run's estimates `(value, std)` of `truth` lie within 3 of their standard
/// deviations, and that the reported standard deviation is the scatter over the runs within a
/// factor of 2.
fn assert_recovered(name: &str, runs: &[([f64; 3], [f64; 3])], truth: [f64; 3]) {
    for (seed, (v, s)) in runs.iter().enumerate() {
        for i in 0..3 {
            assert!(
                (v[i] - truth[i]).abs() < 3.0 * s[i],
                "run {seed} {name} {i}: {} +/- {}, truth {}",
                v[i],
                s[i],
                truth[i]
            );
        }
    }
    for i in 0..3 {
        let n = runs.len() as f64;
        let rms_error = (runs
            .iter()
            .map(|(v, _)| (v[i] - truth[i]).powi(2))
            .sum::<f64>()
            / n)
            .sqrt();
        let reported = (runs.iter().map(|(_, s)| s[i] * s[i]).sum::<f64>() / n).sqrt();
        let ratio = reported / rms_error;
        assert!(
            (0.5..2.0).contains(&ratio),
            "{name} {i}: reported {reported:.3e}, scatter {rms_error:.3e}"
        );
    }
}

#[test]
fn a_calibrations_bias_errors_are_recovered_within_the_reported_uncertainty() {
    let truth = std::fs::read_to_string(repo("config/models/example-3dm-gx1.toml")).unwrap();
    let d = [0.02, -0.015, 0.01];
    let e = [2.0e-3, -1.0e-3, 1.5e-3];
    let checks = checks_over_seeds(&shifted(&shifted(&truth, "accel.bias", d), "gyro.bias", e));
    for c in &checks {
        assert!(c.accel_offset_3d, "not 3-D");
    }
    // The calibration's bias is the truth's + d: the stream reads d too little.
    let accel: Vec<_> = checks
        .iter()
        .map(|c| (c.accel_offset_m_s2, c.accel_offset_std_m_s2))
        .collect();
    assert_recovered("accel offset", &accel, d.map(|v| -v));
    let gyro: Vec<_> = checks
        .iter()
        .map(|c| (c.gyro_offset_rad_s, c.gyro_offset_std_rad_s))
        .collect();
    assert_recovered("gyro offset", &gyro, e.map(|v| -v));
}

#[test]
fn a_calibrations_accel_scale_errors_are_recovered_by_rests_spanning_both_ways() {
    // Scale and bias both off: the joint fit finds each (the calibrated stream reads
    // 1 - delta times physics, and d too little), within the uncertainty it reports.
    let truth = std::fs::read_to_string(repo("config/models/example-3dm-gx1.toml")).unwrap();
    let delta = [2.0e-3, -1.5e-3, 1.0e-3];
    let d = [0.02, -0.015, 0.01];
    let checks = checks_over_seeds(&shifted(
        &shifted(&truth, "accel.scale", delta),
        "accel.bias",
        d,
    ));
    let fits: Vec<_> = checks
        .iter()
        .map(|c| {
            c.accel_scale_fit
                .clone()
                .expect("11 rests, each axis up and down")
        })
        .collect();
    for f in &fits {
        assert_eq!(f.windows, ORIENTATIONS.len());
        // The first-order model holds: the residual scatter is the noise tables' (chi^2 with
        // 5 degrees of freedom lies below 4 with probability 0.995).
        assert!(f.reduced_chi2 < 4.0, "{f:?}");
    }
    let scale: Vec<_> = fits
        .iter()
        .map(|f| (f.scale_error, f.scale_error_std))
        .collect();
    assert_recovered("accel scale error", &scale, delta.map(|v| -v));
    let offset: Vec<_> = fits
        .iter()
        .map(|f| (f.offset_m_s2, f.offset_std_m_s2))
        .collect();
    assert_recovered("accel offset with the scale", &offset, d.map(|v| -v));
}
