//! Equivalent degrees of freedom of the Allan-family variances by Greenhall's algorithm
//! (C. A. Greenhall and W. J. Riley, "Uncertainty of stability variances based on finite
//! differences", 35th PTTI, 2003; the "EDF for Allan variance estimators" computation that
//! Stable32 and allantools' `edf_greenhall` use), and the total variance's EDF (NIST SP 1065
//! Table 7).
//!
//! A variance estimator is described by d (1 first difference, 2 Allan, 3 Hadamard), the
//! filter factor F (1 for the modified variances, m for the others), the stride S (m when
//! overlapping, 1 otherwise) and the power-law exponent alpha of the fractional-frequency
//! spectrum S_y(f) ~ f^alpha. The EDF is the exact "basic sum" (eq. 10 of the paper) over the
//! estimator's autocovariances when it has at most `J_MAX` terms, and the paper's fitted
//! asymptotic forms (Tables 1 to 3) beyond that.

use super::NoiseType;

/// Terms of the basic sum beyond which the asymptotic forms are used (the paper's J_max).
const J_MAX: f64 = 100.0;

/// Filter factor of an estimator: finite, or the limit F -> infinity of the paper's case 2.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Filter {
    /// F = this value.
    Finite(f64),
    /// F -> infinity.
    Infinite,
}

/// Which variance estimator the EDF is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Estimator {
    /// Order of the phase difference: 2 for the Allan variances, 3 for the Hadamard ones.
    pub d: u32,
    /// Overlapping (stride tau0) rather than non-overlapping (stride tau).
    pub overlapping: bool,
    /// Modified (phase averaged over m samples first): MVAR and TVAR.
    pub modified: bool,
}

/// Eq. (7): the generalized autocovariance kernel of the power law with exponent `alpha`.
fn sw(t: f64, alpha: i32) -> f64 {
    let log_term = |p: i32| {
        if t == 0.0 {
            0.0
        } else {
            t.powi(p) * t.abs().ln()
        }
    };
    match alpha {
        2 => -t.abs(),
        1 => log_term(2),
        0 => t.abs().powi(3),
        -1 => log_term(4),
        -2 => t.abs().powi(5),
        -3 => log_term(6),
        _ => t.abs().powi(7),
    }
}

/// Eq. (8): the kernel after the averaging filter of factor `f`.
fn sx(t: f64, f: Filter, alpha: i32) -> f64 {
    match f {
        Filter::Infinite => sw(t, alpha + 2),
        Filter::Finite(f) => {
            f * f * (2.0 * sw(t, alpha) - sw(t - 1.0 / f, alpha) - sw(t + 1.0 / f, alpha))
        }
    }
}

/// Eq. (9): the kernel after the d-th difference: sum over k of (-1)^k C(2d, d+k) sx(t + k).
fn sz(t: f64, f: Filter, alpha: i32, d: u32) -> f64 {
    let d = d as i32;
    (-d..=d)
        .map(|k| {
            let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
            sign * binomial(2 * d as u32, (d + k) as u32) * sx(t + f64::from(k), f, alpha)
        })
        .sum()
}

/// Binomial coefficient C(n, k) as a float (small arguments only).
fn binomial(n: u32, k: u32) -> f64 {
    (0..k).fold(1.0, |acc, i| acc * f64::from(n - i) / f64::from(i + 1))
}

/// Eq. (10): the basic sum over the estimator's J autocovariance terms.
fn basic_sum(j: f64, m: f64, s: f64, f: Filter, alpha: i32, d: u32) -> f64 {
    let sq = |t: f64| sz(t, f, alpha, d).powi(2);
    let mut total = sq(0.0) + (1.0 - j / m) * sq(j / s);
    let mut k = 1.0;
    while k < j {
        total += 2.0 * (1.0 - k / m) * sq(k / s);
        k += 1.0;
    }
    total
}

/// Table 1 (modified variances, r > d + 1): (a0, a1).
fn table1(alpha: i32, d: u32) -> (f64, f64) {
    // A flat table, row alpha = +2 .. -4, column d = 1 .. 3; (-1, -1) where undefined.
    const T: [[(f64, f64); 3]; 7] = [
        [
            (2.0 / 3.0, 1.0 / 3.0),
            (7.0 / 9.0, 1.0 / 2.0),
            (22.0 / 25.0, 2.0 / 3.0),
        ],
        [(0.840, 0.345), (0.997, 0.616), (1.141, 0.843)],
        [(1.079, 0.368), (1.033, 0.607), (1.184, 0.848)],
        [(-1.0, -1.0), (1.048, 0.534), (1.180, 0.816)],
        [(-1.0, -1.0), (1.302, 0.535), (1.175, 0.777)],
        [(-1.0, -1.0), (-1.0, -1.0), (1.194, 0.703)],
        [(-1.0, -1.0), (-1.0, -1.0), (1.489, 0.702)],
    ];
    T[(2 - alpha) as usize][(d - 1) as usize]
}

/// Table 2 (unmodified variances, r > d + 1): (a0, a1).
fn table2(alpha: i32, d: u32) -> (f64, f64) {
    // A flat table, row alpha = +2 .. -4, column d = 1 .. 3; (-1, -1) where undefined.
    const T: [[(f64, f64); 3]; 7] = [
        [
            (3.0 / 2.0, 1.0 / 2.0),
            (35.0 / 18.0, 1.0),
            (231.0 / 100.0, 3.0 / 2.0),
        ],
        [(78.6, 25.2), (790.0, 410.0), (9950.0, 6520.0)],
        [
            (2.0 / 3.0, 1.0 / 6.0),
            (2.0 / 3.0, 1.0 / 3.0),
            (7.0 / 9.0, 1.0 / 2.0),
        ],
        [(-1.0, -1.0), (0.852, 0.375), (0.997, 0.617)],
        [(-1.0, -1.0), (1.079, 0.368), (1.033, 0.607)],
        [(-1.0, -1.0), (-1.0, -1.0), (1.053, 0.553)],
        [(-1.0, -1.0), (-1.0, -1.0), (1.302, 0.535)],
    ];
    T[(2 - alpha) as usize][(d - 1) as usize]
}

/// Table 3 (unmodified variances, flicker PM): (b0, b1).
fn table3(d: u32) -> (f64, f64) {
    [(6.0, 4.0), (15.23, 12.0), (47.8, 40.0)][(d - 1) as usize]
}

/// The lowest power-law exponent the estimator of difference order `d` converges for
/// (alpha + 2d > 1).
pub fn min_alpha(d: u32) -> i32 {
    2 - 2 * d as i32
}

/// Greenhall's EDF of the estimator `est` at averaging factor `m` on `n_phase` phase points for
/// noise of exponent `alpha` (clamped into `min_alpha(d)..=2`).
pub fn edf_greenhall(alpha: i32, est: Estimator, m: usize, n_phase: usize) -> f64 {
    let d = est.d;
    let alpha = alpha.clamp(min_alpha(d), 2);
    let mf = m as f64;
    let df = f64::from(d);
    let f = if est.modified { 1.0 } else { mf };
    let s = if est.overlapping { mf } else { 1.0 };
    let l = mf / f + mf * df;
    let big_m = 1.0 + (s * (n_phase as f64 - l) / mf).floor();
    if big_m < 1.0 {
        return 1.0;
    }
    let j = big_m.min((df + 1.0) * s);
    let r = big_m / s;
    let inv = if est.modified {
        inv_edf_modified(alpha, d, j, big_m, s, r)
    } else if alpha <= 0 {
        inv_edf_unmodified(alpha, d, mf, j, big_m, s, r)
    } else if alpha == 1 {
        inv_edf_flicker_pm(d, mf, j, big_m, s, r)
    } else {
        inv_edf_white_pm(d, mf, j, big_m, s, r)
    };
    let edf = 1.0 / inv;
    if edf.is_finite() && edf > 0.0 {
        edf
    } else {
        1.0
    }
}

/// Case 1: the modified variances (F = 1), every alpha.
fn inv_edf_modified(alpha: i32, d: u32, j: f64, big_m: f64, s: f64, r: f64) -> f64 {
    let one = Filter::Finite(1.0);
    if j <= J_MAX {
        basic_sum(j, big_m, s, one, alpha, d) / (sz(0.0, one, alpha, d).powi(2) * big_m)
    } else if r > f64::from(d) + 1.0 {
        let (a0, a1) = table1(alpha, d);
        (a0 - a1 / r) / r
    } else {
        let m_prime = J_MAX / r;
        basic_sum(J_MAX, J_MAX, m_prime, one, alpha, d) / (sz(0.0, one, alpha, d).powi(2) * J_MAX)
    }
}

/// Case 2: the unmodified variances (F = m), alpha <= 0.
fn inv_edf_unmodified(alpha: i32, d: u32, m: f64, j: f64, big_m: f64, s: f64, r: f64) -> f64 {
    if j <= J_MAX {
        let f = if m * (f64::from(d) + 1.0) <= J_MAX {
            Filter::Finite(m)
        } else {
            Filter::Infinite
        };
        basic_sum(j, big_m, s, f, alpha, d) / (sz(0.0, f, alpha, d).powi(2) * big_m)
    } else if r > f64::from(d) + 1.0 {
        let (a0, a1) = table2(alpha, d);
        (a0 - a1 / r) / r
    } else {
        let m_prime = J_MAX / r;
        let inf = Filter::Infinite;
        basic_sum(J_MAX, J_MAX, m_prime, inf, alpha, d) / (sz(0.0, inf, alpha, d).powi(2) * J_MAX)
    }
}

/// Case 3: the unmodified variances, flicker PM (alpha = 1).
fn inv_edf_flicker_pm(d: u32, m: f64, j: f64, big_m: f64, s: f64, r: f64) -> f64 {
    let (b0, b1) = table3(d);
    if j <= J_MAX {
        let f = Filter::Finite(m);
        basic_sum(j, big_m, s, f, 1, d) / (sz(0.0, f, 1, d).powi(2) * big_m)
    } else if r > f64::from(d) + 1.0 {
        let (a0, a1) = table2(1, d);
        (a0 - a1 / r) / ((b0 + b1 * m.ln()).powi(2) * r)
    } else {
        let m_prime = J_MAX / r;
        let f = Filter::Finite(m_prime);
        basic_sum(J_MAX, J_MAX, m_prime, f, 1, d) / ((b0 + b1 * m.ln()).powi(2) * J_MAX)
    }
}

/// Case 4: the unmodified variances, white PM (alpha = 2). For r > d the paper's closed form;
/// for the few longest taus where ceil(r) <= d, the exact basic sum (which the closed form
/// approximates, and which allantools leaves unimplemented).
fn inv_edf_white_pm(d: u32, m: f64, j: f64, big_m: f64, s: f64, r: f64) -> f64 {
    if r.ceil() <= f64::from(d) {
        let f = Filter::Finite(m);
        return basic_sum(j, big_m, s, f, 2, d) / (sz(0.0, f, 2, d).powi(2) * big_m);
    }
    let a0 = binomial(4 * d, 2 * d) / binomial(2 * d, d).powi(2);
    let a1 = f64::from(d) / 2.0;
    (a0 - a1 / r) / big_m
}

/// EDF of the total variance (NIST SP 1065 Table 7: b N/m - c) for white, flicker and
/// random-walk FM; other noise types use the SP 1065 Table 5 forms, as Stable32 and allantools.
pub fn edf_totdev(alpha: i32, m: usize, n_phase: usize) -> f64 {
    let ratio = n_phase as f64 / m as f64;
    let edf = match alpha {
        0 => 1.50 * ratio,
        -1 => 1.17 * ratio - 0.22,
        -2 => 0.93 * ratio - 0.36,
        _ => super::confidence::edf_sp1065(n_phase, m, NoiseType::from_alpha(alpha)),
    };
    if edf.is_finite() { edf.max(1.0) } else { 1.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Values from allantools 2024.06 `edf_greenhall` (which reproduces Stable32), covering the
    /// basic sum, the tabulated asymptotes and the J_max branches of every case:
    /// (alpha, d, overlapping, modified, m, N phase points, EDF).
    #[test]
    fn edf_equals_allantools_in_every_case() {
        // A flat table of reference values.
        let cases = [
            (0, 2, true, false, 1, 1001, 782.030_299_072_743_8),
            (0, 2, true, false, 128, 1001, 9.550_953_331_497_8),
            (0, 2, true, true, 2, 1001, 478.996_152_279_208_7),
            (0, 3, false, false, 128, 1001, 2.866_242_038_216_560_8),
            (2, 2, true, false, 10, 100_000, 51_420.930_748_302_44),
            (1, 2, true, false, 10, 100_000, 25_072.766_901_532_77),
            (1, 2, false, false, 3, 1000, 187.665_765_858_462_66),
            (-1, 2, true, false, 50, 100_000, 2_345.587_133_597_858),
            (-2, 2, true, false, 1000, 100_000, 91.142_027_445_100_33),
            (-4, 3, true, false, 7, 5000, 544.912_916_167_854_6),
            (-3, 3, false, false, 20, 5000, 220.143_407_481_799_16),
            (2, 2, true, true, 300, 100_000, 425.546_713_660_727_05),
            (-2, 2, true, true, 5, 100_000, 15_356.392_249_680_026),
            (1, 3, true, true, 64, 100_000, 1_366.568_624_893_348_7),
            (0, 2, true, false, 60, 200, 3.151_846_785_225_718),
            (-1, 2, true, false, 30_000, 100_000, 2.241_948_870_315_728),
            (2, 3, false, false, 100, 1000, 3.340_149_965_916_837_4),
            (1, 2, true, false, 40_000, 100_000, 28.022_151_962_651_353),
        ];
        for (alpha, d, overlapping, modified, m, n, want) in cases {
            let est = Estimator {
                d,
                overlapping,
                modified,
            };
            let got = edf_greenhall(alpha, est, m, n);
            assert!(
                (got / want - 1.0).abs() < 1e-9,
                "alpha {alpha} {est:?} m {m} N {n}: {got} vs {want}"
            );
        }
        // Beyond the estimator's span (allantools returns a negative EDF here): the minimum.
        let mvar3 = Estimator {
            d: 3,
            overlapping: true,
            modified: true,
        };
        assert_eq!(edf_greenhall(0, mvar3, 40_000, 100_000), 1.0);
    }
}
