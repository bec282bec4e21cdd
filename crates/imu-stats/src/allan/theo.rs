//! Theo1, bias-removed Theo1 (TheoBR) and TheoH (NIST SP 1065 sections 5.2.14 and 5.2.15;
//! D. A. Howe and T. N. Tasset, "Theo1: characterization of very long-term frequency stability",
//! EFTF 2004; D. A. Howe, "TheoH: a hybrid, high-confidence statistic that improves on the Allan
//! deviation", Metrologia 43, 2006) and the Theo1 EDF (SP 1065 section 5.5.6).
//!
//! Theo1 at an even averaging factor m (10 <= m <= N - 1, N phase points) is an Allan-compatible
//! variance at tau = 0.75 m tau0: it reaches averaging times up to 75 % of the record, where the
//! Allan variances have no or one difference left. TheoBR rescales Theo1 by the mean ratio of
//! AVAR to Theo1 over the short taus (removing Theo1's noise-dependent bias), and TheoH is AVAR
//! up to 10 % of the record and TheoBR beyond.

use super::kernels::sum_by;

/// Smallest Theo1 averaging factor SP 1065 defines it for.
pub const THEO1_MIN_M: usize = 10;

/// Theo1 averaging factor whose averaging time 0.75 m tau0 is nearest `f` tau0: the even m
/// nearest 4f/3 (f = 8 gives m = 10, tau 7.5 tau0; f = 1024 gives m = 1366, tau 1024.5 tau0).
pub fn theo1_m_for(f: usize) -> usize {
    2 * ((2 * f) as f64 / 3.0).round() as usize
}

/// Theo1 variance of phase `x` at averaging factor `m` (tau = 0.75 m tau0), or `None` unless m
/// is even and 2 <= m <= N - 1 (SP 1065 asks m >= 10; smaller even m are computed as allantools
/// does). SP 1065 eq. (30):
/// sum over i < N - m, u = m/2 - delta in 1..=m/2 of (1/u) ((x_i - x_{i+u}) + (x_{i+m} - x_{i+m-u}))^2,
/// over 0.75 (N - m) (m tau0)^2.
pub fn theo1_variance(x: &[f64], m: usize, tau0_s: f64) -> Option<f64> {
    let n = x.len();
    if m < 2 || !m.is_multiple_of(2) || m >= n {
        return None;
    }
    let tau = m as f64 * tau0_s;
    Some(theo1_sum(x, m) / (0.75 * (n - m) as f64 * tau * tau))
}

/// Theo1 sums of at least this many squared terms are split over two threads.
const PARALLEL_MIN_WORK: usize = 1 << 22;

/// The double sum of [`theo1_variance`]. The loop over i is innermost so each of the m/2 passes
/// reads four contiguous windows of `x` (the compiler vectorizes the eight-lane accumulation);
/// O((N - m) m / 2) work. Large sums split the u values over two threads (interleaved, so both
/// get the same work); the total does not depend on the split beyond rounding order, which is
/// fixed by the interleaving.
pub(super) fn theo1_sum(x: &[f64], m: usize) -> f64 {
    let half = m / 2;
    let len = x.len() - m;
    let term = |u: usize| {
        lane_sum(
            &x[..len],
            &x[u..u + len],
            &x[m..m + len],
            &x[m - u..m - u + len],
        ) / u as f64
    };
    if len.saturating_mul(half) < PARALLEL_MIN_WORK || half < 2 {
        return sum_by(1..=half, term);
    }
    let (odd, even) = std::thread::scope(|scope| {
        let other = scope.spawn(|| sum_by((2..=half).step_by(2), term));
        let mine = sum_by((1..=half).step_by(2), term);
        (mine, other.join().expect("Theo1 worker panicked"))
    });
    odd + even
}

/// Sum of ((a - b) + (c - d))^2 over equal-length slices, in eight independent lanes.
fn lane_sum(a: &[f64], b: &[f64], c: &[f64], d: &[f64]) -> f64 {
    const LANES: usize = 8;
    let mut acc = [0.0f64; LANES];
    let chunks = a
        .chunks_exact(LANES)
        .zip(b.chunks_exact(LANES))
        .zip(c.chunks_exact(LANES).zip(d.chunks_exact(LANES)));
    for ((a, b), (c, d)) in chunks {
        for j in 0..LANES {
            let t = (a[j] - b[j]) + (c[j] - d[j]);
            acc[j] += t * t;
        }
    }
    let tail = a.len() / LANES * LANES;
    let mut s: f64 = acc.iter().sum();
    for j in tail..a.len() {
        let t = (a[j] - b[j]) + (c[j] - d[j]);
        s += t * t;
    }
    s
}

/// TheoBR's bias ratio (SP 1065 eq. 31): the mean over i = 0..=n of AVAR(m = 9 + 3i) /
/// Theo1(m = 12 + 4i) (the same tau), n = floor(0.1 N / 3 - 3); `None` for fewer than 90
/// phase points (n < 0). `oavars(ms)` gives the overlapping Allan variances (tau0 = 1) at the
/// increasing factors `ms`. The N/30 Theo1 sums, at m up to 0.13 N, come from shared lagged
/// products (`theo_lags.rs`): O(N^2 / 7.5) instead of O(N^3 / 900) as separate double sums,
/// equal to those to about 1e-13 relative (their error is bounded per m, and any m that fails
/// the bound is summed directly).
pub fn theo_br_ratio(x: &[f64], oavars: impl FnOnce(&[usize]) -> Vec<f64>) -> Option<f64> {
    let n_br = (0.1 * x.len() as f64 / 3.0 - 3.0).floor();
    if n_br < 0.0 {
        return None;
    }
    let n_br = n_br as usize;
    let theo_ms: Vec<usize> = (0..=n_br).map(|i| 12 + 4 * i).collect();
    let avar_ms: Vec<usize> = (0..=n_br).map(|i| 9 + 3 * i).collect();
    let sums = super::theo_lags::theo1_sums(x, &theo_ms, |m| theo1_sum(x, m));
    let avars = oavars(&avar_ms);
    let n = x.len();
    let total = sum_by(0..=n_br, |i| {
        let m = theo_ms[i];
        let tau = m as f64;
        let theo = sums[i] / (0.75 * (n - m) as f64 * tau * tau);
        avars[i] / theo
    });
    Some(total / (n_br + 1) as f64)
}

/// Equivalent degrees of freedom of Theo1 (and TheoBR) at averaging factor `m` for `n_phase`
/// phase points and noise exponent `alpha` (SP 1065 section 5.5.6, Table 12, with
/// r = 0.75 m; alpha outside white PM..random-walk FM is taken as the nearest). The fitted forms
/// can fall below 1 (random-walk FM past m = 0.84 N); the EDF is kept at least 1.
pub fn edf_theo1(alpha: i32, m: usize, n_phase: usize) -> f64 {
    let n = n_phase as f64;
    let r = 0.75 * m as f64;
    let edf = match alpha.clamp(-2, 2) {
        2 => 0.86 * (n + 1.0) * (n - 4.0 * r / 3.0) / (n - r) * (r / (r + 1.14)),
        1 => {
            (4.798 * n * n - 6.374 * n * r + 12.387 * r) / ((r + 36.6).sqrt() * (n - r))
                * (r / (r + 0.3))
        }
        0 => ((4.1 * n + 0.8) / r - (3.1 * n + 6.5) / n) * (r.powf(1.5) / (r.powf(1.5) + 5.2)),
        -1 => (2.0 * n * n - 1.3 * n * r - 3.5 * r) / (n * r) * (r.powi(3) / (r.powi(3) + 2.3)),
        _ => {
            let a = 4.4 * n - 1.0;
            (4.4 * n - 2.0) / (2.9 * r) * (a * a - 8.6 * r * a + 11.4 * r * r)
                / (4.4 * n - 3.0).powi(2)
        }
    };
    if edf.is_finite() { edf.max(1.0) } else { 1.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The direct double sum, written as SP 1065 prints it (delta outer index, i inner).
    fn theo1_direct(x: &[f64], m: usize) -> f64 {
        let n = x.len();
        let h = m / 2;
        let mut s = 0.0;
        for i in 0..n - m {
            for delta in 0..h {
                let t = x[i] - x[i + h - delta] + x[i + m] - x[i + delta + h];
                s += t * t / (h - delta) as f64;
            }
        }
        s / (0.75 * (n - m) as f64 * (m * m) as f64)
    }

    #[test]
    fn theo1_equals_the_direct_double_sum() {
        let x: Vec<f64> = (0..301)
            .map(|i| ((i * 7919) % 101) as f64 * 0.01 + (i as f64).sqrt())
            .collect();
        for m in [2, 10, 12, 64, 150, 300] {
            let got = theo1_variance(&x, m, 1.0).unwrap();
            let want = theo1_direct(&x, m);
            assert!((got / want - 1.0).abs() < 1e-12, "m {m}: {got} vs {want}");
        }
        assert_eq!(theo1_variance(&x, 11, 1.0), None);
        assert_eq!(theo1_variance(&x, 302, 1.0), None);
    }

    /// A pure frequency offset has zero Theo1 (every term is a difference of equal slopes).
    #[test]
    fn theo1_of_a_linear_phase_is_zero() {
        let x: Vec<f64> = (0..200).map(|i| 0.25 * i as f64).collect();
        assert!(theo1_variance(&x, 40, 1.0).unwrap() < 1e-28);
    }

    /// The bias ratio equals SP 1065 eq. (31) evaluated term by term with the direct Theo1 double
    /// sum, to 1e-12, on white FM plus random-walk FM (3,000 points, 98 ratios).
    #[test]
    fn theo_br_ratio_equals_the_direct_evaluation() {
        let mut state: u64 = 5;
        let mut uniform = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let (mut walk, mut phase) = (0.0, 0.0);
        let x: Vec<f64> = (0..3000)
            .map(|_| {
                walk += 0.05 * uniform();
                phase += uniform() + walk;
                phase
            })
            .collect();
        // Overlapping AVAR at tau0 = 1, directly.
        let oavar = |m: usize| {
            let terms = x.len() - 2 * m;
            let s: f64 = (0..terms)
                .map(|i| (x[i + 2 * m] - 2.0 * x[i + m] + x[i]).powi(2))
                .sum();
            s / (2.0 * terms as f64 * (m * m) as f64)
        };
        let got = theo_br_ratio(&x, |ms| ms.iter().map(|&m| oavar(m)).collect()).unwrap();
        let n_br = (0.1 * 3000.0 / 3.0 - 3.0) as usize;
        let want = (0..=n_br)
            .map(|i| oavar(9 + 3 * i) / theo1_direct(&x, 12 + 4 * i))
            .sum::<f64>()
            / (n_br + 1) as f64;
        assert_eq!(n_br, 97);
        assert!((got / want - 1.0).abs() < 1e-12, "{got} vs {want}");
        assert!(got.is_finite() && got > 0.0, "{got}");
        assert_eq!(theo_br_ratio(&x[..89], |_| Vec::new()), None);
    }

    #[test]
    fn theo1_m_maps_to_the_nearest_even_factor() {
        assert_eq!(theo1_m_for(8), 10);
        assert_eq!(theo1_m_for(9), 12);
        assert_eq!(theo1_m_for(1024), 1366);
    }

    #[test]
    fn theo1_edf_is_at_least_one_and_falls_with_m() {
        for alpha in -2..=2 {
            let a = edf_theo1(alpha, 10, 1000);
            let b = edf_theo1(alpha, 500, 1000);
            assert!(a > b && b >= 1.0, "alpha {alpha}: {a} {b}");
        }
    }
}
