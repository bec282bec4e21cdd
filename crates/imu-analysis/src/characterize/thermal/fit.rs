//! The thermal analysis' numerics: time bins, the exponential warm-up fit, and polynomial fits
//! whose standard errors account for coloured noise (the residuals' variogram).

use imu_stats::descriptive::mean;
use imu_stats::linear::ordinary_least_squares;

use super::{PolyFit, ThermalBin, WarmupFit};
use crate::input::ImuSeries;

pub(super) fn make_bins(series: &ImuSeries, bin_s: f64) -> Vec<ThermalBin> {
    let mut bins = Vec::new();
    let n = series.len();
    if n == 0 || bin_s <= 0.0 {
        return bins;
    }
    let rate = series.sample_rate_hz();
    let expected = if rate.is_finite() { rate * bin_s } else { 1.0 };
    let t0 = series.t_s[0];
    let mut i = 0;
    while i < n {
        let k = ((series.t_s[i] - t0) / bin_s).floor();
        let end_t = t0 + (k + 1.0) * bin_s;
        let j = i + series.t_s[i..].partition_point(|&t| t < end_t);
        let m = j - i;
        // Partial bins (gaps, the end) would have a larger scatter than the rest.
        if m as f64 >= 0.5 * expected && m > 0 {
            let mut a = [0.0; 3];
            let mut g = [0.0; 3];
            let mut ts = 0.0;
            for s in i..j {
                ts += series.t_s[s];
                for c in 0..3 {
                    a[c] += series.accel_m_s2[s][c];
                    g[c] += series.gyro_rad_s[s][c];
                }
            }
            let inv = 1.0 / m as f64;
            let t_mid = ts * inv;
            let lo = t0 + k * bin_s;
            let readings: Vec<f64> = series
                .temp
                .iter()
                .filter(|&&(t, _)| t >= lo && t < end_t)
                .map(|&(_, c)| c)
                .collect();
            let temp_c = if readings.is_empty() {
                series.temp_at(t_mid)
            } else {
                mean(&readings)
            };
            bins.push(ThermalBin {
                t_s: t_mid,
                temp_c,
                accel_m_s2: a.map(|v| v * inv),
                gyro_rad_s: g.map(|v| v * inv),
                n_samples: m,
            });
        }
        i = j.max(i + 1);
    }
    bins
}

/// Fits `T = a + b exp(-t / tau)`: a log-spaced scan of tau with the linear parameters solved
/// exactly, refined by golden-section search; standard errors from the Jacobian.
pub(super) fn fit_warmup(temp: &[(f64, f64)]) -> Option<WarmupFit> {
    let n = temp.len();
    if n < 5 {
        return None;
    }
    let t0 = temp[0].0;
    let ts: Vec<f64> = temp.iter().map(|&(t, _)| t - t0).collect();
    let ys: Vec<f64> = temp.iter().map(|&(_, c)| c).collect();
    let span = ts[n - 1].max(1e-9);
    let rss_at = |ln_tau: f64| -> (f64, f64, f64) {
        let tau = ln_tau.exp();
        let rows: Vec<Vec<f64>> = ts.iter().map(|t| vec![1.0, (-t / tau).exp()]).collect();
        match ordinary_least_squares(&rows, &ys) {
            Some((c, _)) => {
                let rss = rows
                    .iter()
                    .zip(&ys)
                    .map(|(r, y)| (y - c[0] - c[1] * r[1]).powi(2))
                    .sum();
                (rss, c[0], c[1])
            }
            None => (f64::INFINITY, f64::NAN, f64::NAN),
        }
    };
    let (lo, hi) = ((span * 0.005).ln(), (span * 20.0).ln());
    let steps = 80;
    let mut best = (f64::INFINITY, lo);
    for k in 0..=steps {
        let l = lo + (hi - lo) * k as f64 / steps as f64;
        let r = rss_at(l).0;
        if r < best.0 {
            best = (r, l);
        }
    }
    let h = (hi - lo) / steps as f64;
    let (mut a, mut b) = (best.1 - h, best.1 + h);
    let phi = 0.5 * (5f64.sqrt() - 1.0);
    for _ in 0..60 {
        let c = b - phi * (b - a);
        let d = a + phi * (b - a);
        if rss_at(c).0 < rss_at(d).0 {
            b = d;
        } else {
            a = c;
        }
    }
    let ln_tau = 0.5 * (a + b);
    let (rss, p_final, p_amp) = rss_at(ln_tau);
    let tau = ln_tau.exp();
    let jac: Vec<Vec<f64>> = ts
        .iter()
        .map(|t| {
            let e = (-t / tau).exp();
            vec![1.0, e, p_amp * t * e / (tau * tau)]
        })
        .collect();
    let s2 = rss / (n as f64 - 3.0).max(1.0);
    let tau_std_s = ordinary_least_squares(&jac, &ys)
        .map(|(_, cov)| (cov[(2, 2)] * s2).sqrt())
        .unwrap_or(f64::NAN);
    Some(WarmupFit {
        tau_s: tau,
        tau_std_s,
        start_c: p_final + p_amp,
        final_c: p_final,
        residual_rms_c: (rss / n as f64).sqrt(),
    })
}

/// Polynomial least squares of `y` on `x` with standard errors from the residual scatter,
/// inflated by `sqrt((1 + r) / (1 - r))` for a positive lag-1 residual autocorrelation `r`.
pub(super) fn poly_fit(x: &[f64], y: &[f64], degree: usize) -> PolyFit {
    let p = degree + 1;
    let rows: Vec<Vec<f64>> = x
        .iter()
        .map(|&v| (0..p).map(|k| v.powi(k as i32)).collect())
        .collect();
    let nan = || PolyFit {
        coefficients: vec![f64::NAN; p],
        std_errors: vec![f64::NAN; p],
        t_stats: vec![f64::NAN; p],
        p_values: vec![1.0; p],
        residual_std: f64::NAN,
        residual_lag1_corr: f64::NAN,
        dof_effective: 0.0,
    };
    let n = x.len();
    if n <= p {
        return nan();
    }
    let Some((c, cov)) = ordinary_least_squares(&rows, y) else {
        return nan();
    };
    let resid: Vec<f64> = rows
        .iter()
        .zip(y)
        .map(|(r, y)| y - r.iter().zip(&c).map(|(a, b)| a * b).sum::<f64>())
        .collect();
    let rss: f64 = resid.iter().map(|r| r * r).sum();
    let s2 = rss / (n - p) as f64;
    // Coloured noise (bias instability, random walk) makes distant bins agree; the variance of
    // each coefficient is taken from the residuals' variogram, which exists for random walks
    // too: for weights w with sum 0, Var(sum w e) = -sum_ij w_i w_j gamma(|i - j|).
    let gamma = variogram_envelope(&resid);
    let std_errors: Vec<f64> = (0..p)
        .map(|k| {
            // Coefficient k = sum_i w_i y_i with w = row k of (X^T X)^-1 X^T.
            let w: Vec<f64> = rows
                .iter()
                .map(|r| (0..p).map(|j| cov[(k, j)] * r[j]).sum())
                .collect();
            let white = cov[(k, k)] * s2;
            let sum_w: f64 = w.iter().sum();
            let coloured = if sum_w.abs() < 1e-9 * w.iter().map(|v| v.abs()).sum::<f64>() {
                let mut v = 0.0;
                for i in 0..n {
                    for j in 0..n {
                        v -= w[i] * w[j] * gamma[i.abs_diff(j)];
                    }
                }
                v
            } else {
                white
            };
            white.max(coloured).sqrt()
        })
        .collect();
    let r1 = imu_stats::descriptive::lag1_autocorrelation(&resid).clamp(0.0, 0.95);
    let inflation = ((1.0 + r1) / (1.0 - r1))
        .max((std_errors[p - 1] * std_errors[p - 1] / (cov[(p - 1, p - 1)] * s2)).min(n as f64));
    let dof = ((n as f64) / inflation - p as f64).max(2.0);
    let t_stats: Vec<f64> = c.iter().zip(&std_errors).map(|(c, s)| c / s).collect();
    let p_values = t_stats
        .iter()
        .map(|&t| imu_stats::distributions::student_t_two_sided_p(t, dof))
        .collect();
    PolyFit {
        coefficients: c,
        std_errors,
        t_stats,
        p_values,
        residual_std: s2
            .sqrt()
            .max(gamma.iter().cloned().fold(0.0, f64::max).sqrt()),
        residual_lag1_corr: imu_stats::descriptive::lag1_autocorrelation(&resid),
        dof_effective: dof,
    }
}

/// Semi-variogram `gamma(h) = mean (e_{i+h} - e_i)^2 / 2` of a series, made non-decreasing
/// in `h` (the running maximum) so the sparse long lags cannot understate the drift.
fn variogram_envelope(e: &[f64]) -> Vec<f64> {
    let n = e.len();
    let mut g = vec![0.0; n.max(1)];
    let mut env = 0.0f64;
    for h in 1..n {
        let m = n - h;
        let v = (0..m).map(|i| (e[i + h] - e[i]).powi(2)).sum::<f64>() / (2.0 * m as f64);
        // Lags with very few pairs are too noisy to raise the envelope on their own.
        if m >= 3 || h == 1 {
            env = env.max(v);
        }
        g[h] = env;
    }
    g
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn t_distribution_p_values() {
        // Known quantiles: t = 2.228 at 10 dof -> p = 0.05; t = 1.96 at large dof -> 0.05.
        assert!((imu_stats::distributions::student_t_two_sided_p(2.228, 10.0) - 0.05).abs() < 1e-3);
        assert!((imu_stats::distributions::student_t_two_sided_p(1.96, 1e6) - 0.05).abs() < 1e-3);
        assert!((imu_stats::distributions::student_t_two_sided_p(0.0, 5.0) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn warmup_fit_recovers_tau() {
        let temp: Vec<(f64, f64)> = (0..3600)
            .map(|i| {
                let t = f64::from(i);
                (
                    t,
                    38.0 - 16.0 * (-t / 600.0).exp() + 0.05 * ((t * 1.7).sin()),
                )
            })
            .collect();
        let w = fit_warmup(&temp).unwrap();
        assert!((w.tau_s - 600.0).abs() < 3.0, "{w:?}");
        assert!((w.final_c - 38.0).abs() < 0.05 && (w.start_c - 22.0).abs() < 0.1);
    }

    #[test]
    fn polynomial_fit_is_exact_on_a_line() {
        let x: Vec<f64> = (0..20).map(f64::from).collect();
        let y: Vec<f64> = x
            .iter()
            .map(|v| 1.0 + 0.5 * v + if (*v as i64) % 2 == 0 { 1e-3 } else { -1e-3 })
            .collect();
        let f = poly_fit(&x, &y, 1);
        assert!((f.coefficients[1] - 0.5).abs() < 1e-4);
        assert!(f.p_values[1] < 1e-10);
    }
}
