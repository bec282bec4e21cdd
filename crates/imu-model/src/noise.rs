//! Stochastic sensor noise: the per-triad description stored in calibration files (IEEE
//! Std 952/1293 Allan-variance terms) and a deterministic, seeded generator for the simulator.
//!
//! Noise is not part of the deterministic model and is never inverted.

use crate::Vec3;
use crate::effect::{AXES, InvalidParam, check_finite};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};

/// Ratio of the flat Allan-deviation floor to the bias instability B: sqrt(2 ln 2 / pi) ~ 0.664.
pub const BIAS_INSTABILITY_ADEV_FACTOR: f64 = 0.664_282_470_267_960_1;

/// Default longest correlation time of the flicker (bias-instability) approximation, seconds.
pub const DEFAULT_BIAS_INSTABILITY_TAU_MAX_S: f64 = 1000.0;

fn default_tau_max_s() -> f64 {
    DEFAULT_BIAS_INSTABILITY_TAU_MAX_S
}

/// Noise of one triad, per axis; every field is optional in TOML and defaults to zero.
///
/// TOML `[<triad>.noise]` (U = the triad's unit):
/// - `white-density = [x, y, z]`: U/sqrt(Hz), angle/velocity random walk N (ADEV = N/sqrt(tau));
/// - `bias-instability = [x, y, z]`: U, the IEEE B (flat Allan floor = 0.664 B);
/// - `bias-instability-tau-max-s = 1000.0`: s, longest correlation time of the flicker model;
/// - `random-walk = [x, y, z]`: U/sqrt(s) = U*sqrt(Hz), rate/acceleration random walk K
///   (ADEV = K sqrt(tau/3));
/// - `quantization-lsb = [x, y, z]`: U, the device's output step (informational; the device
///   model quantizes, [`NoiseGenerator`] does not).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct NoiseModel {
    /// White-noise density N per axis, U/sqrt(Hz).
    #[serde(default)]
    pub white_density: [f64; 3],
    /// Bias instability B per axis, U.
    #[serde(default)]
    pub bias_instability: [f64; 3],
    /// Longest correlation time of the Gauss-Markov bank approximating flicker noise, s.
    #[serde(default = "default_tau_max_s")]
    pub bias_instability_tau_max_s: f64,
    /// Random-walk coefficient K per axis, U/sqrt(s).
    #[serde(default)]
    pub random_walk: [f64; 3],
    /// Output quantization step per axis, U (0 = not quantized).
    #[serde(default)]
    pub quantization_lsb: [f64; 3],
}

impl Default for NoiseModel {
    fn default() -> Self {
        NoiseModel {
            white_density: [0.0; 3],
            bias_instability: [0.0; 3],
            bias_instability_tau_max_s: DEFAULT_BIAS_INSTABILITY_TAU_MAX_S,
            random_walk: [0.0; 3],
            quantization_lsb: [0.0; 3],
        }
    }
}

impl NoiseModel {
    /// Theoretical Allan deviation per axis at averaging time `tau_s` from N, B and K:
    /// sigma^2 = N^2/tau + (2 ln2/pi) B^2 + K^2 tau/3. B's term is the ideal flicker floor (the
    /// generator's approximation rolls off beyond `bias-instability-tau-max-s`). Quantization is
    /// left out: its contribution depends on the sample rate.
    pub fn allan_deviation(&self, tau_s: f64) -> Vec3 {
        Vec3::from_fn(|i, _| {
            let n = self.white_density[i];
            let b = self.bias_instability[i] * BIAS_INSTABILITY_ADEV_FACTOR;
            let k = self.random_walk[i];
            (n * n / tau_s + b * b + k * k * tau_s / 3.0).sqrt()
        })
    }

    /// Expected standard deviation of one axis of a segment mean about the truth: white noise
    /// averaged over `segment_s`, the bias-instability bank's wander (each Gauss-Markov process
    /// shrunk by averaging over the segment) and the random walk over a recording of `span_s`
    /// (its deviation from its mean, `K^2 T / 3`).
    pub fn segment_mean_std(&self, axis: usize, segment_s: f64, span_s: f64) -> f64 {
        let white = self.white_density[axis].powi(2) / segment_s;
        let bank: f64 = self
            .flicker_bank(0.01)
            .iter()
            .map(|&(t_s, unit)| {
                let x = segment_s / t_s;
                let shrink = 2.0 * (x + (-x).exp_m1()) / (x * x);
                self.bias_instability[axis].powi(2) * unit * shrink
            })
            .sum();
        let walk = self.random_walk[axis].powi(2) * span_s / 3.0;
        (white + bank + walk).sqrt()
    }

    /// Covariances of one axis's noise averaged over each of `windows` `(start_s, end_s)` of one
    /// recording (times from the recording's start, when the random walk starts; windows that do
    /// not overlap), as an `n x n` matrix: white noise within a window only, each Gauss-Markov
    /// process of the bias-instability bank (`flicker_bank(dt_s)`, samples `dt_s` apart) by its
    /// correlation over the windows' separation, and the random walk `K^2 min(t, s)` averaged
    /// over both. What a fit over window means (a multi-position fit against gravity) needs to
    /// weight them: the bias wander makes nearby windows agree and distant ones drift apart.
    pub fn window_means_covariance(
        &self,
        axis: usize,
        windows: &[(f64, f64)],
        dt_s: f64,
    ) -> nalgebra::DMatrix<f64> {
        let bank = if self.bias_instability[axis] == 0.0 {
            Vec::new()
        } else {
            self.flicker_bank(dt_s)
        };
        let b2 = self.bias_instability[axis].powi(2);
        let one = |a: (f64, f64), b: (f64, f64), same: bool| {
            let (a, b) = if a.0 <= b.0 { (a, b) } else { (b, a) };
            let (ta, tb) = ((a.1 - a.0).max(dt_s), (b.1 - b.0).max(dt_s));
            let white = if same {
                self.white_density[axis].powi(2) / ta
            } else {
                0.0
            };
            let wander: f64 = bank
                .iter()
                .map(|&(tau, unit)| {
                    // (1/(T_a T_b)) times the double integral of exp(-|t - s| / tau).
                    let g = if same {
                        let x = ta / tau;
                        2.0 * (x + (-x).exp_m1()) / (x * x)
                    } else {
                        let gap = (b.0 - a.1).max(0.0);
                        tau * tau
                            * (-(-ta / tau).exp_m1())
                            * (-(-tb / tau).exp_m1())
                            * (-gap / tau).exp()
                            / (ta * tb)
                    };
                    b2 * unit * g
                })
                .sum();
            // (1/(T_a T_b)) times the double integral of min(t, s): a's mean time when a ends
            // before b starts, start + T/3 for one window.
            let walk_time = if same {
                a.0 + ta / 3.0
            } else {
                0.5 * (a.0 + a.1)
            };
            white + wander + self.random_walk[axis].powi(2) * walk_time.max(0.0)
        };
        let n = windows.len();
        let mut out = nalgebra::DMatrix::zeros(n, n);
        for i in 0..n {
            for j in i..n {
                let c = one(windows[i], windows[j], i == j);
                out[(i, j)] = c;
                out[(j, i)] = c;
            }
        }
        out
    }

    /// The bank of first-order Gauss-Markov processes that stands for the bias instability at
    /// sample period `dt_s`, as `(correlation time s, variance per unit B^2)` per process: what
    /// [`NoiseGenerator`] draws (each process with variance `B^2` times its unit variance), and
    /// what a fit needs to know how the bias wanders between segment means.
    pub fn flicker_bank(&self, dt_s: f64) -> Vec<(f64, f64)> {
        let tau_max_s = self.bias_instability_tau_max_s;
        let times = flicker_correlation_times(dt_s, tau_max_s);
        let unit_var = flicker_unit_variance(dt_s, &times, tau_max_s);
        times.into_iter().map(|t| (t, unit_var)).collect()
    }

    /// Round each axis to its quantization step (axes with a zero step pass through).
    pub fn quantize(&self, v: Vec3) -> Vec3 {
        Vec3::from_fn(|i, _| {
            let lsb = self.quantization_lsb[i];
            if lsb > 0.0 {
                (v[i] / lsb).round() * lsb
            } else {
                v[i]
            }
        })
    }

    /// Check that every term is finite and non-negative and the flicker time constant positive.
    pub fn validate(&self) -> Result<(), InvalidParam> {
        for (key, values) in [
            ("white-density", &self.white_density),
            ("bias-instability", &self.bias_instability),
            ("random-walk", &self.random_walk),
            ("quantization-lsb", &self.quantization_lsb),
        ] {
            check_finite(key, values)?;
            if let Some(i) = values.iter().position(|v| *v < 0.0) {
                return Err(InvalidParam::new(
                    format!("{key}[{i}]"),
                    format!(
                        "{} on axis {} is negative; noise magnitudes are >= 0",
                        values[i], AXES[i]
                    ),
                ));
            }
        }
        let t = self.bias_instability_tau_max_s;
        if !(t.is_finite() && t > 0.0) {
            return Err(InvalidParam::new(
                "bias-instability-tau-max-s",
                format!("{t} s must be a positive number of seconds"),
            ));
        }
        Ok(())
    }
}

/// Allan variance of a continuous first-order Gauss-Markov process with variance `var` and
/// correlation time `t_s`, at averaging time `tau_s`:
/// 2 var T/tau [1 - T/(2 tau) (3 - 4 e^(-tau/T) + e^(-2 tau/T))].
pub(crate) fn gauss_markov_allan_variance(var: f64, t_s: f64, tau_s: f64) -> f64 {
    let x = tau_s / t_s;
    if x < 1e-4 {
        // Series: the closed form cancels catastrophically for tau << T.
        return 2.0 * var * (x / 3.0 - x * x / 4.0);
    }
    let bracket = 1.0 - (-4.0 * (-x).exp_m1() + (-2.0 * x).exp_m1()) / (2.0 * x);
    2.0 * var / x * bracket
}

/// Correlation times of the flicker bank: two per decade, log-spaced from one sample period up
/// to `tau_max_s` (a single process if that span is empty).
pub(crate) fn flicker_correlation_times(dt_s: f64, tau_max_s: f64) -> Vec<f64> {
    if tau_max_s <= dt_s {
        return vec![tau_max_s.max(dt_s)];
    }
    let decades = (tau_max_s / dt_s).log10();
    let n = (2.0 * decades).ceil() as usize + 1;
    (0..n)
        .map(|j| dt_s * (tau_max_s / dt_s).powf(j as f64 / (n - 1) as f64))
        .collect()
}

/// Variance of each bank process per unit B^2 such that the bank's Allan deviation is
/// 0.664 B on its plateau. The plateau is taken as [100 dt, tau_max/10] (where neither the
/// missing faster nor the missing slower processes matter); the scale matches the mean Allan
/// variance over 25 log-spaced points there.
pub(crate) fn flicker_unit_variance(dt_s: f64, correlation_times_s: &[f64], tau_max_s: f64) -> f64 {
    let (a, b) = (100.0 * dt_s, tau_max_s / 10.0);
    let taus: Vec<f64> = if a < b {
        (0..25).map(|j| a * (b / a).powf(j as f64 / 24.0)).collect()
    } else {
        vec![(dt_s * tau_max_s).sqrt()]
    };
    let mean_unit_avar = taus
        .iter()
        .map(|&tau| {
            correlation_times_s
                .iter()
                .map(|&t| gauss_markov_allan_variance(1.0, t, tau))
                .sum::<f64>()
        })
        .sum::<f64>()
        / taus.len() as f64;
    BIAS_INSTABILITY_ADEV_FACTOR * BIAS_INSTABILITY_ADEV_FACTOR / mean_unit_avar
}

#[derive(Clone, Debug)]
struct GaussMarkov {
    /// exp(-dt/T).
    phi: f64,
    /// Standard deviation of the driving noise per step, sqrt(1 - phi^2) sigma.
    drive: f64,
    value: f64,
}

#[derive(Clone, Debug)]
struct AxisNoise {
    white_sigma: f64,
    white_rng: ChaCha8Rng,
    rw_step_sigma: f64,
    rw_value: f64,
    rw_rng: ChaCha8Rng,
    bank: Vec<GaussMarkov>,
    bank_rng: ChaCha8Rng,
}

impl AxisNoise {
    fn next(&mut self) -> f64 {
        let mut v = 0.0;
        // Zero terms draw nothing, and each term has its own stream: enabling one term never
        // changes the sequence of another.
        if self.white_sigma > 0.0 {
            let z: f64 = self.white_rng.sample(StandardNormal);
            v += self.white_sigma * z;
        }
        if self.rw_step_sigma > 0.0 {
            let z: f64 = self.rw_rng.sample(StandardNormal);
            self.rw_value += self.rw_step_sigma * z;
            v += self.rw_value;
        }
        for p in &mut self.bank {
            let z: f64 = self.bank_rng.sample(StandardNormal);
            p.value = p.phi * p.value + p.drive * z;
            v += p.value;
        }
        v
    }
}

/// Deterministic noise source for one triad: `next()` returns the additive noise of one sample.
///
/// - white: N(0, N sqrt(rate)) per sample;
/// - random walk: integrated white noise with step std K/sqrt(rate), starting at 0;
/// - bias instability: a bank of first-order Gauss-Markov processes with log-spaced correlation
///   times (two per decade, from 1/rate to `bias-instability-tau-max-s`), equal variances scaled
///   so that the Allan deviation plateau is 0.664 B (equal-variance Lorentzians spaced evenly in
///   log-frequency sum to a 1/f spectrum). Each process starts in its stationary distribution.
///
/// Uses `ChaCha8Rng` with one stream per (axis, term), so a seed reproduces the same sequence on
/// every platform and `rand` version that keeps ChaCha8's definition.
#[derive(Clone, Debug)]
pub struct NoiseGenerator {
    axes: Vec<AxisNoise>,
}

impl NoiseGenerator {
    /// Build a generator for `model` at `sample_rate_hz` (> 0), seeded with `seed`.
    pub fn new(model: &NoiseModel, sample_rate_hz: f64, seed: u64) -> Self {
        debug_assert!(sample_rate_hz > 0.0, "sample rate must be positive");
        let dt_s = 1.0 / sample_rate_hz;
        let stream = |id: u64| {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            rng.set_stream(id);
            rng
        };
        let times = flicker_correlation_times(dt_s, model.bias_instability_tau_max_s);
        let unit_var = flicker_unit_variance(dt_s, &times, model.bias_instability_tau_max_s);
        let axes = (0..3)
            .map(|i| {
                let base = 3 * i as u64;
                let mut bank_rng = stream(base + 2);
                let b = model.bias_instability[i];
                let bank = if b > 0.0 {
                    let sigma = b * unit_var.sqrt();
                    times
                        .iter()
                        .map(|&t| {
                            let phi = (-dt_s / t).exp();
                            let z: f64 = bank_rng.sample(StandardNormal);
                            GaussMarkov {
                                phi,
                                drive: sigma * (1.0 - phi * phi).sqrt(),
                                value: sigma * z,
                            }
                        })
                        .collect()
                } else {
                    Vec::new()
                };
                AxisNoise {
                    white_sigma: model.white_density[i] * sample_rate_hz.sqrt(),
                    white_rng: stream(base),
                    rw_step_sigma: model.random_walk[i] * dt_s.sqrt(),
                    rw_value: 0.0,
                    rw_rng: stream(base + 1),
                    bank,
                    bank_rng,
                }
            })
            .collect();
        NoiseGenerator { axes }
    }

    /// The noise to add to the next sample, in the triad's unit.
    #[allow(clippy::should_implement_trait)] // an infinite stream; Iterator adds nothing here
    pub fn next(&mut self) -> Vec3 {
        Vec3::new(
            self.axes[0].next(),
            self.axes[1].next(),
            self.axes[2].next(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn window_means_covariance_is_the_generator_s() {
        // Monte Carlo over seeds of the generator: variance of one window's mean and covariance
        // between windows near and far, against the formula, within 4 standard errors of the
        // estimate (var(x y) ~ var x var y + cov^2 over runs).
        let model = NoiseModel {
            white_density: [0.3, 0.0, 0.0],
            bias_instability: [0.5, 0.0, 0.0],
            bias_instability_tau_max_s: 100.0,
            random_walk: [0.05, 0.0, 0.0],
            quantization_lsb: [0.0; 3],
        };
        let (rate_hz, span_s, runs) = (10.0, 200.0, 3000);
        let dt = 1.0 / rate_hz;
        let windows = [(10.0, 25.0), (30.0, 50.0), (150.0, 190.0)];
        let mut means = vec![[0.0; 3]; runs];
        for (run, m) in means.iter_mut().enumerate() {
            let mut g = NoiseGenerator::new(&model, rate_hz, run as u64);
            let mut sums = [(0.0, 0usize); 3];
            for k in 0..(span_s * rate_hz) as usize {
                let t = k as f64 * dt;
                let x = g.next()[0];
                for (w, s) in windows.iter().zip(sums.iter_mut()) {
                    if t >= w.0 && t < w.1 {
                        *s = (s.0 + x, s.1 + 1);
                    }
                }
            }
            *m = sums.map(|(s, n)| s / n as f64);
        }
        let n = runs as f64;
        let model_cov = model.window_means_covariance(0, &windows, dt);
        for i in 0..3 {
            for j in i..3 {
                let mean = |k: usize| means.iter().map(|m| m[k]).sum::<f64>() / n;
                let (mi, mj) = (mean(i), mean(j));
                let cov = means.iter().map(|m| (m[i] - mi) * (m[j] - mj)).sum::<f64>() / (n - 1.0);
                let want = model_cov[(i, j)];
                let (vi, vj) = (model_cov[(i, i)], model_cov[(j, j)]);
                let se = ((vi * vj + want * want) / n).sqrt();
                assert!(
                    (cov - want).abs() < 4.0 * se,
                    "windows {i}, {j}: {cov:.4e} vs {want:.4e} (se {se:.1e})"
                );
            }
        }
    }

    #[test]
    fn bank_is_two_per_decade_from_one_sample_to_tau_max() {
        let t = flicker_correlation_times(0.01, 1000.0);
        assert_eq!(t.len(), 11);
        assert!((t[0] - 0.01).abs() < 1e-15 && (t[10] - 1000.0).abs() < 1e-9);
        assert!((t[1] / t[0] - 10f64.sqrt()).abs() < 1e-12);
        assert_eq!(flicker_correlation_times(0.01, 0.001), vec![0.01]);
    }

    #[test]
    fn gauss_markov_allan_variance_has_the_textbook_limits() {
        // tau >> T: white, 2 var T / tau.  tau << T: random walk, 2 var tau / (3 T).
        let (var, t) = (2.0, 5.0);
        let long = gauss_markov_allan_variance(var, t, 5e4);
        assert!((long / (2.0 * var * t / 5e4) - 1.0).abs() < 1e-3);
        for tau in [1e-3, 1e-5] {
            let short = gauss_markov_allan_variance(var, t, tau);
            assert!((short / (2.0 * var * tau / (3.0 * t)) - 1.0).abs() < 1e-3);
        }
        // Just above the switch to the series, the closed form agrees with the series.
        let x = 1.01e-4;
        let closed = gauss_markov_allan_variance(var, 1.0, x);
        let series = 2.0 * var * (x / 3.0 - x * x / 4.0);
        assert!((closed / series - 1.0).abs() < 1e-6, "{closed} vs {series}");
    }

    #[test]
    fn bank_plateau_is_flat_at_0_664_b() {
        // Analytic Allan deviation of the scaled bank over the plateau band stays within 5 %.
        for (rate_hz, tau_max_s) in [(100.0, 1000.0), (350.0, 300.0), (10.0, 5000.0)] {
            let dt = 1.0 / rate_hz;
            let times = flicker_correlation_times(dt, tau_max_s);
            let var = flicker_unit_variance(dt, &times, tau_max_s);
            let (a, b) = (100.0 * dt, tau_max_s / 10.0);
            for j in 0..=20 {
                let tau = a * (b / a).powf(f64::from(j) / 20.0);
                let adev = times
                    .iter()
                    .map(|&t| gauss_markov_allan_variance(var, t, tau))
                    .sum::<f64>()
                    .sqrt();
                let ratio = adev / BIAS_INSTABILITY_ADEV_FACTOR;
                assert!(
                    (ratio - 1.0).abs() < 0.05,
                    "rate {rate_hz}, tau {tau}: {ratio}"
                );
            }
        }
    }
}
