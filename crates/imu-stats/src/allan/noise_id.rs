//! Power-law noise identification per averaging factor, as Stable32 does it for the EDF of the
//! confidence intervals (W. J. Riley, NIST SP 1065 section 5.6; W. J. Riley and C. A.
//! Greenhall, "Power law noise identification using the lag 1 autocorrelation", 18th EFTF,
//! 2004):
//!
//! - [`autocorrelation_alpha`], the lag-1 autocorrelation of the frequency averaged over m
//!   samples (a linear drift removed, differenced until delta = r1 / (1 + r1) < 0.25), where the
//!   phase decimated by m has at least [`MIN_POINTS`] (30) points;
//! - [`b1_alpha`], the B1 bias ratio (standard variance over Allan variance, Barnes' bias
//!   function, with R(n) = MVAR / AVAR telling white from flicker PM), what Stable32 uses for the
//!   non-overlapping variances when fewer averages remain (see `mod.rs` for which kind uses
//!   which).
//!
//! Both read only the m-averaged frequency, which is the differenced phase decimated by m: two
//! strided passes over the phase per averaging factor, O(N / m) arithmetic each, and no copy for
//! the autocorrelation (what allantools' `autocorr_noise_id(..., data_type="freq")` and `b1`
//! compute, without their copies).
//!
//! Why the averaged frequency rather than the decimated phase (allantools' default for phase
//! data): on the Cs 5071A record whose Stable32 tables ship with allantools (556,990 phase points,
//! `tests/Cs5071A/*_decade.txt`), the decimated phase with its quadratic removed gives white PM at
//! m = 10,000 (56 points, r1 = 0.16), where Stable32 prints white FM for every kind; the averaged
//! frequency gives white FM there and Stable32's type at every shorter decade tau, as does the
//! phase form.

/// Fewest decimated phase points (m-averaged frequency points plus one) the lag-1
/// autocorrelation is trusted on (Riley & Greenhall: about 30; Stable32's limit). Counted on the
/// phase, as Stable32 does: in the GPS table shipped with allantools
/// (`tests/gps/stable32_OADEV_octave.txt`) Stable32 identifies white FM at m = 8,192, where the
/// 241,218 phase points give 30 decimated points and 29 averages, and the previous tau's type
/// would have been flicker PM.
pub const MIN_POINTS: usize = 30;

/// Fewest m-averaged frequency points the B1 ratio is used on. Below it the ratio of two
/// variances each with a handful of degrees of freedom cannot tell neighbouring types apart, and
/// Stable32 keeps the type of the previous tau: in the GPS table shipped with allantools
/// (`tests/gps/stable32_HDEV_octave.txt`) the HDEV at m = 32,768 (7 averages) keeps the previous
/// tau's white FM where the ratio would say flicker PM, while at 27 averages (the Cs 5071A ADEV
/// and HDEV at m = 20,000) Stable32 prints the ratio's flicker FM where the previous tau had
/// white FM. The tables place the limit between 8 and 27; 10 is our choice within that.
pub const B1_MIN_POINTS: usize = 10;

/// The m-averaged frequency (in units of the phase step, i.e. not divided by m tau0: the
/// identification is scale-free): z[k] = x[(k + 1) m] - x[k m].
fn averaged_frequency(x: &[f64], m: usize) -> Vec<f64> {
    let m = m.max(1);
    let n = x.len().saturating_sub(1) / m;
    (0..n).map(|k| x[(k + 1) * m] - x[k * m]).collect()
}

/// The power-law exponent alpha (S_y(f) ~ f^alpha) of phase `x` at averaging factor `m` by the
/// lag-1 autocorrelation of the m-averaged frequency, for an estimator of phase-difference order
/// `d_max` (2 for the Allan variances, 3 for the Hadamard ones: the frequency is differenced at
/// most `d_max - 1` times). `None` if the decimated phase has fewer than [`MIN_POINTS`] points
/// (fewer than `MIN_POINTS - 1` averages).
pub fn autocorrelation_alpha(x: &[f64], m: usize, d_max: u32) -> Option<i32> {
    let m = m.max(1);
    let n = x.len().saturating_sub(1) / m;
    if n + 1 < MIN_POINTS {
        return None;
    }
    let r1 = lag1_of_differences(x, m, n);
    let d_freq = d_max.saturating_sub(1).min(2);
    let mut d = 0u32;
    loop {
        let delta = r1[d as usize] / (1.0 + r1[d as usize]);
        if delta < 0.25 || d >= d_freq {
            let alpha = -(2.0 * delta).round() - 2.0 * f64::from(d);
            // r1 = -1 (a constant difference) gives an infinite delta: clamp before the cast.
            return Some(alpha.clamp(-8.0, 8.0) as i32);
        }
        d += 1;
    }
}

/// The lag-1 autocorrelations of the `n` m-averages z of phase `x` with their least-squares
/// line removed (e), of its first difference (e[k+1] - e[k] = z[k+1] - z[k] - slope) and of its
/// second (z[k+2] - 2 z[k+1] + z[k]), each about its own mean as `lag1_autocorrelation`
/// defines it (e's mean is zero: the line has an intercept). Two strided passes over `x` and no
/// copy: the first finds the line, the second accumulates all three levels, whose means
/// telescope to (last - first) / count.
fn lag1_of_differences(x: &[f64], m: usize, n: usize) -> [f64; 3] {
    let z = |k: usize| x[(k + 1) * m] - x[k * m];
    let centre = (n - 1) as f64 / 2.0;
    let (mut sz, mut stz) = (0.0, 0.0);
    for k in 0..n {
        let v = z(k);
        sz += v;
        stz += (k as f64 - centre) * v;
    }
    let nf = n as f64;
    let mean = sz / nf;
    let slope = stz / (nf * (nf * nf - 1.0) / 12.0);
    let e = |k: usize| z(k) - mean - slope * (k as f64 - centre);
    let mean1 = (e(n - 1) - e(0)) / (nf - 1.0);
    let w = |k: usize| e(k + 1) - e(k);
    let mean2 = if n > 2 {
        (w(n - 2) - w(0)) / (nf - 2.0)
    } else {
        0.0
    };
    // (sum of products with the next, sum of squares) per level.
    let mut sums = [(0.0f64, 0.0f64); 3];
    let (mut e_prev, mut w_prev, mut v_prev) = (0.0, 0.0, 0.0);
    for k in 0..n {
        let e_k = e(k);
        sums[0].1 += e_k * e_k;
        if k >= 1 {
            sums[0].0 += e_prev * e_k;
            let w_k = (e_k - e_prev) - mean1;
            sums[1].1 += w_k * w_k;
            if k >= 2 {
                sums[1].0 += w_prev * w_k;
                let v_k = (w_k - w_prev) - mean2;
                sums[2].1 += v_k * v_k;
                if k >= 3 {
                    sums[2].0 += v_prev * v_k;
                }
                v_prev = v_k;
            }
            w_prev = w_k;
        }
        e_prev = e_k;
    }
    // A level with no variation has no autocorrelation (`lag1_autocorrelation`'s convention).
    sums.map(|(cross, square)| if square > 0.0 { cross / square } else { 0.0 })
}

/// The expected B1 ratio for `n` frequency averages and Allan-variance tau exponent `mu`
/// (Barnes' bias function as SP 1065 and allantools' `b1_theory` tabulate it).
fn b1_theory(n: usize, mu: i32) -> f64 {
    let n = n as f64;
    match mu {
        2 => n * (n + 1.0) / 6.0,
        1 => n / 2.0,
        0 => n * n.ln() / (2.0 * (n - 1.0) * std::f64::consts::LN_2),
        -1 => 1.0,
        -2 => (n * n - 1.0) / (1.5 * n * (n - 1.0)),
        _ => n * (1.0 - n.powi(mu)) / (2.0 * (n - 1.0) * (1.0 - 2f64.powi(mu))),
    }
}

/// The expected MVAR / AVAR ratio R(n) at averaging factor `m` for white PM (`flicker` false)
/// or flicker PM (with the measurement bandwidth f_h = 1 / (2 tau0)), as SP 1065 and
/// allantools' `rn_theory`.
fn rn_theory(m: usize, flicker: bool) -> f64 {
    use std::f64::consts::PI;
    let m = m as f64;
    if flicker {
        let avar = (1.038 + 3.0 * (PI * m).ln()) / (4.0 * PI * PI);
        let mvar = 3.0 * (256.0f64 / 27.0).ln() / (8.0 * PI * PI);
        mvar / avar
    } else {
        1.0 / m
    }
}

/// The power-law exponent alpha of phase `x` at averaging factor `m` by the B1 ratio of the
/// m-averaged frequency, for an estimator of difference order `d_max` (the Hadamard ones also
/// tell flicker-walk and random-run FM). Where B1 says phase noise, `mvar_over_avar` is asked
/// for R(n), the MVAR over the non-overlapping AVAR at this m, to tell white from flicker PM.
/// `None` if fewer than [`B1_MIN_POINTS`] averages exist or the series has no variation.
pub fn b1_alpha(
    x: &[f64],
    m: usize,
    d_max: u32,
    mvar_over_avar: impl FnOnce() -> f64,
) -> Option<i32> {
    let z = averaged_frequency(x, m);
    let n = z.len();
    if n < B1_MIN_POINTS.max(3) {
        return None;
    }
    let mean = z.iter().sum::<f64>() / n as f64;
    let variance = z.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
    let avar = z.windows(2).map(|w| (w[1] - w[0]).powi(2)).sum::<f64>() / (2 * (n - 1)) as f64;
    if avar.is_nan() || avar <= 0.0 {
        return None;
    }
    let ratio = variance / avar;
    let top_mu = d_max as i32; // mu 2 (alpha -3) for Allan, 3 (alpha -4) for Hadamard
    let mut mu = -2;
    while mu < top_mu {
        let boundary = (b1_theory(n, mu) * b1_theory(n, mu + 1)).sqrt();
        if ratio > boundary {
            mu += 1;
        } else {
            break;
        }
    }
    if mu > -2 {
        // mu = -1 white FM, 0 flicker FM, 1 random-walk FM, 2 flicker walk, 3 random run.
        return Some(-mu - 1);
    }
    let boundary = (rn_theory(m, false) * rn_theory(m, true)).sqrt();
    Some(if mvar_over_avar() > boundary { 1 } else { 2 })
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

    fn cumsum(v: &[f64]) -> Vec<f64> {
        v.iter()
            .scan(0.0, |a, x| {
                *a += x;
                Some(*a)
            })
            .collect()
    }

    /// The fused two-pass lag-1 autocorrelations equal the plain ones of the materialised
    /// series (line removed by a least-squares fit, then differenced), at each level.
    #[test]
    fn fused_levels_equal_the_materialised_series() {
        let mut s = 5u64;
        let walk = cumsum(&cumsum(
            &(0..5000).map(|_| uniform(&mut s)).collect::<Vec<_>>(),
        ));
        let x: Vec<f64> = walk
            .iter()
            .enumerate()
            .map(|(i, w)| w + 1e3 + 0.5 * i as f64 + uniform(&mut s))
            .collect();
        for m in [1, 3, 40] {
            let mut z = averaged_frequency(&x, m);
            let n = z.len();
            let t: Vec<f64> = (0..n).map(|k| k as f64).collect();
            let (tm, zm) = (
                t.iter().sum::<f64>() / n as f64,
                z.iter().sum::<f64>() / n as f64,
            );
            let b = t
                .iter()
                .zip(&z)
                .map(|(t, z)| (t - tm) * (z - zm))
                .sum::<f64>()
                / t.iter().map(|t| (t - tm).powi(2)).sum::<f64>();
            for (k, v) in z.iter_mut().enumerate() {
                *v -= zm + b * (k as f64 - tm);
            }
            let fused = lag1_of_differences(&x, m, n);
            for (level, got) in fused.iter().enumerate() {
                let want = crate::descriptive::lag1_autocorrelation(&z);
                assert!(
                    (got - want).abs() < 1e-9,
                    "m {m} level {level}: {got} vs {want}"
                );
                z = z.windows(2).map(|w| w[1] - w[0]).collect();
            }
        }
    }

    /// White PM (phase white), white FM (phase a random walk) and random-walk FM (phase
    /// integrated twice) are told apart at several averaging factors, by both methods.
    #[test]
    fn identifies_the_simulated_power_laws() {
        let mut s = 11u64;
        let white: Vec<f64> = (0..40_000).map(|_| uniform(&mut s)).collect();
        let walk = cumsum(&white);
        let walk2 = cumsum(&walk);
        for m in [1, 4, 32] {
            assert_eq!(autocorrelation_alpha(&white, m, 2), Some(2), "m {m}");
            assert_eq!(autocorrelation_alpha(&walk, m, 2), Some(0), "m {m}");
            assert_eq!(autocorrelation_alpha(&walk2, m, 2), Some(-2), "m {m}");
        }
        // The B1 ratio on 24 averages (m = 4, 97 phase points) of 200 independent records per
        // type: a ratio of two variances with about 24 degrees of freedom each, so single
        // records can be misread (about 70 % of white PM and random-walk FM records are read
        // right here, 80 % of white FM; a guess would be 20 %); most must not be.
        let r_n = |x: &[f64]| {
            let var = |k| super::super::variance_at(k, x, 4, 1.0).unwrap().0;
            var(super::super::Kind::Mdev) / var(super::super::Kind::Adev)
        };
        for (alpha, integrations) in [(2, 0), (0, 1), (-2, 2)] {
            let right = (0..200)
                .filter(|_| {
                    let mut x: Vec<f64> = (0..97).map(|_| uniform(&mut s)).collect();
                    for _ in 0..integrations {
                        x = cumsum(&x);
                    }
                    b1_alpha(&x, 4, 2, || r_n(&x)) == Some(alpha)
                })
                .count();
            assert!(right >= 120, "alpha {alpha}: {right} of 200");
        }
        assert_eq!(autocorrelation_alpha(&white, 2000, 2), None);
        assert_eq!(b1_alpha(&white, 5000, 2, || 0.0), None);
        // A constant series has no autocorrelation: white (of the frequency), no panic.
        assert_eq!(autocorrelation_alpha(&[1.0; 100], 1, 2), Some(0));
        assert_eq!(b1_alpha(&[1.0; 100], 1, 2, || 0.0), None);
    }
}
