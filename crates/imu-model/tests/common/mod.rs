//! Shared helpers for the integration tests: realistic random parameters, inputs and conditions.

#![allow(dead_code)] // each test binary uses a different subset

use imu_model::units::STANDARD_GRAVITY_M_S2 as G;
use imu_model::{Conditions, EffectKind, TempBias, TempScale, Triad, TriadModel, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

pub fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

fn sym(rng: &mut ChaCha8Rng, half_width: f64) -> f64 {
    rng.random_range(-half_width..=half_width)
}

/// Typical magnitude of the triad's signal, in its unit.
pub fn input_range(triad: Triad) -> f64 {
    match triad {
        Triad::Accel => 5.0 * G,
        Triad::Gyro => 5.0,
        Triad::Mag => 0.8,
    }
}

/// Realistic random parameters for one effect (degree-2 polynomials for the temperature terms).
pub fn random_params(kind: EffectKind, triad: Triad, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let bias_scale = match triad {
        Triad::Accel => 0.5,
        Triad::Gyro => 0.05,
        Triad::Mag => 0.3,
    };
    let (k2, k3) = match triad {
        Triad::Accel => (2e-4, 2e-6),
        Triad::Gyro => (2e-3, 5e-5),
        Triad::Mag => (5e-3, 2e-3),
    };
    let mut v = |n: usize, w: f64| (0..n).map(|_| sym(rng, w)).collect::<Vec<f64>>();
    match kind {
        EffectKind::LeverArm => v(3, 0.1),
        EffectKind::Misalignment => v(6, 5e-3),
        EffectKind::Scale => v(3, 2e-2),
        EffectKind::AsymmetricScale => v(3, 1e-2),
        EffectKind::TempScale => [v(3, 2e-4), v(3, 2e-6)].concat(),
        EffectKind::ScaleNonlinearity => [v(3, k2), v(3, k3)].concat(),
        EffectKind::Bias => v(3, bias_scale),
        EffectKind::TempBias => [v(3, bias_scale * 4e-3), v(3, bias_scale * 4e-5)].concat(),
        EffectKind::Warmup => {
            let mut p = v(3, bias_scale / 2.0);
            p.push(rng.random_range(30.0..1200.0));
            p
        }
        EffectKind::GSensitivity => v(9, 2e-3),
    }
}

/// A model with exactly `kinds`, each with random realistic parameters.
pub fn random_model(kinds: &[EffectKind], triad: Triad, rng: &mut ChaCha8Rng) -> TriadModel {
    let mut m = TriadModel::default();
    for &k in kinds {
        match k {
            EffectKind::TempScale => m.temp_scale = Some(TempScale::with_degree(2)),
            EffectKind::TempBias => m.temp_bias = Some(TempBias::with_degree(2)),
            _ => m.add(k),
        }
        let p = random_params(k, triad, rng);
        m.get_mut(k).expect("just added").set_params(&p);
    }
    m
}

/// A random true input: mostly spread over the range, sometimes tiny or exactly zero on an axis.
pub fn random_input(triad: Triad, rng: &mut ChaCha8Rng) -> Vec3 {
    let r = input_range(triad);
    Vec3::from_fn(|_, _| match rng.random_range(0..10) {
        0 => 0.0,
        1 => sym(rng, r * 1e-6),
        _ => sym(rng, r),
    })
}

pub fn random_conditions(rng: &mut ChaCha8Rng) -> Conditions {
    Conditions {
        temp_c: rng.random_range(-20.0..70.0),
        time_since_power_on_s: rng.random_range(0.0..3600.0),
        specific_force_m_s2: Vec3::from_fn(|_, _| sym(rng, 5.0 * G)),
        angular_rate_rad_s: Vec3::from_fn(|_, _| sym(rng, 5.0)),
        angular_accel_rad_s2: Vec3::from_fn(|_, _| sym(rng, 50.0)),
    }
}

/// The effects that exist for `triad`, in canonical order.
pub fn applicable(triad: Triad) -> Vec<EffectKind> {
    EffectKind::ALL
        .into_iter()
        .filter(|k| k.applies_to(triad))
        .collect()
}
