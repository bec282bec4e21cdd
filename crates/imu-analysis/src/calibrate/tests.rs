//! Tests of the calibration fits on synthetic segment means with known parameters.

use super::*;

fn model(kinds: &[EffectKind]) -> TriadModel {
    let mut m = TriadModel::default();
    for k in kinds {
        m.add(*k);
    }
    m
}

#[test]
fn a_cubic_that_would_make_the_model_non_invertible_is_held() {
    use EffectKind::*;
    // Measurements with a strong cubic term (x - 1e-5 x^3): fitted as it is, the curve
    // would fold over well inside +/-20 g.
    let g = 9.8;
    let points: Vec<FitPoint> = [-1.0, -0.7, -0.35, 0.0, 0.35, 0.7, 1.0]
        .iter()
        .enumerate()
        .map(|(k, &c)| {
            let x = Vec3::new(c * g, 0.5 * c * g, -0.8 * c * g);
            FitPoint {
                true_input: x,
                measured: x.map(|v| v - 1e-5 * v * v * v),
                std_error: Vec3::repeat(1e-3),
                conditions: Conditions::default(),
                t_s: k as f64,
                duration_s: 0.0,
            }
        })
        .collect();
    let m = model(&[Bias, Scale, ScaleNonlinearity]);
    let r = fit_loadable(
        &m,
        Triad::Accel,
        &points,
        &Sessions::default(),
        &FitOptions::default(),
    )
    .unwrap();
    assert!(!r.unobservable.is_empty(), "{:?}", r.warnings);
    for u in &r.unobservable {
        assert!(u.name.starts_with("scale-nonlinearity.cubic"), "{u:?}");
    }
    assert!(r.model.validate(Triad::Accel).is_ok());
    assert!(
        matches!(r.unobservable[0].reason, NotFitted::InvalidModel { .. }),
        "{:?}",
        r.unobservable
    );
    // The JSON: the held parameter's code beside its sentence, one entry per parameter (the
    // same as the parallel columns) with its typed id, and a code beside each warning.
    let json = serde_json::to_value(&r).unwrap();
    assert_eq!(json["unobservable"][0]["code"], "invalid_model");
    assert_eq!(
        json["unobservable"][0]["reason"],
        r.unobservable[0].reason.to_string()
    );
    let params = json["parameters"].as_array().unwrap();
    assert_eq!(params.len(), r.names.len());
    for (i, p) in params.iter().enumerate() {
        assert_eq!(p["name"], r.names[i].as_str());
        assert_eq!(p["value"], r.params[i]);
        assert_eq!(p["unit"], r.units[i].as_str());
        assert_eq!(p["id"]["effect"], r.parameters[i].id.effect.id());
    }
    let held = r
        .parameters
        .iter()
        .find(|p| p.name == r.unobservable[0].name)
        .unwrap();
    assert_eq!(held.id.effect, EffectKind::ScaleNonlinearity);
    assert_eq!(held.std_error, None);
    let codes = json["warning_codes"].as_array().unwrap();
    assert_eq!(codes.len(), json["warnings"].as_array().unwrap().len());
    assert!(codes.iter().any(|c| c == "not_fitted"), "{json}");
}

/// Points `k` seconds apart, 20 s long, with distinct white errors.
fn timed_points(times_s: &[f64]) -> Vec<FitPoint> {
    times_s
        .iter()
        .enumerate()
        .map(|(k, &t)| FitPoint {
            true_input: Vec3::zeros(),
            measured: Vec3::zeros(),
            std_error: Vec3::repeat(1e-3 * (1.0 + k as f64)),
            conditions: Conditions::default(),
            t_s: t,
            duration_s: 20.0,
        })
        .collect()
}

#[test]
fn sessions_share_no_noise_and_each_starts_its_own_random_walk() {
    // Session 0 at 10, 50, 90 s; session 1 (its own clock) at 15, 70 s.
    let times = [10.0, 50.0, 90.0, 15.0, 70.0];
    let points = timed_points(&times);
    let sessions = Sessions {
        of_point: vec![0, 0, 0, 1, 1],
        turn_on_bias: None,
    };
    for shared in [
        SharedNoise {
            random_walk_q: 1e-8,
            random_walk_origin_s: Some(0.0),
            flicker_var: 4e-8,
            flicker_tau_s: 1.0,
            flicker_tau_max_s: Some(1000.0),
        },
        SharedNoise {
            random_walk_q: 1e-8,
            random_walk_origin_s: None,
            flicker_var: 4e-8,
            flicker_tau_s: 1.0,
            flicker_tau_max_s: None,
        },
    ] {
        let c = session_covariance(&points, &sessions, 0, &shared, 1.0);
        // Nothing shared across sessions.
        for k in 0..3 {
            for l in 3..5 {
                assert_eq!(c[(k, l)], 0.0);
                assert_eq!(c[(l, k)], 0.0);
            }
        }
        // Within each session, exactly the one-recording covariance of its points alone.
        for range in [0..3, 3..5] {
            let alone = segment_covariance(&points[range.clone()], 0, &shared, 1.0);
            let block = c.view((range.start, range.start), (range.len(), range.len()));
            assert!((block - &alone).abs().max() <= 1e-18, "{c}\n{alone}");
        }
    }
    // With the random walk from t = 0 on each session's clock, session 1's first segment
    // (15 s) carries 15 q, not the 5 s since session 0's first one.
    let rw = SharedNoise {
        random_walk_q: 1e-8,
        random_walk_origin_s: Some(0.0),
        ..SharedNoise::default()
    };
    let c = session_covariance(&points, &sessions, 0, &rw, 0.0);
    assert!((c[(3, 3)] - 15.0 * 1e-8).abs() < 1e-20);
    assert!((c[(3, 4)] - 15.0 * 1e-8).abs() < 1e-20);
    // A turn-on bias spread is shared within a session only.
    let spread = Sessions {
        turn_on_bias: Some([2e-3, 0.0, 0.0]),
        ..sessions.clone()
    };
    let c = session_covariance(&points, &spread, 0, &SharedNoise::default(), 1.0);
    assert!((c[(0, 2)] - 4e-6).abs() < 1e-18 && (c[(3, 4)] - 4e-6).abs() < 1e-18);
    assert_eq!(c[(0, 3)], 0.0);
    assert!((c[(1, 1)] - (4e-6 + 4e-6)).abs() < 1e-18);
}

#[test]
fn a_turn_on_spread_widens_only_the_bias_of_a_joint_fit() {
    use EffectKind::*;
    // Two sessions see the same scale error but biases 1e-3 apart (turn-on to turn-on).
    let scale = 2e-3;
    let mut points = Vec::new();
    let mut of_point = Vec::new();
    for (session, bias) in [(0usize, 0.010), (1, 0.011)] {
        for (k, u) in [-1.0, -0.5, 0.5, 1.0].iter().enumerate() {
            let x = Vec3::new(u * 9.8, -u * 4.0, u * 6.0);
            points.push(FitPoint {
                true_input: x,
                measured: x * (1.0 + scale) + Vec3::repeat(bias),
                std_error: Vec3::repeat(1e-4),
                conditions: Conditions::default(),
                t_s: 30.0 * k as f64,
                duration_s: 20.0,
            });
            of_point.push(session);
        }
    }
    let m = model(&[Bias, Scale]);
    let common = Sessions {
        of_point: of_point.clone(),
        turn_on_bias: None,
    };
    let spread = Sessions {
        of_point,
        turn_on_bias: Some([1e-3; 3]),
    };
    let opts = FitOptions::default();
    let a = fit_triad_sessions(&m, Triad::Accel, &points, &common, &opts).unwrap();
    let b = fit_triad_sessions(&m, Triad::Accel, &points, &spread, &opts).unwrap();
    // Common bias: the 1e-3 difference is excess scatter (reduced chi-square >> 1).
    assert!(a.reduced_chi2 > 10.0, "{}", a.reduced_chi2);
    // With the spread: the offsets (0.5 sigma each) are expected, the bias is their mean
    // with a standard error of about 1e-3 / sqrt(2), the scale exact and its error from
    // the white errors alone.
    assert!(b.reduced_chi2 < 0.2, "{}", b.reduced_chi2);
    // (Canonical order: scale.x..z, then bias.x..z.)
    for axis in 0..3 {
        assert!((b.params[axis] - scale).abs() < 1e-9, "{:?}", b.params);
        // The inputs are symmetric about 0 in each session: the white-error value.
        let sxx: f64 = points.iter().map(|p| p.true_input[axis].powi(2)).sum();
        let se_s = b.std_errors[axis].unwrap();
        assert!((se_s / (1e-4 / sxx.sqrt()) - 1.0).abs() < 0.01, "{se_s}");
        assert!((b.params[3 + axis] - 0.0105).abs() < 1e-9, "{:?}", b.params);
        let se_b = b.std_errors[3 + axis].unwrap();
        assert!((se_b - 1e-3 / 2f64.sqrt()).abs() < 0.02e-3, "{se_b}");
    }
}

/// The reference's unknown input (Earth's rate without a heading) widens the bias standard
/// error with a noise model as well as without: a noise model replaces only the drift.
#[test]
fn the_unknown_input_widens_the_bias_with_or_without_a_noise_model() {
    let points = timed_points(&[0.0, 40.0, 80.0, 120.0]);
    let m = model(&[EffectKind::Bias]);
    let noise = imu_model::NoiseModel {
        white_density: [1e-3; 3],
        ..Default::default()
    };
    let input = 7.3e-5;
    for with_noise in [false, true] {
        let base = FitOptions {
            mean_noise: if with_noise {
                MeanNoise::Characterised(noise.clone())
            } else {
                MeanNoise::White { bias_drift: None }
            },
            ..FitOptions::default()
        };
        let widened = FitOptions {
            bias_input_uncertainty: Some([input; 3]),
            ..base.clone()
        };
        let a = fit_triad(&m, Triad::Gyro, &points, &base).unwrap();
        let b = fit_triad(&m, Triad::Gyro, &points, &widened).unwrap();
        for axis in 0..3 {
            let (sa, sb) = (a.std_errors[axis].unwrap(), b.std_errors[axis].unwrap());
            assert!(
                (sb * sb - sa * sa - input * input).abs() < 1e-6 * input * input,
                "noise model {with_noise}: {sa:e} -> {sb:e}"
            );
        }
    }
}

/// Noise-free points of `truth` at the static inputs `dirs`, each with a 1e-3 standard error.
fn exact_points(truth: &TriadModel, dirs: &[[f64; 3]]) -> Vec<FitPoint> {
    dirs.iter()
        .map(|d| {
            let x = Vec3::from(*d);
            FitPoint {
                true_input: x,
                measured: truth.forward(x, &Conditions::default()),
                std_error: Vec3::repeat(1e-3),
                conditions: Conditions::default(),
                t_s: 0.0,
                duration_s: 0.0,
            }
        })
        .collect()
}

#[test]
fn recovers_exact_parameters_and_flags_unobservable_g_sensitivity() {
    use EffectKind::*;
    let mut truth = model(&[Bias, Scale, Misalignment]);
    let tp: Vec<f64> = (0..truth.n_params())
        .map(|i| 1e-3 * (i as f64 - 4.0))
        .collect();
    truth.set_params(&tp);
    let g = 9.8;
    let dirs = [
        [g, 0.0, 0.0],
        [-g, 0.0, 0.0],
        [0.0, g, 0.0],
        [0.0, -g, 0.0],
        [0.0, 0.0, g],
        [0.0, 0.0, -g],
        [g / 2f64.sqrt(), g / 2f64.sqrt(), 0.0],
        [0.0, g / 2f64.sqrt(), -g / 2f64.sqrt()],
    ];
    let points = exact_points(&truth, &dirs);
    let r = fit_triad(
        &model(&[Bias, Scale, Misalignment]),
        Triad::Accel,
        &points,
        &FitOptions::default(),
    )
    .unwrap();
    for (f, t) in r.params.iter().zip(&tp) {
        assert!((f - t).abs() < 1e-9, "{f} vs {t}");
    }
    assert!(r.unobservable.is_empty());

    // Gyro at rest in one orientation: g-sensitivity columns for x/y are zero, the z column
    // is collinear with the bias.
    let gyro = model(&[Bias, GSensitivity]);
    let pts: Vec<FitPoint> = (0..4)
        .map(|k| FitPoint {
            true_input: Vec3::new(1e-5 * k as f64, 0.0, 5e-5),
            measured: Vec3::new(0.01, -0.02, 0.003),
            std_error: Vec3::repeat(1e-4),
            conditions: Conditions {
                specific_force_m_s2: Vec3::new(0.0, 0.0, g),
                ..Conditions::default()
            },
            t_s: k as f64,
            duration_s: 0.0,
        })
        .collect();
    let r = fit_triad(&gyro, Triad::Gyro, &pts, &FitOptions::default()).unwrap();
    assert_eq!(r.free.len(), 3, "{:?}", r.unobservable);
    assert_eq!(r.unobservable.len(), 9);
    assert!(r.free.iter().all(|&i| r.names[i].starts_with("bias")));
    assert!(
        (r.params[0] - (0.01 - 1.5e-5)).abs() < 1e-9,
        "{}",
        r.params[0]
    );
}

#[test]
fn raw_offsets_and_percent_scales_converge_from_a_neutral_start() {
    // Raw data as an uncompensated sensor gives it: a 1 g accel offset, 5 % scale errors,
    // percent-level misalignment; the fit starts from the neutral model.
    use EffectKind::*;
    let mut truth = model(&[Bias, Scale, Misalignment]);
    let names = truth.param_names(Triad::Accel);
    let tp: Vec<f64> = names
        .iter()
        .enumerate()
        .map(|(i, n)| match n.split('.').next() {
            Some("bias") => [9.5, -6.2, 3.9][i % 3],
            Some("scale") => [0.048, -0.035, 0.021][i % 3],
            _ => 0.01 * (i as f64 - 7.0),
        })
        .collect();
    truth.set_params(&tp);
    let g = 9.8;
    let s = g / 2f64.sqrt();
    let dirs = [
        [g, 0.0, 0.0],
        [-g, 0.0, 0.0],
        [0.0, g, 0.0],
        [0.0, -g, 0.0],
        [0.0, 0.0, g],
        [0.0, 0.0, -g],
        [s, s, 0.0],
        [0.0, s, -s],
        [-s, 0.0, s],
    ];
    let points = exact_points(&truth, &dirs);
    let r = fit_triad(
        &model(&[Bias, Scale, Misalignment]),
        Triad::Accel,
        &points,
        &FitOptions::default(),
    )
    .unwrap();
    assert!(r.converged);
    for ((f, t), n) in r.params.iter().zip(&tp).zip(&names) {
        assert!((f - t).abs() < 1e-9, "{n}: {f} vs {t}");
    }
}
