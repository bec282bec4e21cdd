//! Power-law noise identification by the lag-1 autocorrelation (W. J. Riley and C. A.
//! Greenhall, "Power law noise identification using the lag 1 autocorrelation", 18th EFTF,
//! 2004), as Stable32 and allantools' `autocorr_noise_id` do it on phase data: decimate the
//! phase by the averaging factor, remove a quadratic, then difference until the lag-1
//! autocorrelation r1 gives delta = r1 / (1 + r1) < 0.25 (or the estimator's maximum number of
//! differences is reached); alpha = 2 - round(2 delta) - 2 d.

use crate::descriptive::lag1_autocorrelation;
use nalgebra::{Matrix3, Vector3};

/// Shortest decimated series the identification is trusted on (Riley & Greenhall: about 30).
pub const MIN_POINTS: usize = 30;

/// The power-law exponent alpha (S_y(f) ~ f^alpha) of phase `x` at averaging factor `m`,
/// differencing at most `d_max` times (2 for the Allan variances, 3 for the Hadamard ones).
/// `None` if the decimated series has fewer than `MIN_POINTS` (30) points.
pub fn autocorrelation_alpha(x: &[f64], m: usize, d_max: u32) -> Option<i32> {
    let decimated: Vec<f64> = x.iter().step_by(m.max(1)).copied().collect();
    if decimated.len() < MIN_POINTS {
        return None;
    }
    let mut z = remove_quadratic(&decimated);
    let mut d = 0u32;
    loop {
        let r1 = lag1_autocorrelation(&z);
        let delta = r1 / (1.0 + r1);
        if delta < 0.25 || d >= d_max {
            return Some(2 - (2.0 * delta).round() as i32 - 2 * d as i32);
        }
        z = z.windows(2).map(|w| w[1] - w[0]).collect();
        d += 1;
    }
}

/// `v` minus its least-squares quadratic in the sample index (the abscissa centred and scaled
/// to -1..1, so the normal equations stay well conditioned for any length).
fn remove_quadratic(v: &[f64]) -> Vec<f64> {
    let n = v.len();
    let half = ((n - 1) as f64 / 2.0).max(1.0);
    let t = |k: usize| (k as f64 - (n - 1) as f64 / 2.0) / half;
    let mut ata = Matrix3::zeros();
    let mut atb = Vector3::zeros();
    for (k, &y) in v.iter().enumerate() {
        let tk = t(k);
        let row = Vector3::new(1.0, tk, tk * tk);
        ata += row * row.transpose();
        atb += row * y;
    }
    let Some(c) = ata.lu().solve(&atb) else {
        return v.to_vec();
    };
    v.iter()
        .enumerate()
        .map(|(k, &y)| {
            let tk = t(k);
            y - (c[0] + c[1] * tk + c[2] * tk * tk)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn uniform(state: &mut u64) -> f64 {
        *state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (*state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    }

    /// White PM (phase white), white FM (phase a random walk) and random-walk FM (phase
    /// integrated twice) are told apart at several averaging factors.
    #[test]
    fn identifies_the_simulated_power_laws() {
        let mut s = 11u64;
        let white: Vec<f64> = (0..20_000).map(|_| uniform(&mut s)).collect();
        let walk: Vec<f64> = white
            .iter()
            .scan(0.0, |a, v| {
                *a += v;
                Some(*a)
            })
            .collect();
        let walk2: Vec<f64> = walk
            .iter()
            .scan(0.0, |a, v| {
                *a += v;
                Some(*a)
            })
            .collect();
        for m in [1, 4, 32] {
            assert_eq!(autocorrelation_alpha(&white, m, 2), Some(2), "m {m}");
            assert_eq!(autocorrelation_alpha(&walk, m, 2), Some(0), "m {m}");
            assert_eq!(autocorrelation_alpha(&walk2, m, 2), Some(-2), "m {m}");
        }
        assert_eq!(autocorrelation_alpha(&white, 1000, 2), None);
        // A constant series has no autocorrelation: white PM, no panic.
        assert_eq!(autocorrelation_alpha(&[1.0; 100], 1, 2), Some(2));
    }
}
