//! Truth tests of the reference-free multi-pose calibration: a simulated hand-held session (36
//! random still poses, moves about random axes) recorded through the daemon's offline pipeline
//! and calibrated WITHOUT a reference; the fitted parameters must lie within 3 of their own
//! standard errors of the hidden truth model (expressed in the body frame the procedure's gauge
//! defines), and the accelerometer must come out about as precise as from an index table with
//! a truth reference.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use imu_analysis::ImuSeries;
use imu_analysis::calibrate::reference_free::{
    ReferenceFreeOptions, TriadFit, calibrate_reference_free, in_accel_frame,
};
use imu_analysis::calibrate::{CalibrateOptions, bias_drift_from_noise, calibrate};
use imu_analysis::input::{Source, read_mcap};
use imu_analysis::reference::Reference;
use imu_model::{Calibration, EffectKind, TriadModel};
use imu_rec::truth::read_truth;

/// A hand-held session: 36 random still poses of 22 s, 2 s moves about random axes.
const MULTI_POSE: &str = r#"
name = "multi-pose-test"
rate-hz = 100.0
latitude-deg = 40.0

[[segment]]
kind = "static"
duration-s = 22.0

[[segment]]
kind = "random-poses"
count = 35
dwell-s = 22.0
move-s = 2.0
"#;

/// Too few poses: 5.
const FIVE_POSES: &str = r#"
name = "five-poses"
rate-hz = 100.0

[[segment]]
kind = "static"
duration-s = 10.0

[[segment]]
kind = "random-poses"
count = 4
dwell-s = 10.0
move-s = 2.0
"#;

fn repo_path(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
}

fn model_path() -> PathBuf {
    repo_path("config/models/example-3dm-gx1.toml")
}

/// A recording read back from the log, its truth file, and the hidden truth model.
struct Run {
    series: ImuSeries,
    truth: Reference,
    truth_model: Calibration,
}

fn record(scenario_text: &str, seed: u64) -> Run {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("scenario.toml");
    std::fs::write(&scenario, scenario_text).unwrap();
    let session =
        imud::offline::record_session(dir.path(), "t", &scenario, Some(&model_path()), seed, None)
            .unwrap();
    Run {
        series: read_mcap(&session.recording, Source::Raw, None).unwrap(),
        truth: Reference::Truth(read_truth(&session.truth).unwrap()),
        truth_model: Calibration::load(&model_path()).unwrap(),
    }
}

/// The multi-pose session, recorded once for all tests of this file.
fn multi_pose() -> &'static Run {
    static RUN: OnceLock<Run> = OnceLock::new();
    RUN.get_or_init(|| record(MULTI_POSE, 21))
}

/// The accel model of both procedures: the paper's bias, scale and misalignment plus the
/// quadratic nonlinearity the truth hides (left out, x^2 averages into the bias).
fn accel_model() -> TriadModel {
    let mut m = TriadModel::default();
    for k in [
        EffectKind::Bias,
        EffectKind::Scale,
        EffectKind::Misalignment,
        EffectKind::ScaleNonlinearity,
    ] {
        m.add(k);
    }
    m
}

/// Reference-free options; with `drift`, the bias wander over the recording from the truth's
/// noise terms (what a noise characterisation would give) widens the bias standard errors.
fn options(run: &Run, drift: bool) -> ReferenceFreeOptions {
    let duration_s = run.series.t_s.last().unwrap() - run.series.t_s[0];
    let wander = |n: &Option<imu_model::NoiseModel>| {
        n.as_ref()
            .filter(|_| drift)
            .map(|n| bias_drift_from_noise(n, duration_s))
    };
    ReferenceFreeOptions {
        accel: accel_model(),
        latitude_deg: Some(40.0),
        // The simulator's gravity (standard), not the latitude's normal gravity.
        gravity_m_s2: Some(imu_model::units::STANDARD_GRAVITY_M_S2),
        accel_bias_drift_m_s2: wander(&run.truth_model.accel.noise),
        gyro_bias_drift_rad_s: wander(&run.truth_model.gyro.noise),
        ..ReferenceFreeOptions::default()
    }
}

/// (name, fitted, truth, error in standard errors) for every fitted parameter.
fn z_scores(fit: &TriadFit, truth: &TriadModel) -> Vec<(String, f64, f64, f64)> {
    let names = truth.param_names(fit.triad);
    let values = truth.params();
    fit.free
        .iter()
        .map(|&i| {
            let t = names
                .iter()
                .position(|n| *n == fit.names[i])
                .map_or(0.0, |k| values[k]);
            let se = fit.std_errors[i].unwrap();
            (
                fit.names[i].clone(),
                fit.params[i],
                t,
                (fit.params[i] - t) / se,
            )
        })
        .collect()
}

/// Cubic nonlinearity terms: absent from the truth and held at 0 (see
/// `reference_free_is_about_as_precise_as_an_index_table` for what fitting them costs).
fn cubic() -> Vec<String> {
    ["x", "y", "z"]
        .iter()
        .map(|a| format!("accel.scale-nonlinearity.cubic.{a}"))
        .collect()
}

fn report(z: &[(String, f64, f64, f64)], label: &str) {
    for (n, f, t, z) in z {
        eprintln!("{label} {n:<34} fit {f:>12.4e} truth {t:>12.4e} z {z:>6.2}");
    }
}

#[test]
fn reference_free_recovers_the_truth_within_its_standard_errors() {
    let run = multi_pose();
    let opts = ReferenceFreeOptions {
        hold: cubic(),
        ..options(run, true)
    };
    let fit = calibrate_reference_free(&run.series, &opts).unwrap();
    eprintln!("notes: {:#?}", fit.notes);
    assert_eq!(fit.poses.len(), 36, "{:#?}", fit.segmentation.segments);
    assert_eq!(fit.moves.len(), 35);
    assert!(fit.accel.warnings.is_empty(), "{:?}", fit.accel.warnings);
    assert!(fit.gyro.warnings.is_empty(), "{:?}", fit.gyro.warnings);
    // Moves of random poses turn by up to 180 degrees about random axes.
    assert!(
        fit.moves.iter().any(|m| m.angle_rad > 2.0),
        "{:?}",
        fit.moves
    );

    // The truth in the body frame the accelerometer defines (the gauge).
    let truth = in_accel_frame(&run.truth_model);
    let za = z_scores(&fit.accel, &truth.accel);
    let zg = z_scores(&fit.gyro, &truth.gyro);
    report(&za, "accel");
    report(&zg, "gyro");
    // Bias, scale, lower-triangle misalignment and quadratic nonlinearity of the accel; bias,
    // scale and all six misalignments of the gyro.
    assert_eq!(za.len(), 3 + 3 + 3 + 3);
    assert_eq!(zg.len(), 3 + 3 + 6);
    for (n, f, t, z) in za.iter().chain(&zg) {
        assert!(z.abs() < 3.0, "{n}: fit {f:e} truth {t:e} ({z:.2} SE)");
    }
    // The gyro gains are determined, not merely consistent: well below their own size.
    for (n, f, t, _) in &zg {
        if n.starts_with("scale") {
            let se = fit.gyro.std_errors[fit.gyro.names.iter().position(|x| x == n).unwrap()];
            assert!(
                se.unwrap() < 0.5 * t.abs(),
                "{n}: {f:e} vs {t:e} +/- {se:?}"
            );
        }
    }

    // Over more sessions the errors in SE look like a unit normal (the gyro bias excepted: it
    // carries Earth's unknown horizontal rate as a deliberate upper bound).
    let gains = |z: &[(String, f64, f64, f64)]| -> Vec<f64> {
        z.iter()
            .filter(|r| !r.0.starts_with("bias"))
            .map(|r| r.3)
            .collect()
    };
    let mut all: Vec<f64> = za.iter().map(|r| r.3).chain(gains(&zg)).collect();
    for seed in [1, 2, 3] {
        let r = record(MULTI_POSE, seed);
        let f = calibrate_reference_free(&r.series, &opts).unwrap();
        let t = in_accel_frame(&r.truth_model);
        all.extend(z_scores(&f.accel, &t.accel).iter().map(|r| r.3));
        all.extend(gains(&z_scores(&f.gyro, &t.gyro)));
    }
    let rms = (all.iter().map(|z| z * z).sum::<f64>() / all.len() as f64).sqrt();
    let beyond = all.iter().filter(|z| z.abs() > 3.0).count();
    eprintln!("{} z-scores: RMS {rms:.2}, {beyond} beyond 3", all.len());
    assert!((0.6..1.5).contains(&rms), "RMS z {rms}");
    assert!(beyond as f64 <= 0.03 * all.len() as f64, "{all:?}");
    assert!(all.iter().all(|z| z.abs() < 4.5), "{all:?}");

    // The calibration file loads, says how it was made, and brings every pose's corrected
    // specific force to |g| within the fit's residual.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cal.toml");
    fit.calibration.save(&path).unwrap();
    let cal = Calibration::load(&path).unwrap();
    assert!(
        cal.provenance
            .procedure
            .as_deref()
            .unwrap()
            .contains("reference-free multi-pose")
    );
    assert_eq!(cal.accel.params(), fit.accel.params);
    let g = imu_model::units::STANDARD_GRAVITY_M_S2;
    let (mut raw, mut cor) = (0.0, 0.0);
    for pose in &fit.poses {
        let s = &fit.segmentation.segments[pose.segment];
        let c = imu_model::Conditions::default();
        raw += (s.mean_accel().norm() - g).powi(2);
        cor += (cal.accel.inverse(s.mean_accel(), &c).norm() - g).powi(2);
    }
    let n = fit.poses.len() as f64;
    let (raw, cor) = ((raw / n).sqrt(), (cor / n).sqrt());
    eprintln!("| |f| - g | RMS over the poses: raw {raw:.3e}, calibrated {cor:.3e} m/s^2");
    assert!(raw > 0.1, "{raw}");
    assert!(
        cor < 1.01 * fit.accel.residual_rms + 1e-9,
        "{cor} vs {}",
        fit.accel.residual_rms
    );
}

/// The issue's criterion: with 30+ poses the reference-free procedure determines the
/// accelerometer's bias and scale about as precisely as the truth-referenced index table
/// (config/scenarios/index-table-12pos.toml, 2 x 12 positions of 60 s), within a factor of 2
/// in standard error, for the paper's model (bias, scale, misalignment), and for the scale
/// also with the quadratic nonlinearity the truth hides. A magnitude constraint turns an
/// axis's even x^2 term into an odd u^3 term along gravity, 0.92-correlated with the bias's u
/// over random poses: with that term fitted the bias costs more (measured: ~2.6-4.5 x).
#[test]
fn reference_free_is_about_as_precise_as_an_index_table() {
    use imu_analysis::calibrate::{FitOptions, FitPoint, fit_triad};
    use imu_analysis::segment::{SegmentKind, detect};
    use imu_model::{Conditions, Triad, Vec3};

    let run = multi_pose();
    let table = record(
        &std::fs::read_to_string(repo_path("config/scenarios/index-table-12pos.toml")).unwrap(),
        22,
    );
    let paper = { TriadModel::with_effects(&TriadModel::PAPER_BASE) };
    let se_of = |names: &[String], se: &[Option<f64>], name: &str| {
        se[names.iter().position(|n| n == name).unwrap()].unwrap()
    };
    let ratios = |label: &str, rf: &TriadFit, names: &[String], se: &[Option<f64>]| {
        [
            "bias.x", "bias.y", "bias.z", "scale.x", "scale.y", "scale.z",
        ]
        .map(|name| {
            let a = se_of(&rf.names, &rf.std_errors, name);
            let b = se_of(names, se, name);
            eprintln!(
                "{label} {name}: reference-free {a:.3e}, index table {b:.3e}, ratio {:.2}",
                a / b
            );
            a / b
        })
    };

    // The paper's model: fit::calibrate against the truth vs reference-free.
    let it = calibrate(
        &table.series,
        &table.truth,
        &CalibrateOptions {
            accel: paper.clone(),
            ..CalibrateOptions::default()
        },
    )
    .unwrap();
    assert_eq!(it.count(SegmentKind::Static), 24);
    let rf = calibrate_reference_free(
        &run.series,
        &ReferenceFreeOptions {
            accel: paper,
            ..options(run, false)
        },
    )
    .unwrap();
    for r in ratios(
        "paper model",
        &rf.accel,
        &it.accel.names,
        &it.accel.std_errors,
    ) {
        assert!(r < 2.0, "{r}");
    }

    // With the quadratic nonlinearity (cubic held at 0 in both: the same model). fit::calibrate
    // cannot hold a parameter, so the index table's segment fit is called as calibrate calls it.
    let seg = detect(&table.series, &Default::default()).unwrap();
    let truth = table
        .truth
        .segment_truth(&table.series, &seg.segments)
        .unwrap();
    let points: Vec<FitPoint> = seg
        .segments
        .iter()
        .zip(&truth)
        .filter(|(s, _)| s.kind == SegmentKind::Static)
        .map(|(s, t)| FitPoint {
            true_input: Vec3::from(t.specific_force_m_s2),
            measured: s.mean_accel(),
            std_error: Vec3::from(s.std_accel_m_s2.map(|x| x / (s.n as f64).sqrt())),
            conditions: Conditions::default(),
            t_s: 0.5 * (s.start_s + s.end_s),
            duration_s: s.end_s - s.start_s,
        })
        .collect();
    let model = accel_model();
    let names = model.param_names(Triad::Accel);
    let fixed: Vec<bool> = names
        .iter()
        .map(|n| cubic().contains(&format!("accel.{n}")))
        .collect();
    let it = fit_triad(
        &model,
        Triad::Accel,
        &points,
        &FitOptions {
            fixed,
            ..FitOptions::default()
        },
    )
    .unwrap();
    let rf = calibrate_reference_free(
        &run.series,
        &ReferenceFreeOptions {
            hold: cubic(),
            ..options(run, false)
        },
    )
    .unwrap();
    let r = ratios("with quadratic", &rf.accel, &it.names, &it.std_errors);
    for s in &r[3..] {
        assert!(*s < 2.0, "scale: {r:?}");
    }
    for b in &r[..3] {
        assert!(*b < 5.0, "bias: {r:?}");
    }
}

#[test]
fn too_few_poses_say_what_to_record() {
    let run = record(FIVE_POSES, 3);
    let e = calibrate_reference_free(&run.series, &ReferenceFreeOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("5 still pose(s) found"), "{e}");
    assert!(e.contains("needs at least 10"), "{e}");
    assert!(
        e.contains("each axis up and down, and at 45 degrees in between"),
        "{e}"
    );
}
