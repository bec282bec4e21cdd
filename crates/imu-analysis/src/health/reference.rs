//! What physics says a still window must read, and how far the noise model lets it stray.
//!
//! A still unit's corrected specific force has the magnitude of local gravity and its corrected
//! rate is Earth's rate: in magnitude, and along the up direction (the specific force's) by
//! `Omega sin(latitude)` when the latitude is configured. The heading is unknown, so Earth's
//! horizontal rate is carried as variance ([`unknown_heading_variance_rad2_s2`]). The scatter a
//! window mean may show comes from the calibration's noise tables at the window's length
//! ([`NoiseModel::segment_mean_std`]: white noise averaged, the bias-instability bank's wander,
//! the random walk since the calibration was put in force) plus the calibration's own bias
//! standard errors; without tables it is estimated from the scatter within the first still
//! windows (white noise only), and the report says so.

use imu_model::earth::{earth_rate_split_rad_s, unknown_heading_variance_rad2_s2};
use imu_model::units::EARTH_RATE_RAD_S;
use imu_model::{EffectKind, NoiseModel, ParamRole, TriadModel, Vec3};

use super::still::{ExpectedStill, Moments, StillWindow};

/// Still windows the noise (without tables) or gravity (without a configured value) is learned
/// from before any test is made.
pub const LEARNING_WINDOWS: usize = 3;

/// Noise of one triad: the model and the calibration's bias standard errors.
#[derive(Debug, Clone, PartialEq)]
pub struct TriadNoise {
    /// Allan terms.
    pub model: NoiseModel,
    /// One-sigma bias standard errors of the calibration, per axis (0 when not given).
    pub bias_std_error: [f64; 3],
}

impl TriadNoise {
    /// The noise of `triad` in a calibration; `None` without a `[<triad>.noise]` table.
    pub fn of(triad: &TriadModel) -> Option<TriadNoise> {
        let model = triad.noise.clone()?;
        let mut bias_std_error = [0.0; 3];
        for (id, se) in triad.param_ids().iter().zip(triad.std_errors()) {
            if let (EffectKind::Bias, Some(axis), Some(se)) = (id.effect, id.role.axis(), se)
                && matches!(id.role, ParamRole::Axis(_))
            {
                bias_std_error[axis] = se;
            }
        }
        Some(TriadNoise {
            model,
            bias_std_error,
        })
    }

    /// Variance of one axis of a window mean of `duration_s`, `elapsed_s` after the
    /// calibration was put in force, as (white, coloured): the white part averages down over
    /// windows, the coloured part (bias-instability wander, random walk, the calibration's
    /// own error) is shared by neighbouring windows.
    pub fn window_mean_variance(&self, axis: usize, duration_s: f64, elapsed_s: f64) -> (f64, f64) {
        let white = self.model.white_density[axis].powi(2) / duration_s;
        let total = self.model.segment_mean_std(axis, duration_s, 0.0).powi(2)
            + self.model.random_walk[axis].powi(2) * elapsed_s
            + self.bias_std_error[axis].powi(2);
        (white, (total - white).max(0.0))
    }

    /// What the tables predict for a still unit's block deviation, at any rate.
    pub fn expected_still(&self) -> ExpectedStill {
        ExpectedStill {
            white_var_per_hz: self.model.white_density.iter().map(|d| d * d).sum(),
            quantization_var: self
                .model
                .quantization_lsb
                .iter()
                .map(|q| q * q / 12.0)
                .sum(),
        }
    }
}

/// Where the expected scatter comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum NoiseBasis {
    /// The calibration's noise tables.
    Tables {
        /// Accelerometers.
        accel: TriadNoise,
        /// Gyros.
        gyro: TriadNoise,
    },
    /// No tables: pooled from the scatter within still windows (white noise only).
    Estimated {
        /// Pooled accel moments of the windows so far.
        accel: Moments,
        /// Pooled gyro moments.
        gyro: Moments,
        /// Sum of the windows' sample rates (for the mean rate).
        rate_sum_hz: f64,
        /// Windows pooled.
        windows: usize,
    },
}

impl NoiseBasis {
    /// Adds a still window's scatter to an estimate (tables are left as they are).
    pub fn learn(&mut self, w: &StillWindow) {
        if let NoiseBasis::Estimated {
            accel,
            gyro,
            rate_sum_hz,
            windows,
        } = self
        {
            // Pool variances, not means: each window about its own mean.
            for (pool, m) in [(accel, &w.accel), (gyro, &w.gyro)] {
                pool.n += m.n - 1.0;
                for a in 0..3 {
                    pool.m2[a] += m.m2[a];
                }
            }
            *rate_sum_hz += w.rate_hz();
            *windows += 1;
        }
    }

    /// The noise of both triads, `None` while still estimating.
    pub fn noise(&self) -> Option<(TriadNoise, TriadNoise)> {
        match self {
            NoiseBasis::Tables { accel, gyro } => Some((accel.clone(), gyro.clone())),
            NoiseBasis::Estimated {
                accel,
                gyro,
                rate_sum_hz,
                windows,
            } => (*windows >= LEARNING_WINDOWS).then(|| {
                let rate_hz = rate_sum_hz / *windows as f64;
                let white = |m: &Moments| TriadNoise {
                    model: NoiseModel {
                        white_density: m.m2.map(|s| (s / m.n.max(1.0) / rate_hz).sqrt()),
                        ..NoiseModel::default()
                    },
                    bias_std_error: [0.0; 3],
                };
                (white(accel), white(gyro))
            }),
        }
    }
}

/// The gravity a window's specific force is held against.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GravityReference {
    /// Configured, or normal gravity at the configured latitude and height, m/s^2.
    Known(f64),
    /// Learned from the first still windows: only changes are seen.
    Learned {
        /// Sum of |f| over the learning windows, m/s^2.
        sum_m_s2: f64,
        /// Windows used.
        windows: usize,
    },
}

impl GravityReference {
    /// The reference and the variance of its own estimate relative to one window's (a mean of
    /// `n` windows: `1 / n`); `None` while learning.
    pub fn value(&self) -> Option<(f64, f64)> {
        match *self {
            GravityReference::Known(g) => Some((g, 0.0)),
            GravityReference::Learned { sum_m_s2, windows } => (windows >= LEARNING_WINDOWS)
                .then(|| (sum_m_s2 / windows as f64, 1.0 / windows as f64)),
        }
    }

    /// Adds a window to a reference being learned; false when it is known (or learned).
    pub fn learn(&mut self, w: &StillWindow) -> bool {
        match self {
            GravityReference::Learned { sum_m_s2, windows } if *windows < LEARNING_WINDOWS => {
                *sum_m_s2 += w.mean_accel().norm();
                *windows += 1;
                true
            }
            _ => false,
        }
    }
}

/// One still window held against physics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WindowResiduals {
    /// Up in the sensor frame (the specific force's direction).
    pub up: Vec3,
    /// |f| - g, m/s^2.
    pub accel_residual_m_s2: f64,
    /// Its variance, (m/s^2)^2.
    pub accel_var: f64,
    /// The white part of that variance (the rest is shared by neighbouring windows).
    pub accel_white_var: f64,
    /// Mean rate minus Earth's rate as far as it is known (its vertical part with a latitude),
    /// rad/s.
    pub gyro_residual_rad_s: Vec3,
    /// Its variance per axis (noise plus the unknown part of Earth's rate).
    pub gyro_var: [f64; 3],
    /// The white part of that variance.
    pub gyro_white_var: [f64; 3],
    /// |mean rate| - |Earth rate|, rad/s.
    pub gyro_magnitude_residual_rad_s: f64,
    /// Mean rate along up - Earth rate's vertical part, rad/s (NaN without a latitude).
    pub gyro_vertical_residual_rad_s: f64,
}

/// Holds `w` against gravity `g` (with the variance of its estimate relative to a window's) and Earth's rate at
/// `latitude_deg`, with the noise of both triads, `elapsed_s` after the calibration.
pub fn residuals(
    w: &StillWindow,
    (g, g_relative_var): (f64, f64),
    latitude_deg: Option<f64>,
    (accel, gyro): (&TriadNoise, &TriadNoise),
    elapsed_s: f64,
) -> WindowResiduals {
    let f = w.mean_accel();
    let up = f / f.norm().max(1e-12);
    let t_s = w.duration_s();
    let (mut accel_white_var, mut accel_var) = (0.0, 0.0);
    for i in 0..3 {
        let (white, coloured) = accel.window_mean_variance(i, t_s, elapsed_s);
        accel_white_var += up[i].powi(2) * white;
        accel_var += up[i].powi(2) * (white + coloured);
    }
    // A learned gravity is the mean of a few windows: its error is shared by every window.
    accel_var += accel_var * g_relative_var;
    let omega = w.mean_gyro();
    let vertical = latitude_deg.map(|lat| earth_rate_split_rad_s(lat).0);
    let gyro_residual_rad_s = omega - up * vertical.unwrap_or(0.0);
    let gyro_white_var = std::array::from_fn(|i| gyro.window_mean_variance(i, t_s, elapsed_s).0);
    let gyro_var = std::array::from_fn(|i| {
        let (white, coloured) = gyro.window_mean_variance(i, t_s, elapsed_s);
        white + coloured + unknown_heading_variance_rad2_s2(latitude_deg, up[i])
    });
    WindowResiduals {
        up,
        accel_residual_m_s2: f.norm() - g,
        accel_var,
        accel_white_var,
        gyro_residual_rad_s,
        gyro_var,
        gyro_white_var,
        gyro_magnitude_residual_rad_s: omega.norm() - EARTH_RATE_RAD_S,
        gyro_vertical_residual_rad_s: vertical.map_or(f64::NAN, |v| omega.dot(&up) - v),
    }
}
