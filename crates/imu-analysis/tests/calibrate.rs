//! Truth tests of the calibration fit: short simulated index-table, Earth-rate and rate-table
//! recordings through the daemon's offline pipeline, fitted against the simulator's truth. For
//! fixed seeds every fitted parameter must lie within 3 of its own standard errors of the hidden
//! truth model; over 20 seeds of each procedure the errors in standard errors must be distributed
//! like a unit normal (about 95 % within 2 SE), so the standard errors are neither optimistic nor
//! padded.

use std::path::{Path, PathBuf};

use imu_analysis::ImuSeries;
use imu_analysis::calibrate::{
    CalibrateOptions, CalibrationFit, FitResult, bias_drift_from_noise, calibrate,
};
use imu_analysis::input::{Source, read_mcap};
use imu_analysis::reference::Reference;
use imu_analysis::segment::SegmentKind;
use imu_model::{Calibration, EffectKind, Measured, Triad, TriadModel, Vec3};
use imu_rec::truth::read_truth;

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

/// Paper 3.2.3 shortened: each axis in turn on a vertical table axis, plateaus at +/-40 and
/// +/-80 deg/s for 10 s each, and a still position with that axis up and one with it down (so
/// the g-sensitivity of every gyro axis is seen at +g and -g on every accel axis).
const RATE_TABLE: &str = r#"
name = "rate-table-short"
rate-hz = 100.0
latitude-deg = 40.0
transition-s = 5.0

[[segment]]
kind = "static"
orientation = { z = "up", x = "north" }
duration-s = 15.0
[[segment]]
kind = "rate-steps"
axis = "z"
rates-deg-s = [40, 80, -40, -80, 0]
dwell-s = 10.0
accel-deg-s2 = 40.0
[[segment]]
kind = "static"
orientation = { z = "down", x = "north" }
duration-s = 15.0
[[segment]]
kind = "static"
orientation = { x = "up", y = "north" }
duration-s = 15.0
[[segment]]
kind = "rate-steps"
axis = "x"
rates-deg-s = [40, 80, -40, -80, 0]
dwell-s = 10.0
accel-deg-s2 = 40.0
[[segment]]
kind = "static"
orientation = { x = "down", y = "north" }
duration-s = 15.0
[[segment]]
kind = "static"
orientation = { y = "up", z = "north" }
duration-s = 15.0
[[segment]]
kind = "rate-steps"
axis = "y"
rates-deg-s = [40, 80, -40, -80, 0]
dwell-s = 10.0
accel-deg-s2 = 40.0
[[segment]]
kind = "static"
orientation = { y = "down", z = "north" }
duration-s = 15.0
"#;

fn model_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/models/example-3dm-gx1.toml")
}

struct Run {
    _dir: tempfile::TempDir,
    series: ImuSeries,
    truth: Reference,
    truth_path: PathBuf,
    truth_model: Calibration,
}

/// Records `scenario_text` with `seed`, or with `$CAL_SEED` when set (to explore other seeds).
fn record(scenario_text: &str, seed: u64) -> Run {
    let seed = std::env::var("CAL_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(seed);
    record_seed(scenario_text, seed)
}

fn record_seed(scenario_text: &str, seed: u64) -> Run {
    let dir = tempfile::tempdir().unwrap();
    let model = std::fs::read_to_string(model_path()).unwrap();
    let session = imud::offline::record_session_text(
        dir.path(),
        "t",
        scenario_text,
        Some(&model),
        seed,
        None,
    )
    .unwrap();
    let series = read_mcap(&session.recording, Source::Raw, None).unwrap();
    let truth = Reference::Truth(read_truth(&session.truth).unwrap());
    let truth_model = Calibration::load(&model_path()).unwrap();
    Run {
        _dir: dir,
        series,
        truth,
        truth_path: session.truth,
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
        accel_noise: run.truth_model.accel.noise.clone(),
        gyro_noise: run.truth_model.gyro.noise.clone(),
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

#[test]
fn index_table_recovers_accel_bias_scale_misalignment() {
    let run = record(INDEX_TABLE, 11);
    // The truth has a quadratic scale nonlinearity (3e-5..4e-5 per m/s^2, ~0.3 % at 1 g):
    // left out of the model, x^2 averages into the bias (bias.z ends > 5 SE off), so the fitted
    // model includes it.
    let mut opts = options(&run);
    opts.accel.add(EffectKind::ScaleNonlinearity);
    let fit = calibrate(&run.series, &run.truth, &opts).unwrap();
    assert_eq!(
        fit.recordings[0].segmentation.count(SegmentKind::Static),
        12,
        "{:#?}",
        fit.recordings[0].segmentation
    );
    assert_eq!(
        fit.recordings[0].segmentation.count(SegmentKind::Plateau),
        0
    );
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
    // Without plateaus the gyro gains are left out, and the bias is still fitted.
    assert!(
        fit.notes.iter().any(|n| matches!(
            n,
            imu_analysis::note::Note::GainsNeedPlateaus { effects } if !effects.is_empty()
        )),
        "{:?}",
        fit.notes
    );
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
    for (seg, t) in fit.recordings[0]
        .segmentation
        .segments
        .iter()
        .zip(&fit.recordings[0].segment_truth)
    {
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
        fit.recordings[0].segmentation.count(SegmentKind::Static),
        8,
        "{:#?}",
        fit.recordings[0].segmentation
    );
    let z = z_scores(&fit.gyro, &run.truth_model.gyro, Triad::Gyro);
    report("gyro", &z);
    assert_eq!(z.len(), 12, "{:?}", fit.gyro.warnings);
    for (n, f, t, z) in &z {
        assert!(z.abs() < 3.0, "{n}: fit {f:e} truth {t:e} ({z:.2} SE)");
    }
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
    // Each held parameter is a typed warning naming a g-sensitivity parameter, by its id.
    let held: Vec<&str> = fit
        .gyro
        .warnings
        .iter()
        .filter_map(|w| match &w.kind {
            imu_analysis::calibrate::FitWarningKind::NotFitted(u) => Some(u.name.as_str()),
            _ => None,
        })
        .collect();
    assert_eq!(held.len(), 9, "{:?}", fit.gyro.warnings);
    for name in held {
        let p = fit.gyro.parameters.iter().find(|p| p.name == name).unwrap();
        assert_eq!(p.id.effect, EffectKind::GSensitivity, "{name}");
        assert_eq!(p.std_error, None, "{name}");
    }
    let e = calibrate(&run.series, &run.truth, &CalibrateOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("still positions"), "{e}");
}

#[test]
fn rate_table_recovers_gyro_scale_misalignment_and_g_sensitivity() {
    let run = record(RATE_TABLE, 2);
    let mut opts = options(&run);
    opts.gyro.add(EffectKind::GSensitivity);
    let fit = calibrate(&run.series, &run.truth, &opts).unwrap();
    // The streamed truth file gives the same segment means as the truth in memory.
    let streamed = Reference::TruthFile(run.truth_path.clone())
        .segment_truth(&run.series, &fit.recordings[0].segmentation.segments)
        .unwrap();
    assert_eq!(streamed, fit.recordings[0].segment_truth);
    // 6 still positions plus the 0 deg/s dwell that ends each axis's steps; 4 plateaus per axis.
    assert_eq!(
        fit.recordings[0].segmentation.count(SegmentKind::Plateau),
        12,
        "{:#?}",
        fit.recordings[0].segmentation
    );
    assert_eq!(fit.recordings[0].segmentation.count(SegmentKind::Static), 9);
    let z = z_scores(&fit.gyro, &run.truth_model.gyro, Triad::Gyro);
    report("gyro", &z);
    assert_eq!(z.len(), 21, "{:?}", fit.gyro.warnings);
    for (n, f, t, z) in &z {
        assert!(z.abs() < 3.0, "{n}: fit {f:e} truth {t:e} ({z:.2} SE)");
    }
    // Scale and misalignment are determined to a small fraction of their size.
    // (0.014 deg/s at 1 rad/s; a sixth of the smallest hidden scale error.)
    for (name, se) in fit.gyro.names.iter().zip(&fit.gyro.std_errors) {
        if name.starts_with("scale") {
            assert!(se.unwrap() < 2.5e-4, "{name}: {se:?}");
        }
    }
}

/// One calibration procedure of the coverage test: what is recorded, what is fitted and which
/// triad's parameters are scored against the truth.
struct Procedure {
    name: &'static str,
    scenario: &'static str,
    /// Effects added to the default model (bias, scale, misalignment) of the scored triad.
    extra: EffectKind,
    scored: Triad,
    /// Added to the coverage seeds, so the procedures draw independent noise.
    seed_offset: u64,
    /// Parameters every fit must have free (`None`: the 18 of the model less the unobservable
    /// cubic nonlinearity terms).
    n_free: Option<usize>,
}

const PROCEDURES: [Procedure; 3] = [
    Procedure {
        name: "index-table accel",
        scenario: INDEX_TABLE,
        extra: EffectKind::ScaleNonlinearity,
        scored: Triad::Accel,
        seed_offset: 1000,
        n_free: None,
    },
    Procedure {
        name: "earth-rate gyro",
        scenario: EARTH_RATE,
        extra: EffectKind::GSensitivity,
        scored: Triad::Gyro,
        seed_offset: 2000,
        n_free: Some(12),
    },
    Procedure {
        name: "rate-table gyro",
        scenario: RATE_TABLE,
        extra: EffectKind::GSensitivity,
        scored: Triad::Gyro,
        seed_offset: 3000,
        n_free: Some(21),
    },
];

/// Seeds of the coverage test (fixed, so the test is reproducible).
const COVERAGE_SEEDS: std::ops::RangeInclusive<u64> = 1..=20;

/// Fits one procedure for one seed; the scored triad's `(parameter, z)` pairs.
fn procedure_z(p: &Procedure, seed: u64) -> Vec<(String, f64)> {
    let run = record_seed(p.scenario, seed);
    let mut opts = options(&run);
    match p.scored {
        Triad::Accel => opts.accel.add(p.extra),
        _ => opts.gyro.add(p.extra),
    }
    let fit = calibrate(&run.series, &run.truth, &opts)
        .unwrap_or_else(|e| panic!("{} seed {seed}: {e}", p.name));
    let (f, truth) = match p.scored {
        Triad::Accel => (&fit.accel, &run.truth_model.accel),
        _ => (&fit.gyro, &run.truth_model.gyro),
    };
    // Only the cubic nonlinearity may be unobservable (60-degree steps make x^3 ~ x).
    for u in &f.unobservable {
        assert!(u.name.contains("cubic"), "{} seed {seed}: {u:?}", p.name);
    }
    let want = p.n_free.unwrap_or(18 - f.unobservable.len());
    assert_eq!(
        f.free.len(),
        want,
        "{} seed {seed}: {:?}",
        p.name,
        f.warnings
    );
    z_scores(f, truth, p.scored)
        .into_iter()
        .map(|(n, _, _, z)| (n, z))
        .collect()
}

/// Issue 4 item 7: honest uncertainties. Every procedure is recorded and fitted for 20 seeds (its
/// own 20, so the procedures draw independent noise) and each fitted parameter's error is
/// expressed in its own standard error (z). With honest standard errors z is close to a unit
/// normal: 95.4 % of |z| below 2, 0.27 % above 3.
///
/// Why not "every parameter within 3 SE in every seed": this test scores about 1000 parameters
/// (20 seeds x (16..17 accel + 12 + 21 gyro)); with exact standard errors about 2.7 of them lie
/// beyond 3 SE and the chance that none does is 0.9973^1000 = 7 %. So the strict per-seed check
/// is made for fixed seeds in the procedure tests above (index table seed 11, Earth rate seed 5,
/// rate table seed 2), and here the count beyond 3 SE is bounded by 1 % of the parameters
/// (exceeded with probability below 0.1 % for a unit normal) and nothing may lie beyond 5 SE.
/// The share within 2 SE must lie in 90-99 % overall, which fails both for standard errors too
/// small by a quarter (share 87 %) and for ones padded by half (share 99.7 %).
#[test]
fn standard_errors_are_honest_over_20_seeds() {
    // One thread per procedure (the seeds of one procedure run in order).
    let per_procedure: Vec<Vec<(u64, String, f64)>> = std::thread::scope(|scope| {
        let handles: Vec<_> = PROCEDURES
            .iter()
            .map(|p| {
                scope.spawn(move || {
                    COVERAGE_SEEDS
                        .map(|s| s + p.seed_offset)
                        .flat_map(|seed| {
                            procedure_z(p, seed)
                                .into_iter()
                                .map(move |(name, z)| (seed, name, z))
                        })
                        .collect()
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    let mut all: Vec<f64> = Vec::new();
    let mut beyond_3: Vec<String> = Vec::new();
    for (p, results) in PROCEDURES.iter().zip(per_procedure) {
        let mut zs: Vec<f64> = Vec::new();
        for (seed, name, z) in results {
            if z.abs() >= 3.0 {
                beyond_3.push(format!("{} seed {seed}: {name} z {z:.2}", p.name));
            }
            zs.push(z);
        }
        let within_2 = zs.iter().filter(|z| z.abs() < 2.0).count() as f64 / zs.len() as f64;
        let rms = (zs.iter().map(|z| z * z).sum::<f64>() / zs.len() as f64).sqrt();
        eprintln!(
            "{}: {} parameters, {:.1} % within 2 SE, RMS z {rms:.2}",
            p.name,
            zs.len(),
            100.0 * within_2
        );
        all.extend(zs);
    }
    let n = all.len() as f64;
    let within_2 = all.iter().filter(|z| z.abs() < 2.0).count() as f64 / n;
    let rms = (all.iter().map(|z| z * z).sum::<f64>() / n).sqrt();
    let max = all.iter().fold(0.0f64, |m, z| m.max(z.abs()));
    eprintln!(
        "all: {} parameters, {:.1} % within 2 SE, RMS z {rms:.2}, max |z| {max:.2}, {} beyond 3 SE",
        all.len(),
        100.0 * within_2,
        beyond_3.len()
    );
    for b in &beyond_3 {
        eprintln!("  beyond 3 SE: {b}");
    }
    assert!(all.len() >= 900, "{} parameters", all.len());
    assert!((0.90..=0.99).contains(&within_2), "{within_2}");
    assert!(beyond_3.len() as f64 <= 0.01 * n, "{beyond_3:#?}");
    assert!(max < 5.0, "max |z| {max}");
}
