//! Thermal (warm-up) test of Aslan & Saranli 3.1.3 / 3.2.3: output versus temperature and time,
//! the warm-up time constant, temperature coefficients with honest uncertainties, and a plain
//! recommendation whether a thermal error model is warranted over the observed range.
//!
//! The data are reduced to time bins first. Coefficients are fitted to the bin means, and their
//! standard errors come from the scatter of the bin means about the fit (inflated for the
//! residuals' serial correlation), not from white-noise formulas: bias instability and random
//! walk make neighbouring bins agree with each other, which a white-noise formula would read
//! as a (spurious) temperature coefficient.

use imu_stats::descriptive::{correlation, mean};
use imu_stats::linear::ordinary_least_squares;
use serde::Serialize;

use crate::input::ImuSeries;
use crate::render::svg::{Chart, Series, Style};

const G0: f64 = imu_model::units::STANDARD_GRAVITY_M_S2;

/// Errors of the thermal analysis.
#[derive(Debug, thiserror::Error)]
pub enum ThermalError {
    /// The recording has no temperature readings.
    #[error(
        "{origin}: no temperature readings; record with temperature logging on (imud logs it at device.temperature-rate-hz)"
    )]
    NoTemperature {
        /// The input.
        origin: String,
    },
    /// Too little data for the bins asked for.
    #[error(
        "{origin}: only {n_bins} bins of {bin_s} s; need at least {min_bins} (use a longer recording or smaller bins)"
    )]
    TooShort {
        /// The input.
        origin: String,
        /// Bins obtained.
        n_bins: usize,
        /// Bin width, s.
        bin_s: f64,
        /// Bins needed.
        min_bins: usize,
    },
}

/// Settings of the thermal analysis.
#[derive(Debug, Clone, PartialEq)]
pub struct ThermalOptions {
    /// Width of a time bin, s.
    pub bin_s: f64,
    /// Two-sided p-value below which a coefficient is called significant.
    pub significance_p: f64,
    /// A coefficient is practically relevant when the change it predicts over the observed
    /// temperature range exceeds this many times the scatter of a bin mean.
    pub relevance_factor: f64,
}

impl Default for ThermalOptions {
    fn default() -> Self {
        Self {
            bin_s: 60.0,
            significance_p: 0.01,
            relevance_factor: 3.0,
        }
    }
}

/// One time bin: means of everything in it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ThermalBin {
    /// Mean sample time, s.
    pub t_s: f64,
    /// Mean temperature, deg C.
    pub temp_c: f64,
    /// Mean specific force, m/s^2.
    pub accel_m_s2: [f64; 3],
    /// Mean angular rate, rad/s.
    pub gyro_rad_s: [f64; 3],
    /// Samples in the bin.
    pub n_samples: usize,
}

/// Exponential warm-up fit `T(t) = final - (final - start) exp(-t / tau)`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WarmupFit {
    /// Time constant, s.
    pub tau_s: f64,
    /// Standard error of `tau_s`, s.
    pub tau_std_s: f64,
    /// Fitted temperature at t = 0, deg C.
    pub start_c: f64,
    /// Fitted asymptotic (operating) temperature, deg C.
    pub final_c: f64,
    /// RMS of the readings about the fit, deg C.
    pub residual_rms_c: f64,
}

/// A polynomial fit of bin means against `T - T_ref`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PolyFit {
    /// Coefficients, lowest order first (unit: output unit / K^k).
    pub coefficients: Vec<f64>,
    /// Standard errors (from the bin scatter, inflated for serial correlation).
    pub std_errors: Vec<f64>,
    /// t-statistics `coefficient / std_error`.
    pub t_stats: Vec<f64>,
    /// Two-sided p-values (Student t with the effective degrees of freedom).
    pub p_values: Vec<f64>,
    /// Scatter of the bin means about the fit (output unit): the larger of the residual
    /// standard deviation and the root of the residuals' variogram plateau (the drift level).
    pub residual_std: f64,
    /// Lag-1 autocorrelation of the residuals.
    pub residual_lag1_corr: f64,
    /// Effective degrees of freedom after the coloured-noise correction.
    pub dof_effective: f64,
}

/// The thermal result for one axis of one sensor.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AxisThermal {
    /// `accel` or `gyro`.
    pub sensor: String,
    /// `x`, `y` or `z`.
    pub axis: String,
    /// Output unit (`m/s^2` or `rad/s`).
    pub unit: String,
    /// Mean output over the recording.
    pub mean: f64,
    /// Linear fit: `[offset at T_ref, bias coefficient per K]`.
    pub linear: PolyFit,
    /// Quadratic fit: `[offset, per K, per K^2]`.
    pub quadratic: PolyFit,
    /// The quadratic term is significant.
    pub quadratic_significant: bool,
    /// Bias temperature coefficient, output unit per K (linear fit).
    pub bias_coeff_per_k: f64,
    /// Its standard error.
    pub bias_coeff_std_per_k: f64,
    /// When the axis has a non-zero input (|mean| > 0.5 g or 0.5 rad/s): the coefficient read as
    /// a scale-factor temperature coefficient, 1/K (a single orientation cannot tell bias and
    /// scale apart; both readings are reported).
    pub scale_coeff_per_k: Option<f64>,
    /// Change the linear (or significant quadratic) fit predicts over the observed range.
    pub predicted_change: f64,
    /// Scatter of a bin mean (the linear fit's residual standard deviation).
    pub bin_noise: f64,
    /// The coefficient is statistically significant.
    pub significant: bool,
    /// The predicted change exceeds `relevance_factor` x `bin_noise`.
    pub relevant: bool,
    /// Significant and relevant: a thermal model is warranted for this axis.
    pub model_warranted: bool,
}

/// How far a warm-up transient and a temperature coefficient can be told apart.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Confounding {
    /// Correlation of the bin temperatures with a warm-up shape `exp(-t / tau)` at the fitted
    /// thermal time constant (|r| near 1: indistinguishable).
    pub temp_vs_warmup_corr: f64,
    /// Correlation of the bin temperatures with time.
    pub temp_vs_time_corr: f64,
    /// Plain-language note.
    pub note: String,
}

/// The full thermal analysis.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ThermalReport {
    /// Input description.
    pub origin: String,
    /// Samples analysed.
    pub n_samples: usize,
    /// Temperature readings.
    pub n_temp_readings: usize,
    /// Recording length, s.
    pub duration_s: f64,
    /// Bin width, s.
    pub bin_s: f64,
    /// Lowest and highest temperature reading, deg C.
    pub temp_range_c: [f64; 2],
    /// Reference temperature of the fits (mean of the bins), deg C.
    pub temp_ref_c: f64,
    /// Warm-up fit of temperature versus time (None when the temperature hardly changes).
    pub warmup: Option<WarmupFit>,
    /// The bins.
    pub bins: Vec<ThermalBin>,
    /// Per axis: accel x, y, z, gyro x, y, z.
    pub axes: Vec<AxisThermal>,
    /// Warm-up versus temperature confounding.
    pub confounding: Confounding,
    /// A thermal model is warranted on at least one axis.
    pub model_recommended: bool,
    /// Plain-language recommendation.
    pub recommendation: String,
}

/// Runs the thermal analysis on a static recording with temperature readings.
pub fn analyze(
    series: &ImuSeries,
    options: &ThermalOptions,
) -> Result<ThermalReport, ThermalError> {
    if series.temp.is_empty() {
        return Err(ThermalError::NoTemperature {
            origin: series.origin.clone(),
        });
    }
    let bins = make_bins(series, options.bin_s);
    const MIN_BINS: usize = 8;
    if bins.len() < MIN_BINS {
        return Err(ThermalError::TooShort {
            origin: series.origin.clone(),
            n_bins: bins.len(),
            bin_s: options.bin_s,
            min_bins: MIN_BINS,
        });
    }
    let (tmin, tmax) = series
        .temp
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &(_, c)| {
            (a.min(c), b.max(c))
        });
    let temps: Vec<f64> = bins.iter().map(|b| b.temp_c).collect();
    let times: Vec<f64> = bins.iter().map(|b| b.t_s).collect();
    let temp_ref_c = mean(&temps);
    let x: Vec<f64> = temps.iter().map(|t| t - temp_ref_c).collect();
    let bin_range = temps.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
        - temps.iter().cloned().fold(f64::INFINITY, f64::min);
    let warmup = if tmax - tmin > 1.0 {
        fit_warmup(&series.temp)
    } else {
        None
    };
    let axes = thermal_axes(&bins, &x, bin_range, options);
    let confounding = confounding(&temps, &times, warmup.as_ref());
    let warranted: Vec<String> = axes
        .iter()
        .filter(|a| a.model_warranted)
        .map(|a| format!("{} {}", a.sensor, a.axis))
        .collect();
    let model_recommended = !warranted.is_empty();
    let recommendation = recommendation(&warranted, bin_range, [tmin, tmax], options);
    Ok(ThermalReport {
        origin: series.origin.clone(),
        n_samples: series.len(),
        n_temp_readings: series.temp.len(),
        duration_s: series.t_s.last().copied().unwrap_or(0.0),
        bin_s: options.bin_s,
        temp_range_c: [tmin, tmax],
        temp_ref_c,
        warmup,
        bins,
        axes,
        confounding,
        model_recommended,
        recommendation,
    })
}

/// The temperature dependence of each axis (accel x, y, z, gyro x, y, z) over the bins, against
/// `x`, the bins' temperatures minus the reference temperature; `bin_range` K between them.
fn thermal_axes(
    bins: &[ThermalBin],
    x: &[f64],
    bin_range: f64,
    options: &ThermalOptions,
) -> Vec<AxisThermal> {
    let mut axes = Vec::with_capacity(6);
    for (sensor, unit, big) in [("accel", "m/s^2", 0.5 * G0), ("gyro", "rad/s", 0.5)] {
        for (i, axis) in ["x", "y", "z"].iter().enumerate() {
            let y: Vec<f64> = bins
                .iter()
                .map(|b| {
                    if sensor == "accel" {
                        b.accel_m_s2[i]
                    } else {
                        b.gyro_rad_s[i]
                    }
                })
                .collect();
            axes.push(axis_thermal(
                sensor, axis, unit, big, x, &y, bin_range, options,
            ));
        }
    }
    axes
}

/// How far the bins' temperatures follow a warm-up transient and time.
fn confounding(temps: &[f64], times: &[f64], warmup: Option<&WarmupFit>) -> Confounding {
    let tau = warmup.map_or(f64::NAN, |w| w.tau_s);
    let shape: Vec<f64> = times.iter().map(|t| (-t / tau).exp()).collect();
    let temp_vs_warmup_corr = if tau.is_finite() {
        correlation(temps, &shape).unwrap_or(f64::NAN)
    } else {
        f64::NAN
    };
    let temp_vs_time_corr = correlation(temps, times).unwrap_or(f64::NAN);
    let note = format!(
        "In a monotonic warm-up the temperature follows time: its correlation with a warm-up \
         transient exp(-t/tau) is {temp_vs_warmup_corr:.3} (with time {temp_vs_time_corr:.3}), so a \
         warm-up transient and a temperature coefficient are confounded here. A temperature \
         cycle (heating and cooling, or a soak at several temperatures) separates them."
    );
    Confounding {
        temp_vs_warmup_corr,
        temp_vs_time_corr,
        note,
    }
}

/// The plain-language recommendation: the axes for which a thermal model is `warranted`, over
/// the temperature range `[tmin, tmax]` deg C (`bin_range` K between the bins).
fn recommendation(
    warranted: &[String],
    bin_range: f64,
    [tmin, tmax]: [f64; 2],
    options: &ThermalOptions,
) -> String {
    if bin_range < 1.0 {
        format!(
            "The temperature varied by only {bin_range:.2} K; the data cannot support or rule \
             out a thermal model."
        )
    } else if !warranted.is_empty() {
        format!(
            "A thermal error model IS warranted between {tmin:.1} and {tmax:.1} deg C for: {}. \
             The coefficients are significant and the change they predict over the range \
             exceeds {} x the scatter of a {} s mean.",
            warranted.join(", "),
            options.relevance_factor,
            options.bin_s
        )
    } else {
        format!(
            "No thermal error model is recommended between {tmin:.1} and {tmax:.1} deg C: no \
             axis shows a temperature dependence that is both significant and larger than {} x \
             the scatter of a {} s mean. There may still be a dependence outside this range.",
            options.relevance_factor, options.bin_s
        )
    }
}

#[allow(clippy::too_many_arguments)]
fn axis_thermal(
    sensor: &str,
    axis: &str,
    unit: &str,
    big_input: f64,
    x: &[f64],
    y: &[f64],
    range_k: f64,
    options: &ThermalOptions,
) -> AxisThermal {
    let linear = poly_fit(x, y, 1);
    let quadratic = poly_fit(x, y, 2);
    let m = mean(y);
    let quadratic_significant = quadratic.p_values[2] < options.significance_p;
    let slope = linear.coefficients[1];
    let (xmin, xmax) = x
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let predicted_change = if quadratic_significant {
        let q = &quadratic.coefficients;
        let f = |v: f64| q[1] * v + q[2] * v * v;
        // Largest excursion of the fitted curve over the range (the vertex may be inside).
        let mut vals = vec![f(xmin), f(xmax)];
        if q[2] != 0.0 {
            let v = -q[1] / (2.0 * q[2]);
            if v > xmin && v < xmax {
                vals.push(f(v));
            }
        }
        let hi = vals.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        let lo = vals.iter().cloned().fold(f64::INFINITY, f64::min);
        hi - lo
    } else {
        (slope * range_k).abs()
    };
    let significant = linear.p_values[1] < options.significance_p || quadratic_significant;
    let bin_noise = linear.residual_std;
    let relevant = predicted_change > options.relevance_factor * bin_noise;
    AxisThermal {
        sensor: sensor.into(),
        axis: axis.into(),
        unit: unit.into(),
        mean: m,
        bias_coeff_per_k: slope,
        bias_coeff_std_per_k: linear.std_errors[1],
        scale_coeff_per_k: (m.abs() > big_input).then(|| slope / m),
        linear,
        quadratic,
        quadratic_significant,
        predicted_change,
        bin_noise,
        significant,
        relevant,
        model_warranted: significant && relevant && range_k >= 1.0,
    }
}

fn make_bins(series: &ImuSeries, bin_s: f64) -> Vec<ThermalBin> {
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
fn fit_warmup(temp: &[(f64, f64)]) -> Option<WarmupFit> {
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
pub(crate) fn poly_fit(x: &[f64], y: &[f64], degree: usize) -> PolyFit {
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

/// Charts like the paper's Figures 4-6: temperature versus time with the warm-up fit, and the
/// binned outputs (offset from their mean) versus time and versus temperature.
pub fn charts(report: &ThermalReport) -> Vec<Chart> {
    let mut out = vec![temperature_chart(report)];
    for (sensor, unit_label, k0, scale) in [
        ("accel", "specific force - mean [mg]", 0usize, 1e3 / G0),
        ("gyro", "rate - mean [deg/h]", 3, 3600.0_f64.to_degrees()),
    ] {
        for (versus, x_label) in [
            ("time", "time [min]"),
            ("temperature", "temperature [deg C]"),
        ] {
            let series = (0..3)
                .map(|i| bin_mean_series(report, sensor, k0 + i, i, scale, versus == "time"))
                .collect();
            out.push(Chart {
                title: format!("{sensor} {}-s means vs {versus}", report.bin_s),
                x_label: x_label.into(),
                y_label: unit_label.into(),
                series,
                ..Chart::default()
            });
        }
    }
    out
}

/// The bins' mean temperature over time, with the warm-up fit if any.
fn temperature_chart(report: &ThermalReport) -> Chart {
    let mut temp_series = vec![Series {
        name: "bin mean temperature".into(),
        points: report
            .bins
            .iter()
            .map(|b| (b.t_s / 60.0, b.temp_c))
            .collect(),
        style: Style::Points,
    }];
    if let Some(w) = &report.warmup {
        let t_end = report.duration_s.max(1.0);
        temp_series.push(Series {
            name: format!("fit, tau = {:.0} s", w.tau_s),
            points: (0..=200)
                .map(|k| {
                    let t = t_end * f64::from(k) / 200.0;
                    (
                        t / 60.0,
                        w.final_c - (w.final_c - w.start_c) * (-t / w.tau_s).exp(),
                    )
                })
                .collect(),
            style: Style::Line,
        });
    }
    Chart {
        title: "Internal temperature".into(),
        x_label: "time [min]".into(),
        y_label: "temperature [deg C]".into(),
        series: temp_series,
        ..Chart::default()
    }
}

/// Axis `i` of `sensor` (report axis `k`): its bin means minus their mean, times `scale`,
/// against time in minutes (a line) or temperature (points).
fn bin_mean_series(
    report: &ThermalReport,
    sensor: &str,
    k: usize,
    i: usize,
    scale: f64,
    by_time: bool,
) -> Series {
    let ax = &report.axes[k];
    Series {
        name: format!("{sensor} {}", ax.axis),
        points: report
            .bins
            .iter()
            .map(|b| {
                let v = if sensor == "accel" {
                    b.accel_m_s2[i]
                } else {
                    b.gyro_rad_s[i]
                };
                let x = if by_time { b.t_s / 60.0 } else { b.temp_c };
                (x, (v - ax.mean) * scale)
            })
            .collect(),
        style: if by_time { Style::Line } else { Style::Points },
    }
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
