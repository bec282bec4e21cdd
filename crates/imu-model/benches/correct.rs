//! Cost of `Calibration::correct` alone, per call, for the example 3DM-GX1 model and two
//! reductions of it: `correct` (prepared or affine path) against `correct_iterative` (the effect
//! chains and the fixed-point iteration) and against the plain loop `correct` was before this
//! benchmark existed (loop-invariant accel stages recomputed every round). Prints the median and
//! p90 over batches. Run: `cargo bench -p imu-model --bench correct`.

use std::hint::black_box;
use std::time::Instant;

use imu_model::{
    Calibration, Conditions, Corrected, EffectKind, InversePath, Measured, TrueMotion, Vec3,
};

const BATCH: usize = 1000;
const BATCHES: usize = 2000;

/// Measurements of a tumbling, shaken IMU through the model (deterministic, no RNG).
fn samples(cal: &Calibration) -> Vec<(Measured, Vec3)> {
    (0..BATCH)
        .map(|i| {
            let t = i as f64 * 0.01;
            let truth = TrueMotion {
                specific_force_m_s2: Vec3::new(2.0 * t.sin(), 1.5 * (0.7 * t).cos(), 9.8),
                angular_rate_rad_s: Vec3::new(0.5 * (1.3 * t).sin(), -0.2, 0.8 * t.cos()),
                angular_accel_rad_s2: Vec3::new(0.65 * (1.3 * t).cos(), 0.0, -0.8 * t.sin()),
                mag_field_gauss: Vec3::new(0.2 * t.cos(), 0.2 * t.sin(), 0.4),
            };
            let c = Conditions {
                temp_c: 30.0,
                time_since_power_on_s: 100.0 + t,
                ..Conditions::default()
            };
            (cal.forward(&truth, &c), truth.angular_accel_rad_s2)
        })
        .collect()
}

type Path = fn(&Calibration, &Measured, f64, f64, Vec3) -> Corrected;

fn run(label: &str, cal: &Calibration, path: Path) {
    let input = samples(cal);
    let mut per_call_ns = Vec::with_capacity(BATCHES);
    let mut converged = 0usize;
    for b in 0..BATCHES {
        let start = Instant::now();
        for (k, (m, a)) in input.iter().enumerate() {
            let out = path(
                black_box(cal),
                black_box(m),
                30.0,
                100.0 + k as f64 * 0.01,
                *a,
            );
            converged += usize::from(black_box(out).converged);
        }
        if b == 0 {
            assert_eq!(converged, BATCH, "{label}: every sample converges");
        }
        per_call_ns.push(start.elapsed().as_nanos() as f64 / BATCH as f64);
    }
    per_call_ns.sort_by(f64::total_cmp);
    let q = |p: f64| per_call_ns[((per_call_ns.len() - 1) as f64 * p) as usize];
    println!(
        "{label:<62} median {:>6.0} ns/call   p90 {:>6.0}",
        q(0.5),
        q(0.9)
    );
}

fn main() {
    let example = Calibration::load(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../config/models/example-3dm-gx1.toml"
    )))
    .expect("example model");
    let mut no_nonlinearity = example.clone();
    no_nonlinearity.accel.remove(EffectKind::ScaleNonlinearity);
    let mut linear = no_nonlinearity.clone();
    linear.accel.remove(EffectKind::LeverArm);
    assert_eq!(example.inverse_path(), InversePath::Prepared);
    assert_eq!(no_nonlinearity.inverse_path(), InversePath::Prepared);
    assert_eq!(linear.inverse_path(), InversePath::Affine);

    println!("Calibration::correct, {BATCH}-sample batches x {BATCHES}");
    let correct: Path = |c, m, t, s, a| c.correct(m, t, s, a);
    let iterative: Path = |c, m, t, s, a| c.correct_iterative(m, t, s, a);
    for (name, cal) in [
        ("example model", &example),
        ("example without nonlinearity", &no_nonlinearity),
        ("linear part (no nonlinearity, no lever arm)", &linear),
    ] {
        println!("{name}: correct takes the {:?} path", cal.inverse_path());
        run("  correct_iterative (accel stages hoisted)", cal, iterative);
        run("  correct", cal, correct);
    }
}
