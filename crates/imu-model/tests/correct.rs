//! Whole-sample tests: `Calibration::forward` then `Calibration::correct` recovers the truth,
//! including the accel/gyro coupling through lever arm and g-sensitivity.

mod common;

use common::*;
use imu_model::units::STANDARD_GRAVITY_M_S2 as G;
use imu_model::{Calibration, Conditions, EffectKind, Triad, TrueMotion, Vec3};

fn full_truth_model(seed: u64) -> Calibration {
    let mut rng = rng(seed);
    let mut cal = Calibration::identity();
    for t in Triad::ALL {
        *cal.triad_mut(t) = random_model(&applicable(t), t, &mut rng);
    }
    cal.validate().expect("realistic random model is valid");
    cal
}

fn rel_err(a: Vec3, b: Vec3) -> f64 {
    (a - b).norm() / b.norm().max(1e-12)
}

#[test]
fn correct_inverts_forward_with_lever_arm_and_g_sensitivity() {
    let mut rng = rng(21);
    for seed in 0..20 {
        let cal = full_truth_model(seed);
        assert!(cal.accel.has(EffectKind::LeverArm) && cal.gyro.has(EffectKind::GSensitivity));
        for _ in 0..50 {
            let c = random_conditions(&mut rng);
            let truth = TrueMotion {
                specific_force_m_s2: c.specific_force_m_s2,
                angular_rate_rad_s: c.angular_rate_rad_s,
                angular_accel_rad_s2: c.angular_accel_rad_s2,
                mag_field_gauss: random_input(Triad::Mag, &mut rng),
            };
            let m = cal.forward(&truth, &c);
            let out = cal.correct(
                &m,
                c.temp_c,
                c.time_since_power_on_s,
                truth.angular_accel_rad_s2,
            );
            assert!(out.converged);
            assert!(
                rel_err(out.accel_m_s2, truth.specific_force_m_s2) < 1e-9,
                "{out:?} vs {truth:?}"
            );
            assert!(
                rel_err(out.gyro_rad_s, truth.angular_rate_rad_s) < 1e-9,
                "{out:?} vs {truth:?}"
            );
            assert!(
                (out.mag_gauss - truth.mag_field_gauss).norm()
                    < 1e-9 * truth.mag_field_gauss.norm() + 1e-12
            );
            // Guard: the model really distorted the sample.
            assert!(rel_err(m.gyro_rad_s, truth.angular_rate_rad_s) > 1e-6);
        }
    }
}

#[test]
fn forward_takes_motion_from_truth_and_only_temperature_and_time_from_conditions() {
    let mut cal = Calibration::identity();
    cal.gyro.add(EffectKind::GSensitivity);
    cal.gyro.g_sensitivity.as_mut().expect("added").matrix[0][2] = 1e-3;
    let truth = TrueMotion {
        specific_force_m_s2: Vec3::new(0.0, 0.0, G),
        ..Default::default()
    };
    // Conditions carry a different (wrong) specific force: it must be ignored.
    let c = Conditions {
        specific_force_m_s2: Vec3::new(0.0, 0.0, -G),
        ..Default::default()
    };
    let m = cal.forward(&truth, &c);
    assert!((m.gyro_rad_s[0] - 1e-3 * G).abs() < 1e-15);
}

#[test]
fn uncoupled_models_converge_in_one_round() {
    let mut rng = rng(3);
    let mut cal = Calibration::identity();
    for t in Triad::ALL {
        let kinds: Vec<EffectKind> = applicable(t)
            .into_iter()
            .filter(|k| !matches!(k, EffectKind::LeverArm | EffectKind::GSensitivity))
            .collect();
        *cal.triad_mut(t) = random_model(&kinds, t, &mut rng);
    }
    let c = random_conditions(&mut rng);
    let truth = TrueMotion {
        specific_force_m_s2: c.specific_force_m_s2,
        angular_rate_rad_s: c.angular_rate_rad_s,
        angular_accel_rad_s2: c.angular_accel_rad_s2,
        mag_field_gauss: Vec3::new(0.2, -0.1, 0.4),
    };
    let out = cal.correct(
        &cal.forward(&truth, &c),
        c.temp_c,
        c.time_since_power_on_s,
        Vec3::zeros(),
    );
    assert!(out.converged);
    assert!(rel_err(out.accel_m_s2, truth.specific_force_m_s2) < 1e-12);
    assert!(rel_err(out.gyro_rad_s, truth.angular_rate_rad_s) < 1e-12);
}

#[test]
fn identity_calibration_passes_samples_through() {
    let cal = Calibration::identity();
    let m = imu_model::Measured {
        accel_m_s2: Vec3::new(0.1, 0.2, -G),
        gyro_rad_s: Vec3::new(0.01, -0.02, 0.03),
        mag_gauss: Vec3::new(0.2, 0.0, 0.4),
    };
    let out = cal.correct(&m, 25.0, 10.0, Vec3::zeros());
    assert!(out.converged);
    assert_eq!(
        (out.accel_m_s2, out.gyro_rad_s, out.mag_gauss),
        (m.accel_m_s2, m.gyro_rad_s, m.mag_gauss)
    );
}

#[test]
fn a_diverging_coupling_is_reported_as_not_converged() {
    // Loop gain ~ (2 |w| |r|) * |G| = 2 * 30 * 1 * 1 >> 1: no fixed point iteration can settle.
    // (Validation would reject G this large; the daemon must still not pretend.)
    let mut cal = Calibration::identity();
    cal.accel.add(EffectKind::LeverArm);
    cal.accel.lever_arm.as_mut().expect("added").offset_m = [1.0, 0.0, 0.0];
    cal.gyro.add(EffectKind::GSensitivity);
    cal.gyro.g_sensitivity.as_mut().expect("added").matrix =
        [[0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0]];
    let m = imu_model::Measured {
        accel_m_s2: Vec3::new(0.0, 0.0, G),
        gyro_rad_s: Vec3::new(0.0, 0.0, 30.0),
        mag_gauss: Vec3::zeros(),
    };
    let out = cal.correct(&m, 25.0, 0.0, Vec3::zeros());
    assert!(!out.converged, "{out:?}");
}
