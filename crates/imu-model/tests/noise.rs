//! Noise generator statistics: white, random-walk and bias-instability terms reproduce their
//! Allan-deviation signatures (IEEE Std 952: N at tau = 1 s, K sqrt(tau/3), flat 0.664 B).

use imu_model::{BIAS_INSTABILITY_ADEV_FACTOR, NoiseGenerator, NoiseModel, Vec3};

/// Overlapping Allan deviation of rate samples `y` (sample period `dt_s`) at `tau = m dt`,
/// computed from the integrated series x_k = dt * sum_{j<k} y_j:
/// sigma^2 = sum_k (x_{k+2m} - 2 x_{k+m} + x_k)^2 / (2 tau^2 (N + 1 - 2m)).
fn oadev(y: &[f64], dt_s: f64, m: usize) -> f64 {
    let mut x = Vec::with_capacity(y.len() + 1);
    let mut acc = 0.0;
    x.push(0.0);
    for v in y {
        acc += v * dt_s;
        x.push(acc);
    }
    let tau = m as f64 * dt_s;
    let n_terms = x.len() - 2 * m;
    let sum: f64 = (0..n_terms)
        .map(|k| {
            let d = x[k + 2 * m] - 2.0 * x[k + m] + x[k];
            d * d
        })
        .sum();
    (sum / (2.0 * tau * tau * n_terms as f64)).sqrt()
}

/// `n` samples of one axis.
fn series(model: &NoiseModel, rate_hz: f64, seed: u64, n: usize, axis: usize) -> Vec<f64> {
    let mut g = NoiseGenerator::new(model, rate_hz, seed);
    (0..n).map(|_| g.next()[axis]).collect()
}

#[test]
fn oadev_helper_matches_nist_reference_values() {
    // NIST SP 1065 1000-point Lehmer set (shared/reference/allan-reference-values.md).
    let mut n: u64 = 1_234_567_890;
    let y: Vec<f64> = (0..1000)
        .map(|_| {
            let v = n as f64 / 2_147_483_647.0;
            n = (16_807 * n) % 2_147_483_647;
            v
        })
        .collect();
    for (m, want) in [(1, 2.922319e-01), (10, 9.159953e-02), (100, 3.241343e-02)] {
        let got = oadev(&y, 1.0, m);
        assert!((got / want - 1.0).abs() < 1e-4, "tau {m}: {got} vs {want}");
    }
}

#[test]
fn white_noise_gives_its_density_at_one_second() {
    let rate_hz = 100.0;
    let density = 1.0e-3; // U/sqrt(Hz)
    let model = NoiseModel {
        white_density: [density, 2.0 * density, 0.0],
        ..Default::default()
    };
    let y = series(&model, rate_hz, 1, 200_000, 0);
    let std = (y.iter().map(|v| v * v).sum::<f64>() / y.len() as f64).sqrt();
    assert!(
        (std / (density * rate_hz.sqrt()) - 1.0).abs() < 0.02,
        "per-sample std {std}"
    );
    let adev_1s = oadev(&y, 1.0 / rate_hz, 100);
    assert!(
        (adev_1s / density - 1.0).abs() < 0.05,
        "ADEV(1 s) = {adev_1s}, density {density}"
    );
    let y1 = series(&model, rate_hz, 1, 200_000, 1);
    let adev_1s = oadev(&y1, 1.0 / rate_hz, 100);
    assert!(
        (adev_1s / (2.0 * density) - 1.0).abs() < 0.05,
        "axis y: {adev_1s}"
    );
    assert!(
        series(&model, rate_hz, 1, 1000, 2)
            .iter()
            .all(|v| *v == 0.0),
        "zero term stays zero"
    );
}

#[test]
fn random_walk_gives_k_sqrt_tau_over_3() {
    let rate_hz = 100.0;
    let k = 1.0e-4; // U/sqrt(s)
    let model = NoiseModel {
        random_walk: [k; 3],
        ..Default::default()
    };
    let y = series(&model, rate_hz, 2, 1_000_000, 0);
    for tau_s in [10.0, 30.0] {
        let m = (tau_s * rate_hz) as usize;
        let got = oadev(&y, 1.0 / rate_hz, m);
        let want = k * (tau_s / 3.0f64).sqrt();
        assert!(
            (got / want - 1.0).abs() < 0.15,
            "tau {tau_s}: {got} vs {want}"
        );
    }
}

#[test]
fn bias_instability_gives_a_flat_floor_of_0_664_b() {
    let rate_hz = 100.0;
    let b = 1.0e-4; // U
    let model = NoiseModel {
        bias_instability: [b; 3],
        ..Default::default()
    };
    let y = series(&model, rate_hz, 3, 2_000_000, 0);
    let want = BIAS_INSTABILITY_ADEV_FACTOR * b;
    for tau_s in [10.0, 20.0, 50.0, 100.0] {
        let m = (tau_s * rate_hz) as usize;
        let got = oadev(&y, 1.0 / rate_hz, m);
        assert!(
            (got / want - 1.0).abs() < 0.15,
            "tau {tau_s}: {got} vs {want}"
        );
    }
    // Flicker is not white: at short tau the floor is reached from below, not as 1/sqrt(tau).
    let short = oadev(&y, 1.0 / rate_hz, 1);
    assert!(short < 2.0 * want, "ADEV(0.01 s) = {short}");
}

#[test]
fn theory_curve_combines_the_terms() {
    let model = NoiseModel {
        white_density: [2.0, 0.0, 0.0],
        bias_instability: [0.0, 1.0, 0.0],
        random_walk: [0.0, 0.0, 3.0],
        ..Default::default()
    };
    let a = model.allan_deviation(4.0);
    assert!((a[0] - 1.0).abs() < 1e-15);
    assert!((a[1] - BIAS_INSTABILITY_ADEV_FACTOR).abs() < 1e-15);
    assert!((a[2] - 3.0 * (4.0f64 / 3.0).sqrt()).abs() < 1e-14);
}

#[test]
fn generator_is_deterministic_and_terms_use_independent_streams() {
    let model = NoiseModel {
        white_density: [1e-3; 3],
        bias_instability: [1e-4; 3],
        random_walk: [1e-5; 3],
        ..Default::default()
    };
    let take = |m: &NoiseModel, seed| {
        let mut g = NoiseGenerator::new(m, 200.0, seed);
        (0..500).map(|_| g.next()).collect::<Vec<Vec3>>()
    };
    assert_eq!(take(&model, 42), take(&model, 42));
    assert_ne!(take(&model, 42), take(&model, 43));
    // Axes differ from each other.
    let s = take(&model, 42);
    assert!(s.iter().any(|v| v[0] != v[1]));
    // Turning off the other terms leaves the white sequence untouched.
    let white_only = NoiseModel {
        white_density: [1e-3; 3],
        ..Default::default()
    };
    let mut full_white = NoiseGenerator::new(
        &NoiseModel {
            bias_instability: [0.0; 3],
            random_walk: [0.0; 3],
            ..model.clone()
        },
        200.0,
        42,
    );
    let mut only = NoiseGenerator::new(&white_only, 200.0, 42);
    for _ in 0..100 {
        assert_eq!(full_white.next(), only.next());
    }
    // A zero model produces zeros.
    let mut zero = NoiseGenerator::new(&NoiseModel::default(), 100.0, 1);
    assert_eq!(zero.next(), Vec3::zeros());
}

#[test]
fn quantize_rounds_to_the_lsb() {
    let model = NoiseModel {
        quantization_lsb: [0.5, 0.0, 0.1],
        ..Default::default()
    };
    let q = model.quantize(Vec3::new(1.3, 1.3, -0.26));
    assert_eq!(q[0], 1.5);
    assert_eq!(q[1], 1.3);
    assert!((q[2] + 0.3).abs() < 1e-15);
}
