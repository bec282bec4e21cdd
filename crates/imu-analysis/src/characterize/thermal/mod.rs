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
use serde::Serialize;

use crate::input::ImuSeries;

mod charts;
mod fit;
mod verdict;

pub use charts::charts;
use fit::{fit_warmup, make_bins, poly_fit};
pub use verdict::{Recommendation, ThermalVerdict};

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
    /// Two-sided p-value below which the linear coefficient is called significant (the
    /// quadratic term is tested at half of it).
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
    /// The coefficient (linear, or the quadratic term) is significant by the test that accounts
    /// for coloured noise.
    pub significant: bool,
    /// The predicted change exceeds `relevance_factor` x `bin_noise`.
    pub relevant: bool,
    /// Significant and relevant: a thermal model is warranted for this axis (the verdict is
    /// [`ThermalVerdict::Warranted`]).
    pub model_warranted: bool,
    /// What this recording says about the axis: warranted, negligible, or not resolvable with an
    /// upper bound.
    pub verdict: ThermalVerdict,
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
    /// Whether a thermal model is warranted (its `Display` is the plain-language
    /// recommendation); JSON `recommendation` and `recommendation_codes`.
    #[serde(flatten)]
    pub recommendation: Recommendation,
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
    let model_recommended = axes.iter().any(|a| a.model_warranted);
    let recommendation = Recommendation {
        axes: axes.clone(),
        range_k: bin_range,
        temp_range_c: [tmin, tmax],
        options: options.clone(),
    };
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
    // The quadratic term is a second look at the same axis: tested at half the level, so an
    // axis without any dependence is called significant with probability at most 1.5 x
    // `significance_p` (at the full level, curvature of the drift alone passed too often).
    let quadratic_significant = quadratic.p_values[2] < 0.5 * options.significance_p;
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
    let mut a = AxisThermal {
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
        model_warranted: false,
        verdict: ThermalVerdict::NoTemperatureRange,
    };
    a.verdict = ThermalVerdict::decide(&a, range_k, options);
    a.model_warranted = a.verdict == ThermalVerdict::Warranted;
    a
}
