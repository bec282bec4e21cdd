//! Effect-level tests: each forward formula against hand-computed values, exact inverses for
//! every subset of effects on every triad, parameter vectors, names, units and neutrality.

mod common;

use common::*;
use imu_model::units::STANDARD_GRAVITY_M_S2 as G;
use imu_model::{
    AsymmetricScale, Bias, Conditions, Effect, EffectKind, GSensitivity, LeverArm, Misalignment,
    Scale, ScaleNonlinearity, TempBias, TempScale, Triad, TriadModel, Vec3, Warmup,
};

fn close(a: Vec3, b: Vec3, rel: f64, abs: f64) -> bool {
    (a - b).norm() <= rel * b.norm() + abs
}

#[test]
fn forward_formulas_match_hand_computation() {
    let c = Conditions {
        temp_c: 35.0,
        time_since_power_on_s: 60.0,
        specific_force_m_s2: Vec3::new(0.0, 0.0, -G),
        angular_rate_rad_s: Vec3::new(0.0, 0.0, 2.0),
        angular_accel_rad_s2: Vec3::new(0.0, 0.0, 3.0),
    };
    let x = Vec3::new(1.0, -2.0, 4.0);

    // Lever arm r = (0.1, 0, 0) spinning about z at 2 rad/s: centripetal -w^2 r = (-0.4, 0, 0);
    // tangential a x r = (0, 0.3, 0).
    let la = LeverArm {
        offset_m: [0.1, 0.0, 0.0],
        std_error: None,
    };
    assert!(close(
        la.forward(x, &c),
        x + Vec3::new(-0.4, 0.3, 0.0),
        1e-15,
        1e-15
    ));

    // Misalignment: y_x = x_x + xy x_y + xz x_z, etc.
    let m = Misalignment {
        xy: 0.01,
        xz: -0.02,
        yx: 0.03,
        yz: 0.0,
        zx: 0.0,
        zy: 0.05,
        std_error: None,
    };
    let want = Vec3::new(1.0 - 0.02 - 0.08, -2.0 + 0.03, 4.0 - 0.1);
    assert!(close(m.forward(x, &c), want, 1e-15, 1e-15));

    let s = Scale {
        value: [0.01, -0.02, 0.5],
        std_error: None,
    };
    assert!(close(
        s.forward(x, &c),
        Vec3::new(1.01, -1.96, 6.0),
        1e-15,
        0.0
    ));

    // Positive input scaled by (1 + a), negative by (1 - a).
    let a = AsymmetricScale {
        value: [0.1, 0.1, -0.1],
        std_error: None,
    };
    assert!(close(
        a.forward(x, &c),
        Vec3::new(1.1, -1.8, 3.6),
        1e-15,
        0.0
    ));

    // dT = 10 K: factor 1 + 1e-3*10 + 1e-5*100 = 1.011 on x.
    let ts = TempScale {
        t0_c: 25.0,
        coefficients: vec![[1e-3, 0.0, 0.0], [1e-5, 0.0, 2e-4]],
        std_error: None,
    };
    assert!(close(
        ts.forward(x, &c),
        Vec3::new(1.011, -2.0, 4.0 * 1.02),
        1e-14,
        0.0
    ));

    let nl = ScaleNonlinearity {
        quadratic: [0.1, 0.0, 0.0],
        cubic: [0.0, 0.01, 0.0],
        std_error: None,
    };
    assert!(close(
        nl.forward(x, &c),
        Vec3::new(1.1, -2.08, 4.0),
        1e-15,
        0.0
    ));

    let b = Bias {
        value: [0.5, 0.25, -1.0],
        std_error: None,
    };
    assert!(close(
        b.forward(x, &c),
        Vec3::new(1.5, -1.75, 3.0),
        1e-15,
        0.0
    ));

    let tb = TempBias {
        t0_c: 30.0,
        coefficients: vec![[0.1, 0.0, -0.2], [0.0, 0.01, 0.0]],
        std_error: None,
    };
    assert!(close(
        tb.forward(x, &c),
        Vec3::new(1.5, -1.75, 3.0),
        1e-15,
        0.0
    ));

    // t = tau: amplitude * e^-1.
    let w = Warmup {
        amplitude: [1.0, 0.0, -2.0],
        tau_s: 60.0,
        std_error: None,
    };
    let e1 = (-1.0f64).exp();
    assert!(close(
        w.forward(x, &c),
        Vec3::new(1.0 + e1, -2.0, 4.0 - 2.0 * e1),
        1e-15,
        0.0
    ));

    // Paper Eq. 3: the z-up gyro at rest reads B_gz * (-g) on each axis from column z.
    let g = GSensitivity {
        matrix: [[0.0, 0.0, 1e-3], [0.0, 0.0, 0.0], [2e-3, 0.0, 0.0]],
        std_error: None,
    };
    assert!(close(
        g.forward(x, &c),
        x + Vec3::new(-1e-3 * G, 0.0, 0.0),
        1e-15,
        0.0
    ));
}

#[test]
fn canonical_order_is_applied_first_to_last() {
    // Scale then bias: y = x (1 + s) + b, not (x + b)(1 + s).
    // Written in reverse on purpose: the struct, not the writing order, fixes the order.
    let m = TriadModel {
        bias: Some(Bias {
            value: [1.0, 0.0, 0.0],
            std_error: None,
        }),
        scale: Some(Scale {
            value: [1.0 / 2.0, 0.0, 0.0],
            std_error: None,
        }),
        misalignment: Some(Misalignment {
            xy: 0.5,
            ..Default::default()
        }),
        ..Default::default()
    };
    let c = Conditions::default();
    // (I + M) then scale then bias: x = (2, 2, 0) -> (3, 2, 0) -> (4.5, 2, 0) -> (5.5, 2, 0).
    let y = m.forward(Vec3::new(2.0, 2.0, 0.0), &c);
    assert_eq!(y, Vec3::new(5.5, 2.0, 0.0));
    assert_eq!(
        m.kinds(),
        vec![
            EffectKind::Misalignment,
            EffectKind::Scale,
            EffectKind::Bias
        ]
    );
}

/// Inverse(forward(x)) == x for every subset of the effects applicable to `triad`.
fn check_all_subsets(triad: Triad, seed: u64) {
    let kinds = applicable(triad);
    let mut rng = rng(seed);
    let cases_per_subset = 8;
    let mut worst_rel = 0.0f64;
    for mask in 0u32..(1 << kinds.len()) {
        let subset: Vec<EffectKind> = kinds
            .iter()
            .enumerate()
            .filter(|(i, _)| mask & (1 << i) != 0)
            .map(|(_, k)| *k)
            .collect();
        let mut changed = false;
        for _ in 0..cases_per_subset {
            let model = random_model(&subset, triad, &mut rng);
            model
                .validate(triad)
                .unwrap_or_else(|e| panic!("{triad} {subset:?}: {e:?}"));
            let c = random_conditions(&mut rng);
            let x = random_input(triad, &mut rng);
            let y = model.forward(x, &c);
            let back = model.inverse(y, &c);
            let err = (back - x).norm();
            assert!(
                err <= 1e-9 * x.norm() + 1e-12,
                "{triad} {subset:?}: x = {x:?}, y = {y:?}, inverse = {back:?}, error {err:e}"
            );
            if x.norm() > 1e-3 * input_range(triad) {
                worst_rel = worst_rel.max(err / x.norm());
            }
            changed |= y != x;
        }
        // Guard against a vacuous pass: a non-empty model must actually alter the signal.
        assert_eq!(
            changed,
            !subset.is_empty(),
            "{triad} {subset:?}: forward changed nothing"
        );
    }
    eprintln!(
        "{triad}: 2^{} subsets, worst relative error {worst_rel:e}",
        kinds.len()
    );
}

/// The batch inverse (one misalignment factorisation per batch, as the workbench integrates a
/// move) gives bit-for-bit the values of the per-sample inverse, for every effect of every
/// triad together and for the gain effects alone.
#[test]
fn batch_inverse_is_bit_identical_to_the_per_sample_inverse() {
    let mut rng = rng(4);
    for triad in [Triad::Accel, Triad::Gyro, Triad::Mag] {
        let all = applicable(triad);
        let gains: Vec<EffectKind> = all.iter().copied().filter(|k| k.is_gain()).collect();
        for kinds in [all, gains] {
            let model = random_model(&kinds, triad, &mut rng);
            let c = random_conditions(&mut rng);
            let ys: Vec<Vec3> = (0..64)
                .map(|_| model.forward(random_input(triad, &mut rng), &c))
                .collect();
            let mut batch = ys.clone();
            model.inverse_batch(&mut batch, &c);
            for (y, b) in ys.iter().zip(&batch) {
                let one = model.inverse(*y, &c);
                assert_eq!(
                    one.map(f64::to_bits),
                    b.map(f64::to_bits),
                    "{triad} {kinds:?}: {y:?}"
                );
            }
        }
    }
}

#[test]
fn inverse_undoes_forward_for_every_accel_subset() {
    check_all_subsets(Triad::Accel, 1);
}

#[test]
fn inverse_undoes_forward_for_every_gyro_subset() {
    check_all_subsets(Triad::Gyro, 2);
}

#[test]
fn inverse_undoes_forward_for_every_mag_subset() {
    check_all_subsets(Triad::Mag, 3);
}

#[test]
fn each_effect_inverts_across_the_whole_input_range() {
    // Sweep every axis from -range to +range (accel +/-5 g, gyro +/-5 rad/s, mag +/-0.8 G).
    let mut rng = rng(11);
    for triad in Triad::ALL {
        for kind in applicable(triad) {
            let model = random_model(&[kind], triad, &mut rng);
            let e = model.get(kind).expect("present");
            let c = random_conditions(&mut rng);
            let r = input_range(triad);
            for i in 0..=200 {
                let v = -r + 2.0 * r * f64::from(i) / 200.0;
                let x = Vec3::new(v, -v * 0.7, v * 0.3);
                let back = e.inverse(e.forward(x, &c), &c);
                assert!(
                    close(back, x, 1e-9, 1e-12),
                    "{triad} {kind}: {x:?} -> {back:?}"
                );
            }
        }
    }
}

#[test]
fn nonlinearity_inverse_reaches_machine_precision_and_saturates_past_a_fold() {
    let c = Conditions::default();
    let nl = ScaleNonlinearity {
        quadratic: [1e-3, -2e-3, 0.0],
        cubic: [1e-5, 0.0, -1e-4],
        std_error: None,
    };
    for &v in &[1e-300, 1e-9, 0.3, 7.0, 49.0, 150.0, 1e4, -1e4] {
        let x = Vec3::new(v, v.min(200.0), v.clamp(-50.0, 50.0));
        let y = nl.forward(x, &c);
        let back = nl.inverse(y, &c);
        for i in 0..3 {
            let tol = 4.0 * f64::EPSILON * x[i].abs();
            assert!(
                (back[i] - x[i]).abs() <= tol,
                "axis {i}: {} vs {}",
                back[i],
                x[i]
            );
        }
    }
    // k2 < 0, k3 = 0: y = x - 2e-3 x^2 peaks at x = 250 with y = 125. A larger y is impossible;
    // the inverse saturates at the fold instead of jumping to the other branch.
    let back = nl.inverse(Vec3::new(0.0, 200.0, 0.0), &c);
    assert!((back[1] - 250.0).abs() < 1e-9, "{}", back[1]);
}

#[test]
fn asymmetric_scale_keeps_sign_and_zero() {
    let a = AsymmetricScale {
        value: [0.5, -0.5, 0.75],
        std_error: None,
    };
    let c = Conditions::default();
    let y = a.forward(Vec3::new(0.0, -1.0, -1.0), &c);
    assert_eq!(y, Vec3::new(0.0, -1.5, -0.25));
    assert_eq!(a.inverse(y, &c), Vec3::new(0.0, -1.0, -1.0));
}

#[test]
fn params_round_trip_and_names_units_match_lengths() {
    let mut rng = rng(5);
    for triad in Triad::ALL {
        for kind in applicable(triad) {
            let mut m = random_model(&[kind], triad, &mut rng);
            let e = m.get_mut(kind).expect("present");
            let n = e.params().len();
            assert_eq!(e.param_names().len(), n, "{kind} names");
            assert_eq!(e.param_units(triad).len(), n, "{kind} units");
            assert_eq!(e.n_params(), n);
            let p: Vec<f64> = (0..n).map(|i| 0.25 + i as f64 * 1e-3).collect();
            e.set_params(&p);
            assert_eq!(e.params(), p, "{kind}");
            assert_eq!(e.std_errors(), None);
            let se: Vec<f64> = (0..n).map(|i| 1e-6 * (i + 1) as f64).collect();
            e.set_std_errors(Some(se.clone()));
            assert_eq!(e.std_errors(), Some(se), "{kind} std errors");
            e.set_std_errors(None);
            assert_eq!(e.std_errors(), None);
        }
    }
}

#[test]
fn param_names_and_units_are_the_documented_ones() {
    let mut m = TriadModel::default();
    for k in EffectKind::ALL {
        m.add(k);
    }
    let names = m.param_names(Triad::Gyro);
    let units = m.param_units(Triad::Gyro);
    assert_eq!(names.len(), m.params().len());
    assert_eq!(units.len(), m.params().len());
    let unit_of = |name: &str| {
        let i = names
            .iter()
            .position(|n| n == name)
            .unwrap_or_else(|| panic!("no {name} in {names:?}"));
        units[i].clone()
    };
    assert_eq!(unit_of("lever-arm.x"), "m");
    assert_eq!(unit_of("misalignment.zy"), "rad");
    assert_eq!(unit_of("scale.y"), "1");
    assert_eq!(unit_of("temp-scale.c1.z"), "1/K");
    assert_eq!(unit_of("scale-nonlinearity.quadratic.x"), "1/(rad/s)");
    assert_eq!(unit_of("scale-nonlinearity.cubic.x"), "1/(rad/s)^2");
    assert_eq!(unit_of("bias.x"), "rad/s");
    assert_eq!(unit_of("temp-bias.c1.y"), "(rad/s)/K");
    assert_eq!(unit_of("warmup.amplitude.z"), "rad/s");
    assert_eq!(unit_of("warmup.tau_s"), "s");
    assert_eq!(unit_of("g-sensitivity.zx"), "(rad/s)/(m/s^2)");
    let accel_units = m.param_units(Triad::Accel);
    let i = names
        .iter()
        .position(|n| n == "temp-bias.c1.x")
        .expect("present");
    assert_eq!(accel_units[i], "(m/s^2)/K");
    let m2 = TriadModel {
        temp_bias: Some(TempBias::with_degree(2)),
        ..Default::default()
    };
    assert_eq!(m2.param_units(Triad::Mag)[3], "gauss/K^2");
    assert_eq!(m2.param_names(Triad::Mag)[3], "temp-bias.c2.x");
}

#[test]
fn neutral_effects_are_the_identity() {
    let mut rng = rng(7);
    for kind in EffectKind::ALL {
        let mut m = TriadModel::default();
        m.add(kind);
        assert!(m.has(kind));
        assert_eq!(m.kinds(), vec![kind]);
        for triad in Triad::ALL {
            for _ in 0..20 {
                let c = random_conditions(&mut rng);
                let x = random_input(triad, &mut rng);
                assert_eq!(m.forward(x, &c), x, "{kind} forward");
                assert_eq!(m.inverse(x, &c), x, "{kind} inverse");
            }
        }
        m.remove(kind);
        assert!(!m.has(kind));
        assert!(m.is_empty());
    }
}

#[test]
fn add_keeps_existing_parameters() {
    let mut m = TriadModel {
        bias: Some(Bias {
            value: [1.0, 2.0, 3.0],
            std_error: None,
        }),
        ..Default::default()
    };
    m.add(EffectKind::Bias);
    assert_eq!(m.params(), vec![1.0, 2.0, 3.0]);
}

#[test]
fn triad_params_round_trip_in_canonical_layout() {
    let mut rng = rng(9);
    let kinds = applicable(Triad::Gyro);
    let mut m = random_model(&kinds, Triad::Gyro, &mut rng);
    let n = m.n_params();
    assert_eq!(m.param_names(Triad::Gyro).len(), n);
    let p: Vec<f64> = (0..n).map(|i| 1e-4 * (i as f64 + 1.0)).collect();
    m.set_params(&p);
    assert_eq!(m.params(), p);
    // The first parameters are misalignment's (lever-arm does not exist on a gyro model here).
    assert_eq!(m.misalignment.as_ref().map(|e| e.xy), Some(1e-4));
    let se: Vec<f64> = p.iter().map(|v| v / 10.0).collect();
    m.set_std_errors(Some(&se));
    assert_eq!(
        m.std_errors(),
        se.iter().map(|v| Some(*v)).collect::<Vec<_>>()
    );
    m.set_std_errors(None);
    assert!(m.std_errors().iter().all(Option::is_none));
}
