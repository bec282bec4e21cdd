//! Truth tests of the calibration fit: short simulated index-table and Earth-rate recordings
//! through the daemon's offline pipeline, fitted against the simulator's truth; every fitted
//! parameter must lie within 3 of its own standard errors of the hidden truth model.

use std::path::{Path, PathBuf};

use imu_analysis::ImuSeries;
use imu_analysis::fit::{
    CalibrateOptions, CalibrationFit, FitResult, bias_drift_from_noise, calibrate,
};
use imu_analysis::input::{Source, read_mcap};
use imu_analysis::reference::Reference;
use imu_analysis::segment::SegmentKind;
use imu_bus::truth::read_truth;
use imu_model::{Calibration, EffectKind, Measured, Triad, TriadModel, Vec3};

/// Paper 3.1.2 shortened: 2 x 6 positions, 60-degree steps, 20 s each.
const INDEX_TABLE: &str = r#"
name = "index-table-short"
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
"#;

/// Paper 3.2.2, Table 1, with 60 s per position instead of 600 s.
const EARTH_RATE: &str = r#"
name = "earth-rate-short"
rate-hz = 100.0
latitude-deg = 40.0
transition-s = 4.0

[[segment]]
kind = "static"
orientation = { z = "up", x = "north", y = "west" }
duration-s = 60.0
[[segment]]
kind = "static"
orientation = { z = "up", x = "west", y = "south" }
duration-s = 60.0
[[segment]]
kind = "static"
orientation = { z = "up", x = "south", y = "east" }
duration-s = 60.0
[[segment]]
kind = "static"
orientation = { z = "up", x = "east", y = "north" }
duration-s = 60.0
[[segment]]
kind = "static"
orientation = { z = "north", x = "east", y = "down" }
duration-s = 60.0
[[segment]]
kind = "static"
orientation = { z = "north", x = "up", y = "east" }
duration-s = 60.0
[[segment]]
kind = "static"
orientation = { z = "north", x = "west", y = "up" }
duration-s = 60.0
[[segment]]
kind = "static"
orientation = { z = "north", x = "down", y = "west" }
duration-s = 60.0
"#;

fn model_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/models/example-3dm-gx1.toml")
}

struct Run {
    _dir: tempfile::TempDir,
    series: ImuSeries,
    truth: Reference,
    truth_model: Calibration,
}

fn record(scenario_text: &str, seed: u64) -> Run {
    let seed = std::env::var("CAL_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(seed);
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("scenario.toml");
    std::fs::write(&scenario, scenario_text).unwrap();
    let mut sim = imu_sim::SimOptions::from_files(&scenario, Some(&model_path())).unwrap();
    sim.seed = seed;
    let truth_path = dir.path().join("truth.mcap");
    sim.truth_out = Some(truth_path.clone());
    let mut c = imud::config::Config::default();
    c.log.dir = dir.path().join("log");
    c.name = "t".into();
    let out = imud::offline::record(sim, &c).unwrap();
    assert_eq!(out.files.len(), 1, "{:?}", out.files);
    let series = read_mcap(&out.files[0], Source::Raw, None).unwrap();
    let truth = Reference::Truth(read_truth(&truth_path).unwrap());
    let truth_model = Calibration::load(&model_path()).unwrap();
    Run {
        _dir: dir,
        series,
        truth,
        truth_model,
    }
}

/// Default options plus the bias wander over the recording, from the noise terms a noise
/// characterisation (imu-noise) would give; here taken from the truth model's noise.
fn options(run: &Run) -> CalibrateOptions {
    let duration_s = run.series.t_s.last().unwrap() - run.series.t_s[0];
    let drift = |n: &Option<imu_model::NoiseModel>| {
        n.as_ref().map(|n| bias_drift_from_noise(n, duration_s))
    };
    CalibrateOptions {
        accel_bias_drift_m_s2: drift(&run.truth_model.accel.noise),
        gyro_bias_drift_rad_s: drift(&run.truth_model.gyro.noise),
        ..CalibrateOptions::default()
    }
}

/// Fitted value, truth and error in standard errors for every fitted parameter of `fit`
/// whose effect is present in the truth (absent effects have truth 0).
fn z_scores(fit: &FitResult, truth: &TriadModel, triad: Triad) -> Vec<(String, f64, f64, f64)> {
    let names = truth.param_names(triad);
    let values = truth.params();
    fit.free
        .iter()
        .map(|&i| {
            let name = &fit.names[i];
            let t = names
                .iter()
                .position(|n| n == name)
                .map_or(0.0, |k| values[k]);
            let se = fit.std_errors[i].unwrap();
            (name.clone(), fit.params[i], t, (fit.params[i] - t) / se)
        })
        .collect()
}

fn report(label: &str, z: &[(String, f64, f64, f64)]) {
    for (n, f, t, z) in z {
        eprintln!("{label} {n:<22} fit {f:>12.4e} truth {t:>12.4e} z {z:>6.2}");
    }
}

/// Calibration of the standard errors over several seeds: the errors in SE must look like a
/// unit normal (RMS near 1, almost none beyond 3). With ~20 parameters per fit a single seed
/// has a few per cent chance of one |z| > 3 even with exact standard errors.
fn check_z_statistics(all: &[f64]) {
    let rms = (all.iter().map(|z| z * z).sum::<f64>() / all.len() as f64).sqrt();
    let beyond = all.iter().filter(|z| z.abs() > 3.0).count();
    eprintln!("{} z-scores: RMS {rms:.2}, {beyond} beyond 3", all.len());
    assert!((0.6..1.5).contains(&rms), "RMS z {rms}");
    assert!(
        beyond as f64 <= 0.03 * all.len() as f64,
        "{beyond} of {}",
        all.len()
    );
    assert!(all.iter().all(|z| z.abs() < 4.5), "{all:?}");
}

#[test]
fn index_table_recovers_accel_bias_scale_misalignment() {
    let run = record(INDEX_TABLE, 11);
    // The truth has a quadratic scale nonlinearity (3e-5..4e-5 per m/s^2, ~0.3 % at 1 g):
    // left out of the model, x^2 averages into the bias (bias.z ends > 5 SE off), so the fitted
    // model includes it.
    let mut opts = options(&run);
    opts.accel.add(EffectKind::ScaleNonlinearity);
    // (The same drift settings serve the other seeds below: same scenario, same duration.)
    let fit = calibrate(&run.series, &run.truth, &opts).unwrap();
    assert_eq!(
        fit.segmentation.count(SegmentKind::Static),
        12,
        "{:#?}",
        fit.segmentation
    );
    assert_eq!(fit.segmentation.count(SegmentKind::Plateau), 0);
    // 60-degree steps from a horizontal start give an axis only 0 and +/-sin 60: x^3 is then
    // exactly proportional to x, and the fit must say so instead of fitting it.
    for u in &fit.accel.unobservable {
        assert!(u.name.starts_with("scale-nonlinearity.cubic"), "{u:?}");
    }
    assert!(
        fit.accel.unobservable.len() <= 2,
        "{:?}",
        fit.accel.warnings
    );
    let z = z_scores(&fit.accel, &run.truth_model.accel, Triad::Accel);
    report("accel", &z);
    assert_eq!(z.len(), 18 - fit.accel.unobservable.len());
    for (n, f, t, z) in &z {
        assert!(z.abs() < 3.0, "{n}: fit {f:e} truth {t:e} ({z:.2} SE)");
    }
    let mut all: Vec<f64> = z.iter().map(|r| r.3).collect();
    for seed in [1, 3, 5] {
        let r = record(INDEX_TABLE, seed);
        let f = calibrate(&r.series, &r.truth, &opts).unwrap();
        all.extend(
            z_scores(&f.accel, &r.truth_model.accel, Triad::Accel)
                .iter()
                .map(|r| r.3),
        );
    }
    check_z_statistics(&all);
    // Without plateaus the gyro gains are left out, and the bias is still fitted.
    assert!(fit.notes.iter().any(|n| n.contains("no rate plateaus")));
    assert!(fit.gyro.names.iter().all(|n| n.starts_with("bias")));

    // The calibration file round-trips and applying it brings the static segment means to
    // the truth within the noise.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cal.toml");
    fit.calibration.save(&path).unwrap();
    let loaded = Calibration::load(&path).unwrap();
    assert_eq!(loaded.accel.params(), fit.calibration.accel.params());
    // Fitted effects carry their standard errors; an effect with a held (unobservable)
    // parameter carries none rather than a false 0.
    let se = loaded.accel.std_errors();
    let names = loaded.accel.param_names(Triad::Accel);
    for (n, se) in names.iter().zip(&se) {
        let held = n.starts_with("scale-nonlinearity") && !fit.accel.unobservable.is_empty();
        assert_eq!(se.is_some(), !held, "{n}: {se:?}");
    }
    check_correction(&fit, &run, &loaded);
}

/// Mean corrected accel per static segment vs the mean truth: the error must drop from the
/// uncalibrated level (tens of mg) to the segment noise level.
fn check_correction(fit: &CalibrationFit, run: &Run, cal: &Calibration) {
    let mut raw_sq = 0.0;
    let mut cor_sq = 0.0;
    let mut k = 0.0;
    for (seg, t) in fit.segmentation.segments.iter().zip(&fit.segment_truth) {
        if seg.kind != SegmentKind::Static {
            continue;
        }
        let mut mean = Vec3::zeros();
        for i in seg.range() {
            let m = Measured {
                accel_m_s2: Vec3::from(run.series.accel_m_s2[i]),
                gyro_rad_s: Vec3::from(run.series.gyro_rad_s[i]),
                mag_gauss: Vec3::zeros(),
            };
            let c = cal.correct(&m, t.temp_c, t.time_since_power_on_s, Vec3::zeros());
            mean += c.accel_m_s2 / seg.n as f64;
        }
        let truth = Vec3::from(t.specific_force_m_s2);
        raw_sq += (seg.mean_accel() - truth).norm_squared();
        cor_sq += (mean - truth).norm_squared();
        k += 1.0;
    }
    let raw_rms = (raw_sq / k).sqrt();
    let cor_rms = (cor_sq / k).sqrt();
    let fit_rms = Vec3::from(fit.accel.residual_rms).norm();
    eprintln!(
        "accel segment-mean error: raw {raw_rms:.3e}, corrected {cor_rms:.3e}, fit residual {fit_rms:.3e} m/s^2"
    );
    assert!(raw_rms > 0.1, "{raw_rms}");
    // The corrected error is the fit residual (bias instability, unmodelled quadratic
    // nonlinearity): at most a few mg, and close to the residual the fit reported.
    assert!(cor_rms < 0.01, "{cor_rms}");
    assert!(cor_rms < 1.5 * fit_rms + 1e-4, "{cor_rms} vs {fit_rms}");
}

#[test]
fn earth_rate_recovers_gyro_bias_and_g_sensitivity() {
    let run = record(EARTH_RATE, 5);
    let mut opts = options(&run);
    opts.gyro.add(EffectKind::GSensitivity);
    let fit = calibrate(&run.series, &run.truth, &opts).unwrap();
    assert_eq!(
        fit.segmentation.count(SegmentKind::Static),
        8,
        "{:#?}",
        fit.segmentation
    );
    let z = z_scores(&fit.gyro, &run.truth_model.gyro, Triad::Gyro);
    report("gyro", &z);
    assert_eq!(z.len(), 12, "{:?}", fit.gyro.warnings);
    for (n, f, t, z) in &z {
        assert!(z.abs() < 3.0, "{n}: fit {f:e} truth {t:e} ({z:.2} SE)");
    }
    let mut all: Vec<f64> = z.iter().map(|r| r.3).collect();
    for seed in [1, 3, 7] {
        let r = record(EARTH_RATE, seed);
        let f = calibrate(&r.series, &r.truth, &opts).unwrap();
        all.extend(
            z_scores(&f.gyro, &r.truth_model.gyro, Triad::Gyro)
                .iter()
                .map(|r| r.3),
        );
    }
    check_z_statistics(&all);
    // The bias is determined far better than its size (the floor is its instability).
    for i in 0..3 {
        assert!(fit.gyro.std_errors[i].unwrap() < 0.1 * fit.gyro.params[i].abs());
    }
}

#[test]
fn one_position_cannot_separate_g_sensitivity() {
    let one = EARTH_RATE
        .split("[[segment]]")
        .take(3)
        .collect::<Vec<_>>()
        .join("[[segment]]");
    let run = record(&one, 3);
    let with = |kinds: &[EffectKind]| {
        let mut m = TriadModel::default();
        kinds.iter().for_each(|k| m.add(*k));
        m
    };
    let opts = CalibrateOptions {
        accel: with(&[EffectKind::Bias]),
        gyro: with(&[EffectKind::Bias, EffectKind::GSensitivity]),
        ..CalibrateOptions::default()
    };
    let fit = calibrate(&run.series, &run.truth, &opts).unwrap();
    // Two positions, both z up: only the bias is fitted, g-sensitivity is reported.
    assert_eq!(fit.gyro.free.len(), 3, "{:?}", fit.gyro.warnings);
    assert_eq!(fit.gyro.unobservable.len(), 9);
    assert!(
        fit.gyro
            .warnings
            .iter()
            .any(|w| w.contains("g-sensitivity"))
    );
    let e = calibrate(&run.series, &run.truth, &CalibrateOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("still positions"), "{e}");
}
