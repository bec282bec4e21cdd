//! Live calibration health through the daemon's real decode and calibration path at CPU speed
//! (`imud::offline::health_reports`): the simulator's truth model is the calibration, so any
//! rejection is a false alarm, and a knock injected as a `[[disturbance]]` step must be found
//! and sized.

use std::path::{Path, PathBuf};

use imu_bus::CalibrationHealth;
use imu_bus::sample::{health_checks, health_noise_source, health_state};
use imu_sim::SimOptions;
use imud::config::Config;
use imud::offline::health_reports;

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(path)
}

/// The daemon's configuration for the simulator: its latitude and its (standard) gravity.
fn config(calibration: Option<&str>) -> Config {
    let mut c = Config::default();
    c.calibration.path = calibration.map(repo);
    c.health.latitude_deg = Some(40.0);
    c.health.gravity_m_s2 = Some(imu_model::units::STANDARD_GRAVITY_M_S2);
    c
}

fn run(scenario: &str, seed: u64, config: &Config) -> Vec<CalibrationHealth> {
    let mut sim = SimOptions::from_files(&repo(scenario), None).unwrap();
    sim.seed = seed;
    health_reports(sim, config).unwrap()
}

fn tested(reports: &[CalibrationHealth]) -> impl Iterator<Item = &CalibrationHealth> {
    reports.iter().filter(|r| r.accel_p.is_finite())
}

#[test]
fn a_correct_calibration_raises_no_alarm_over_twelve_simulated_hours() {
    let cfg = config(Some("config/models/example-3dm-gx1.toml"));
    let (mut windows, mut alarms) = (0usize, Vec::new());
    let (mut accel_p, mut gyro_p) = (Vec::new(), Vec::new());
    for seed in 1..=12 {
        let reports = run("config/scenarios/health-hour.toml", seed, &cfg);
        for r in tested(&reports) {
            windows += 1;
            accel_p.push(r.accel_p);
            gyro_p.push(r.gyro_p);
            assert_eq!(r.noise_source, health_noise_source::TABLES);
            assert_ne!(r.checks & health_checks::EARTH_RATE_VERTICAL, 0);
            if r.accel_state != health_state::OK || r.gyro_state != health_state::OK {
                alarms.push((seed, r.still_windows, r.accel_p, r.gyro_p));
            }
        }
    }
    // 150 rests an hour; the first window of each run has no history but is tested.
    assert!(
        windows >= 12 * 140,
        "only {windows} still windows were tested"
    );
    assert!(alarms.is_empty(), "false alarms: {alarms:?}");
    // The p-values are those of a calibrated test: about 5 % below 0.05, never far more
    // (an underestimated scatter would flood the alarm), nor all near 1 (a test that cannot see).
    for (name, p) in [("accel", &accel_p), ("gyro", &gyro_p)] {
        let below = p.iter().filter(|p| **p < 0.05).count() as f64 / p.len() as f64;
        assert!(
            (0.005..0.12).contains(&below),
            "{name}: {below:.3} of the windows have p < 0.05"
        );
    }
}

/// Over 40 seeds: a knock of about five times a window's expected scatter is flagged within
/// three still windows (single-window power against 5 sigma at p < 5e-5 is about 0.8 for one
/// degree of freedom and 0.6 for three; the test of the last three windows' mean adds a little),
/// and sized within 30 % by the fifth window after it.
#[test]
fn a_knock_is_flagged_within_three_still_windows_and_its_size_estimated() {
    let cfg = config(Some("config/models/example-3dm-gx1.toml"));
    let origin_ns = 1_000_000_000_000u64; // the offline path's monotonic origin
    let step_ns = 250_000_000_000u64;
    let (accel_step, gyro_step) = (6.0e-3, 2.2e-3);
    let seeds = 11..51u64;
    let (mut flagged_accel, mut flagged_gyro, mut sized_accel, mut sized_gyro) = (0, 0, 0, 0);
    let mut sizes = Vec::new();
    for seed in seeds.clone() {
        let reports: Vec<_> = run("config/scenarios/health-knock.toml", seed, &cfg);
        let before: Vec<_> = tested(&reports)
            .filter(|r| r.t_sample_ns - origin_ns < step_ns)
            .collect();
        let after: Vec<_> = tested(&reports)
            .filter(|r| r.window_start_ns - origin_ns >= step_ns)
            .collect();
        assert!(
            before.len() >= 8 && after.len() >= 8,
            "{seed}: too few windows"
        );
        assert!(
            before
                .iter()
                .all(|r| r.accel_state == health_state::OK && r.gyro_state == health_state::OK),
            "{seed}: alarm before the knock"
        );
        // The knock is about five times the scatter a window may show: for the rate, the step
        // against the per-axis scatter; for |f|, the shift the tilted windows see (the step's
        // projection on gravity, 0.77 to 1 of it) against theirs.
        let median = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let accel_ratio = median(
            &mut after[..3]
                .iter()
                .map(|r| r.accel_residual_m_s2.abs() / r.accel_expected_std_m_s2)
                .collect(),
        );
        let gyro_ratio =
            gyro_step / median(&mut before.iter().map(|r| r.gyro_expected_std_rad_s).collect());
        sizes.push((accel_ratio, gyro_ratio));
        let within_three = |state: fn(&CalibrationHealth) -> u8| {
            after[..3].iter().any(|r| state(r) != health_state::OK)
        };
        flagged_accel += usize::from(within_three(|r| r.accel_state));
        flagged_gyro += usize::from(within_three(|r| r.gyro_state));
        let late = after[5];
        let (accel, gyro) = (late.accel_offset_m_s2, late.gyro_offset_rad_s);
        sized_accel += usize::from((accel[2] - accel_step).abs() < 0.3 * accel_step);
        sized_gyro += usize::from((gyro[0] - gyro_step).abs() < 0.3 * gyro_step);
    }
    let n = seeds.count();
    let mean = |f: fn(&(f64, f64)) -> f64| sizes.iter().map(f).sum::<f64>() / n as f64;
    let (accel_ratio, gyro_ratio) = (mean(|s| s.0), mean(|s| s.1));
    assert!(
        (4.5..6.0).contains(&accel_ratio),
        "accel knock {accel_ratio:.1}x"
    );
    assert!(
        (4.5..6.0).contains(&gyro_ratio),
        "gyro knock {gyro_ratio:.1}x"
    );
    let at_least = |k: usize, share: f64| k as f64 >= share * n as f64;
    assert!(
        at_least(flagged_accel, 0.9) && at_least(flagged_gyro, 0.9),
        "flagged within three windows: accel {flagged_accel}/{n}, gyro {flagged_gyro}/{n}"
    );
    assert!(
        at_least(sized_accel, 0.9) && at_least(sized_gyro, 0.9),
        "sized within 30 %: accel {sized_accel}/{n}, gyro {sized_gyro}/{n}"
    );
}

#[test]
fn an_uncalibrated_stream_is_reported_as_uncalibrated_not_stale() {
    let cfg = config(None);
    let reports = run("config/scenarios/health-knock.toml", 3, &cfg);
    assert!(reports.len() >= 20, "{} windows", reports.len());
    for r in &reports {
        assert_eq!(
            (r.accel_state, r.gyro_state),
            (health_state::UNCALIBRATED, health_state::UNCALIBRATED)
        );
        assert_eq!(r.calibration_id, 0);
        assert!(r.accel_p.is_nan());
    }
}

#[test]
fn bias_tracking_takes_up_a_stale_shift_and_the_stream_agrees_with_physics_again() {
    let mut cfg = config(Some("config/models/example-3dm-gx1.toml"));
    cfg.health.track_bias = true;
    let reports = run("config/scenarios/health-knock.toml", 21, &cfg);
    let tested: Vec<_> = tested(&reports).collect();
    let first_tracked = tested
        .iter()
        .position(|r| r.bias_tracking == 1)
        .expect("a stale triad was never tracked");
    let last = &tested[first_tracked..];
    assert!(last.len() >= 5, "tracking began too late: {}", last.len());
    assert!(last.iter().all(|r| r.bias_tracking == 1));
    // With the offsets applied, the windows agree with gravity and Earth's rate again.
    let tail = &last[last.len() - 4..];
    assert!(
        tail.iter()
            .all(|r| r.accel_state == health_state::OK && r.gyro_state == health_state::OK),
        "{tail:#?}"
    );
    let typical = tail
        .iter()
        .filter(|r| r.accel_residual_m_s2.abs() < 3.0 * r.accel_expected_std_m_s2)
        .count();
    assert!(typical >= 3, "{tail:#?}");
    // Off by default: the same run without it never tracks.
    let off = run(
        "config/scenarios/health-knock.toml",
        21,
        &config(Some("config/models/example-3dm-gx1.toml")),
    );
    assert!(off.iter().all(|r| r.bias_tracking == 0));
}

#[test]
fn a_hidden_temperature_coefficient_is_flagged_as_the_sensor_leaves_the_calibrated_range() {
    let dir = tempfile::tempdir().unwrap();
    let example = std::fs::read_to_string(repo("config/models/example-3dm-gx1.toml")).unwrap();
    // The truth: the example unit plus 6e-4 m/s^2/K about 24.5 C on accel z: under two times a
    // window's scatter (0.7e-3 to 1.4e-3 m/s^2) at the calibrated range's ends, six times at 38 C (a
    // random orientation sees |u_z| of it).
    let truth = dir.path().join("truth.toml");
    std::fs::write(
        &truth,
        format!("{example}\n[accel.temp-bias]\nt0-c = 24.5\ncoefficients = [[0.0, 0.0, 6.0e-4]]\n"),
    )
    .unwrap();
    // The calibration: the unit without it, fitted on data between 22 and 27 C.
    let calibration = dir.path().join("calibration.toml");
    std::fs::write(
        &calibration,
        example.replacen(
            "[provenance]\n",
            "[provenance]\ntemperature-range-c = [22.0, 27.0]\n",
            1,
        ),
    )
    .unwrap();
    let mut cfg = config(None);
    cfg.calibration.path = Some(calibration);
    let mut sim =
        SimOptions::from_files(&repo("config/scenarios/health-thermal.toml"), Some(&truth))
            .unwrap();
    sim.seed = 4;
    let reports = health_reports(sim, &cfg).unwrap();
    let tested: Vec<_> = tested(&reports).collect();
    let (inside, outside): (Vec<&CalibrationHealth>, Vec<&CalibrationHealth>) =
        tested.iter().partition(|r| r.temp_c <= 27.0);
    assert!(
        inside.len() >= 5 && outside.len() >= 20,
        "{} {}",
        inside.len(),
        outside.len()
    );
    let out_of_range = |r: &CalibrationHealth| r.checks & health_checks::TEMP_OUT_OF_RANGE != 0;
    assert!(
        inside
            .iter()
            .all(|r| !out_of_range(r) && r.accel_state == health_state::OK)
    );
    assert!(outside.iter().all(|r| out_of_range(r)));
    let flagged = outside
        .iter()
        .find(|r| r.accel_state != health_state::OK)
        .expect("the thermal bias was never flagged");
    assert!(flagged.temp_c > 28.0, "flagged at {} C", flagged.temp_c);
    // Once warm, most windows are flagged (a window whose orientation puts z near horizontal
    // sees little of a z bias, and three consistent windows in a row turn it `ok` again).
    let warm: Vec<_> = outside.iter().filter(|r| r.temp_c > 38.0).collect();
    let flagged_warm = warm
        .iter()
        .filter(|r| r.accel_state != health_state::OK)
        .count();
    assert!(
        flagged_warm * 10 >= warm.len() * 8,
        "{flagged_warm}/{}",
        warm.len()
    );
    assert!(outside.iter().all(|r| r.gyro_state == health_state::OK));
}
