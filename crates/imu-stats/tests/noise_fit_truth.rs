//! Truth tests of the IEEE term fit's term selection on simulated series of known noise:
//! pure white noise gives B and K consistent with zero (not significant) on 20 seeds; white
//! plus rate random walk gives K within 25 % on a 6-hour 100 Hz record and no rate ramp; a
//! real rate ramp is found (Auto) and excluded when asked; Theo1 points beyond the OADEV's
//! longest tau recover a rate random walk within the reported uncertainty, narrow it, and add
//! no spurious K on white noise.

use imu_stats::allan::{EdfMethod, Kind, Options, TauSet, deviation};
use imu_stats::noise_terms::{
    FitOptions, NoiseTerms, RampTerm, fit_terms_extended, fit_terms_with,
};

const RATE_HZ: f64 = 100.0;

/// Standard normal deviates (Box-Muller on a 64-bit LCG; deterministic per seed).
struct Gauss(u64);

impl Gauss {
    fn new(seed: u64) -> Self {
        Gauss(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1)
    }

    fn uniform(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    fn next(&mut self) -> f64 {
        let (a, b) = (self.uniform(), self.uniform());
        (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos()
    }
}

/// `n` rate samples at 100 Hz: white noise of density `white` (U/sqrt(Hz)), a rate random
/// walk of `k` (U sqrt(Hz)) and a rate ramp of `ramp` (U/s).
fn series(seed: u64, n: usize, white: f64, k: f64, ramp: f64) -> Vec<f64> {
    let mut g = Gauss::new(seed);
    let mut walk = 0.0;
    (0..n)
        .map(|i| {
            walk += k / RATE_HZ.sqrt() * g.next();
            white * RATE_HZ.sqrt() * g.next() + walk + ramp * i as f64 / RATE_HZ
        })
        .collect()
}

fn fit(y: &[f64], options: &FitOptions) -> NoiseTerms {
    let opts = Options {
        taus: TauSet::PerDecade(8),
        edf: EdfMethod::Greenhall,
        ..Options::default()
    };
    let curve = deviation(Kind::Oadev, y, 1.0 / RATE_HZ, &opts).unwrap();
    fit_terms_with(&curve, options).unwrap()
}

#[test]
fn white_noise_gives_b_and_k_consistent_with_zero_on_20_seeds() {
    for seed in 0..20 {
        let y = series(seed, 360_000, 1e-3, 0.0, 0.0);
        let t = fit(&y, &FitOptions::default());
        assert!(
            (t.n_u_per_sqrt_hz.value / 1e-3 - 1.0).abs() < 0.05,
            "seed {seed}: {t:?}"
        );
        for (name, term) in [("B", t.b_u), ("K", t.k_u_sqrt_hz), ("R", t.r_u_per_s)] {
            assert!(!term.significant, "seed {seed}: {name} {term:?}");
            // Consistent with zero: within 3 sigma of it (a dropped term is 0 +- its bound).
            assert!(
                term.value <= 3.0 * term.sigma,
                "seed {seed}: {name} {term:?}"
            );
        }
    }
}

#[test]
fn random_walk_is_recovered_within_25_percent_on_a_6_hour_record() {
    for seed in [1, 2, 3] {
        let y = series(seed, 6 * 3600 * 100, 1e-3, 2e-5, 0.0);
        let t = fit(&y, &FitOptions::default());
        let k = t.k_u_sqrt_hz;
        assert!((k.value / 2e-5 - 1.0).abs() < 0.25, "seed {seed}: {t:?}");
        assert!(k.significant, "seed {seed}: {k:?}");
        assert!(
            !t.b_u.significant && !t.r_u_per_s.significant,
            "seed {seed}: {t:?}"
        );
        assert!(
            (t.n_u_per_sqrt_hz.value / 1e-3 - 1.0).abs() < 0.05,
            "seed {seed}: {t:?}"
        );
    }
}

#[test]
fn rate_ramp_only_where_the_curve_shows_it_or_when_asked() {
    // A 2-hour record with white noise and a ramp of 2e-6 U/s: the ADEV turns up with slope +1
    // from some 100 s on (R tau / sqrt(2) passes N / sqrt(tau) at tau ~ 100 s).
    let y = series(4, 720_000, 1e-3, 0.0, 2e-6);
    let auto = fit(&y, &FitOptions::default());
    let r = auto.r_u_per_s;
    assert!(
        r.significant && (r.value / 2e-6 - 1.0).abs() < 0.25,
        "{auto:?}"
    );
    let excluded = fit(
        &y,
        &FitOptions {
            ramp: RampTerm::Exclude,
            ..FitOptions::default()
        },
    );
    assert_eq!(excluded.r_u_per_s.value, 0.0, "{excluded:?}");
    // Without a ramp, Include lets the fit consider R, which the data then do not support.
    let walk = series(5, 720_000, 1e-3, 2e-5, 0.0);
    let included = fit(
        &walk,
        &FitOptions {
            ramp: RampTerm::Include,
            ..FitOptions::default()
        },
    );
    assert!(!included.r_u_per_s.significant, "{included:?}");
    assert!(included.k_u_sqrt_hz.significant, "{included:?}");
    // The default options are Auto.
    let auto_again = fit(
        &y,
        &FitOptions {
            ramp: RampTerm::Auto,
            ..FitOptions::default()
        },
    );
    assert_eq!(auto_again, auto);
}

/// The OADEV at 8 per decade with Greenhall's EDF, and Theo1 at the same set (read as
/// averaging times) beyond its longest tau, as `imu-noise --kind theo1` fits them.
fn oadev_and_theo1(y: &[f64]) -> (imu_stats::allan::DevCurve, imu_stats::allan::DevCurve) {
    let opts = Options {
        taus: TauSet::PerDecade(8),
        edf: EdfMethod::Greenhall,
        ..Options::default()
    };
    let oadev = deviation(Kind::Oadev, y, 1.0 / RATE_HZ, &opts).unwrap();
    let longest = oadev.points.last().unwrap().m;
    let beyond: Vec<usize> = TauSet::PerDecade(8)
        .factors(3 * y.len() / 4)
        .into_iter()
        .filter(|&f| f > longest)
        .collect();
    let theo_opts = Options {
        taus: TauSet::Factors(beyond),
        ..opts
    };
    let theo1 = deviation(Kind::Theo1, y, 1.0 / RATE_HZ, &theo_opts).unwrap();
    (oadev, theo1)
}

#[test]
fn theo1_points_recover_a_random_walk_within_the_reported_uncertainty() {
    // 400 s at 100 Hz, white 1e-3 and K = 2e-4 (crossing at sqrt(3) N / K = 8.7 s): the OADEV
    // stops at 178 s, Theo1 adds 237 s.
    let k_true = 2e-4;
    for seed in [1, 2, 3] {
        let y = series(seed, 40_000, 1e-3, k_true, 0.0);
        let (oadev, theo1) = oadev_and_theo1(&y);
        let alone = fit_terms_with(&oadev, &FitOptions::default()).unwrap();
        let t = fit_terms_extended(&oadev, Some(&theo1), &FitOptions::default()).unwrap();
        assert_eq!(alone.n_theo1_points, 0);
        assert!(t.n_theo1_points >= 1, "seed {seed}: {t:?}");
        assert_eq!(t.n_points, alone.n_points + t.n_theo1_points);
        let k = t.k_u_sqrt_hz;
        assert!(k.significant, "seed {seed}: {t:?}");
        assert!(
            (k.value - k_true).abs() < 2.0 * k.sigma,
            "seed {seed}: K {k:?}, truth {k_true}"
        );
        assert!(
            (t.n_u_per_sqrt_hz.value / 1e-3 - 1.0).abs() < 0.05,
            "seed {seed}: {t:?}"
        );
    }
}

#[test]
fn theo1_points_narrow_k_and_add_no_spurious_k_on_white_noise() {
    for seed in 0..6 {
        let y = series(seed, 40_000, 1e-3, 0.0, 0.0);
        let (oadev, theo1) = oadev_and_theo1(&y);
        let alone = fit_terms_with(&oadev, &FitOptions::default()).unwrap();
        let t = fit_terms_extended(&oadev, Some(&theo1), &FitOptions::default()).unwrap();
        assert!(t.n_theo1_points >= 1, "seed {seed}: {t:?}");
        assert!(!t.k_u_sqrt_hz.significant, "seed {seed}: {t:?}");
        // The extra points tighten the bound on a K the data do not show.
        assert!(
            t.k_u_sqrt_hz.sigma < alone.k_u_sqrt_hz.sigma,
            "seed {seed}: {:?} vs {:?}",
            t.k_u_sqrt_hz,
            alone.k_u_sqrt_hz
        );
    }
    // A Theo1 curve is required for the extension.
    let y = series(9, 4_000, 1e-3, 0.0, 0.0);
    let (oadev, _) = oadev_and_theo1(&y);
    assert!(fit_terms_extended(&oadev, Some(&oadev), &FitOptions::default()).is_err());
}
