//! IEEE Std 952/1293 noise terms (Q, N, B, K, R) from an Allan deviation curve: a weighted,
//! non-negative least-squares fit to the Allan VARIANCE, plus the classic slope read-offs.
//!
//! Model (U = unit of the rate data, e.g. rad/s or m/s^2):
//! `sigma^2(tau) = 3 Q^2/tau^2 + N^2/tau + (2 ln 2/pi) B^2 + K^2 tau/3 + R^2 tau^2/2`, with
//! - Q quantization, U*s;
//! - N angle/velocity random walk (white rate noise), continuous density U/sqrt(Hz) = U*sqrt(s);
//!   the discrete per-sample standard deviation at rate f is N*sqrt(f);
//! - B bias instability, U (the flat ADEV floor is 0.664 B, NOT B);
//! - K rate/acceleration random walk, U*sqrt(Hz) = U/sqrt(s); the per-sample random-walk step
//!   at rate f is K/sqrt(f);
//! - R rate ramp, U/s.
//!
//! The fit is linear in the squared coefficients c = (Q^2, N^2, B^2, K^2, R^2), constrained to
//! c >= 0. With five unknowns, non-negative least squares is solved exactly by trying every one
//! of the 32 passive sets and keeping the best feasible unconstrained solution (the NNLS optimum
//! is the unconstrained optimum on its passive set). Weights are the inverse variance of each
//! Allan-variance estimate, var(sigma^2) = sigma^4 (2 / EDF + 0.05^2) (the second term is a
//! model-error floor, see [`MODEL_ERROR_FLOOR`]); the first pass takes sigma^2 from the data,
//! later passes (iteratively reweighted, 4 in all) from the fitted model, because weights from
//! the noisy data themselves favour points that happen to fall low. Term uncertainties
//! propagate the inverse normal matrix (on the passive set; for a term fitted as zero, the
//! 1-sigma upper bound from the full five-term covariance). Adjacent OADEV points are
//! correlated, so these uncertainties are somewhat optimistic.

use serde::Serialize;
use thiserror::Error;

use nalgebra::{DMatrix, DVector};

use crate::allan::{DevCurve, DevPoint, Kind};

/// sqrt(2 ln 2 / pi): ADEV floor per unit bias instability.
pub const BIAS_INSTABILITY_FACTOR: f64 = 0.664_282_470_267_960_1;

/// Relative standard deviation added in quadrature to each Allan-variance point's statistical
/// one (2/EDF): short taus have millions of EDF, and without a floor the tiny deviations of real
/// (or simulated) spectra from the idealized power laws there would outweigh every long-tau
/// point, where K and R live.
pub const MODEL_ERROR_FLOOR: f64 = 0.10;

/// Errors of the noise-term fit.
#[derive(Debug, Error, PartialEq)]
pub enum NoiseError {
    /// Not enough usable points (positive deviation, EDF > 0).
    #[error("too few Allan deviation points to fit noise terms: {n_points} usable, need 3")]
    TooFewPoints {
        /// Usable points.
        n_points: usize,
    },
    /// The curve is not an Allan (ADEV/OADEV) curve.
    #[error("noise terms are defined on the Allan variance, got a {kind:?} curve")]
    WrongKind {
        /// The curve's kind.
        kind: Kind,
    },
}

/// One fitted term, in the continuous-time unit stated on the field that holds it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Term {
    /// Estimate (>= 0).
    pub value: f64,
    /// 1-sigma uncertainty (for a zero estimate: a 1-sigma upper bound).
    pub sigma: f64,
    /// `value > 2 sigma`: the data need this term.
    pub significant: bool,
}

/// The five IEEE terms fitted to an Allan variance, in units of U (the rate unit).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct NoiseTerms {
    /// Quantization noise Q, U*s.
    pub q_u_s: Term,
    /// White rate noise (angle/velocity random walk) N, U/sqrt(Hz).
    pub n_u_per_sqrt_hz: Term,
    /// Bias instability B, U.
    pub b_u: Term,
    /// Rate/acceleration random walk K, U*sqrt(Hz) (= U/sqrt(s)).
    pub k_u_sqrt_hz: Term,
    /// Rate ramp R, U/s.
    pub r_u_per_s: Term,
    /// Weighted residual sum of squares per degree of freedom (~1 for a good fit).
    pub chi2_per_dof: f64,
    /// Points used.
    pub n_points: usize,
}

impl NoiseTerms {
    /// The model's Allan deviation at `tau_s`, in U.
    pub fn adev(&self, tau_s: f64) -> f64 {
        let c = self.coefficients();
        basis(tau_s)
            .iter()
            .zip(c)
            .map(|(a, c)| a * c)
            .sum::<f64>()
            .sqrt()
    }

    /// Allan deviation of each term alone at `tau_s` (Q, N, B, K, R), in U.
    pub fn term_adevs(&self, tau_s: f64) -> [f64; 5] {
        let c = self.coefficients();
        let a = basis(tau_s);
        std::array::from_fn(|i| (a[i] * c[i]).sqrt())
    }

    fn coefficients(&self) -> [f64; 5] {
        [
            self.q_u_s.value,
            self.n_u_per_sqrt_hz.value,
            self.b_u.value,
            self.k_u_sqrt_hz.value,
            self.r_u_per_s.value,
        ]
        .map(|v| v * v)
    }

    /// Discrete per-sample standard deviation of the white noise at `rate_hz`: N sqrt(rate), U.
    pub fn white_per_sample_u(&self, rate_hz: f64) -> f64 {
        self.n_u_per_sqrt_hz.value * rate_hz.sqrt()
    }

    /// Discrete per-sample random-walk step at `rate_hz`: K / sqrt(rate), U.
    pub fn random_walk_step_per_sample_u(&self, rate_hz: f64) -> f64 {
        self.k_u_sqrt_hz.value / rate_hz.sqrt()
    }
}

/// Regressors of the Allan variance model for (Q^2, N^2, B^2, K^2, R^2) at `tau_s`.
fn basis(tau_s: f64) -> [f64; 5] {
    [
        3.0 / (tau_s * tau_s),
        1.0 / tau_s,
        BIAS_INSTABILITY_FACTOR * BIAS_INSTABILITY_FACTOR,
        tau_s / 3.0,
        tau_s * tau_s / 2.0,
    ]
}

/// Solves the normal equations `a x = b` of one passive set (columns scaled to unit norm, so
/// the absolute pivot threshold is relative); returns the inverse as well. `None` if singular.
fn solve(a: &DMatrix<f64>, b: &DVector<f64>) -> Option<(DVector<f64>, DMatrix<f64>)> {
    crate::linear::solve_with_inverse(a, b, 1e-13)
}

/// Fits the five IEEE terms to an ADEV/OADEV curve (see the module docs). The curve's EDF
/// weights the points; the units of the result are those of the rate data.
pub fn fit_terms(curve: &DevCurve) -> Result<NoiseTerms, NoiseError> {
    if !matches!(curve.kind, Kind::Adev | Kind::Oadev) {
        return Err(NoiseError::WrongKind { kind: curve.kind });
    }
    let pts: Vec<_> = curve
        .points
        .iter()
        .filter(|p| p.dev > 0.0 && p.dev.is_finite() && p.edf > 0.0)
        .collect();
    if pts.len() < 3 {
        return Err(NoiseError::TooFewPoints {
            n_points: pts.len(),
        });
    }
    // Iteratively reweighted: the first pass weights by the measured variance, later passes by
    // the fitted model's (measured-variance weights favour points that happen to fall low).
    let mut reference: Option<[f64; 5]> = None;
    let mut result = None;
    for _ in 0..IRLS_PASSES {
        let (rss, c, set, inv, scale) = nnls_pass(&pts, reference.as_ref())?;
        reference = Some(c);
        result = Some((rss, c, set, inv, scale));
    }
    let (rss, c, set, inv, scale) = result.expect("IRLS_PASSES > 0");
    let rows = weighted_rows(&pts, Some(&c));
    let normal = |set: &[usize]| normal_equations(&rows, &scale, set);
    let full = solve(&normal(&[0, 1, 2, 3, 4]).0, &DVector::zeros(5)).map(|(_, inv)| inv);
    let term = |j: usize| -> Term {
        let var_c = if let Some(k) = set.iter().position(|&s| s == j) {
            inv[(k, k)] / (scale[j] * scale[j])
        } else if let Some(f) = &full {
            f[(j, j)] / (scale[j] * scale[j])
        } else {
            f64::NAN
        };
        let sd_c = var_c.max(0.0).sqrt();
        let value = c[j].sqrt();
        let sigma = if c[j] > 0.0 {
            sd_c / (2.0 * value)
        } else {
            sd_c.sqrt()
        };
        Term {
            value,
            sigma,
            significant: value > 2.0 * sigma,
        }
    };
    let dof = pts.len().saturating_sub(set.len()).max(1);
    Ok(NoiseTerms {
        q_u_s: term(0),
        n_u_per_sqrt_hz: term(1),
        b_u: term(2),
        k_u_sqrt_hz: term(3),
        r_u_per_s: term(4),
        chi2_per_dof: rss / dof as f64,
        n_points: pts.len(),
    })
}

/// The classic graphical read-offs, for comparison with the fit (units of U as in
/// [`NoiseTerms`]); `None` where the curve has no segment of the needed slope.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SlopeReadoffs {
    /// N: sigma(tau) sqrt(tau) at the point whose local slope is nearest -1/2 (the -1/2 line
    /// through it, read at tau = 1 s), U/sqrt(Hz).
    pub n_u_per_sqrt_hz: Option<f64>,
    /// B: minimum ADEV / 0.664, U.
    pub b_u: Option<f64>,
    /// K: sigma(tau) sqrt(3/tau) at the point whose local slope is nearest +1/2 (the +1/2 line
    /// read at tau = 3 s), U*sqrt(Hz).
    pub k_u_sqrt_hz: Option<f64>,
}

/// Passes of the iteratively reweighted fit.
const IRLS_PASSES: usize = 4;

fn model_var(c: &[f64; 5], tau_s: f64) -> f64 {
    basis(tau_s).iter().zip(c).map(|(a, c)| a * c).sum()
}

type Rows = Vec<([f64; 5], f64)>;

fn weighted_rows(pts: &[&DevPoint], reference: Option<&[f64; 5]>) -> Rows {
    pts.iter()
        .map(|p| {
            let avar = p.dev * p.dev;
            let ref_var = reference.map_or(avar, |c| model_var(c, p.tau_s).max(0.1 * avar));
            let rel_var = 2.0 / p.edf + MODEL_ERROR_FLOOR * MODEL_ERROR_FLOOR;
            let sw = 1.0 / (rel_var.sqrt() * ref_var);
            (basis(p.tau_s).map(|a| a * sw), avar * sw)
        })
        .collect()
}

fn normal_equations(rows: &Rows, scale: &[f64; 5], set: &[usize]) -> (DMatrix<f64>, DVector<f64>) {
    let n = set.len();
    let ata = DMatrix::from_fn(n, n, |r, c| {
        let (i, j) = (set[r], set[c]);
        rows.iter()
            .map(|(a, _)| a[i] / scale[i] * a[j] / scale[j])
            .sum()
    });
    let atb = DVector::from_fn(n, |r, _| {
        let i = set[r];
        rows.iter().map(|(a, b)| a[i] / scale[i] * b).sum()
    });
    (ata, atb)
}

/// Best passive-set solution: (cost, coefficients, passive set, inverse normal matrix).
type Candidate = (f64, [f64; 5], Vec<usize>, DMatrix<f64>);

type Pass = (f64, [f64; 5], Vec<usize>, DMatrix<f64>, [f64; 5]);

/// One exact NNLS solve over all 31 non-empty passive sets.
fn nnls_pass(pts: &[&DevPoint], reference: Option<&[f64; 5]>) -> Result<Pass, NoiseError> {
    let rows = weighted_rows(pts, reference);
    // Column scaling for conditioning.
    let scale: [f64; 5] = std::array::from_fn(|j| {
        rows.iter()
            .map(|(a, _)| a[j] * a[j])
            .sum::<f64>()
            .sqrt()
            .max(f64::MIN_POSITIVE)
    });
    let normal = |set: &[usize]| normal_equations(&rows, &scale, set);
    let cost = |c: &[f64; 5]| -> f64 {
        rows.iter()
            .map(|(a, b)| {
                let r = b - (0..5).map(|j| a[j] * c[j]).sum::<f64>();
                r * r
            })
            .sum()
    };
    let mut best: Option<Candidate> = None;
    for mask in 1u32..32 {
        let set: Vec<usize> = (0..5).filter(|j| mask & (1 << j) != 0).collect();
        if set.len() > pts.len() {
            continue;
        }
        let (ata, atb) = normal(&set);
        let Some((x, inv)) = solve(&ata, &atb) else {
            continue;
        };
        if x.iter().any(|&v| v < 0.0) {
            continue;
        }
        let mut c = [0.0; 5];
        for (&j, v) in set.iter().zip(&x) {
            c[j] = v / scale[j];
        }
        let r = cost(&c);
        if best.as_ref().is_none_or(|b| r < b.0) {
            best = Some((r, c, set, inv));
        }
    }
    let Some((rss, c, set, inv)) = best else {
        return Err(NoiseError::TooFewPoints {
            n_points: pts.len(),
        });
    };
    Ok((rss, c, set, inv, scale))
}

/// Reads N, B, K off the curve by slope (tolerance +-0.15 on the slope).
pub fn slope_readoffs(curve: &DevCurve) -> SlopeReadoffs {
    let p = &curve.points;
    let slopes: Vec<(usize, f64)> = (0..p.len())
        .filter_map(|i| {
            let (a, b) = (i.checked_sub(1)?, i + 1);
            let b = p.get(b)?;
            let s = (b.dev / p[a].dev).ln() / (b.tau_s / p[a].tau_s).ln();
            s.is_finite().then_some((i, s))
        })
        .collect();
    let nearest = |target: f64| {
        slopes
            .iter()
            .filter(|(_, s)| (s - target).abs() < 0.15)
            .min_by(|a, b| (a.1 - target).abs().total_cmp(&(b.1 - target).abs()))
            .map(|&(i, _)| &p[i])
    };
    SlopeReadoffs {
        n_u_per_sqrt_hz: nearest(-0.5).map(|q| q.dev * q.tau_s.sqrt()),
        b_u: p
            .iter()
            .map(|q| q.dev)
            .filter(|d| *d > 0.0)
            .min_by(f64::total_cmp)
            .map(|d| d / BIAS_INSTABILITY_FACTOR),
        k_u_sqrt_hz: nearest(0.5).map(|q| q.dev * (3.0 / q.tau_s).sqrt()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_model_curve_is_recovered() {
        let truth = [1e-6, 1e-3, 2e-4, 1e-5, 0.0];
        let points = (0..30)
            .map(|i| {
                let tau = 0.01 * 2f64.powi(i);
                let b = basis(tau);
                let dev = (0..5)
                    .map(|j| b[j] * truth[j] * truth[j])
                    .sum::<f64>()
                    .sqrt();
                DevPoint {
                    m: 1 << i,
                    tau_s: tau,
                    dev,
                    n_terms: 100,
                    edf: 100.0,
                    dev_lo: dev,
                    dev_hi: dev,
                }
            })
            .collect();
        let curve = DevCurve {
            kind: Kind::Oadev,
            tau0_s: 0.01,
            confidence: 0.683,
            points,
        };
        let t = fit_terms(&curve).unwrap();
        assert!((t.n_u_per_sqrt_hz.value / 1e-3 - 1.0).abs() < 1e-6, "{t:?}");
        assert!((t.b_u.value / 2e-4 - 1.0).abs() < 1e-6);
        assert!((t.k_u_sqrt_hz.value / 1e-5 - 1.0).abs() < 1e-6);
        assert!((t.q_u_s.value / 1e-6 - 1.0).abs() < 1e-4);
        assert!(t.r_u_per_s.value < 1e-9);
        assert!((t.adev(1.0) / fit_model_dev(&truth, 1.0) - 1.0).abs() < 1e-6);
        // The read-off overestimates B where the N and K terms overlap the floor: that bias is
        // why the fit exists.
        let r = slope_readoffs(&curve);
        let b = r.b_u.unwrap();
        assert!(b > 2e-4 && b < 2e-4 * 1.6, "{r:?}");
    }

    fn fit_model_dev(c: &[f64; 5], tau: f64) -> f64 {
        let b = basis(tau);
        (0..5).map(|j| b[j] * c[j] * c[j]).sum::<f64>().sqrt()
    }
}
