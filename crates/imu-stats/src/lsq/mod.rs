//! The one weighted nonlinear least-squares engine (Levenberg-Marquardt) of the project.
//!
//! A problem is a closure (or any [`Residuals`]) mapping a parameter vector to WHITENED
//! residuals (each divided by its standard deviation, or premultiplied by the inverse Cholesky
//! factor of their covariance) of a fixed length. The engine knows nothing of IMUs: the
//! triad fit, the gravity-magnitude fit and the integrated-rotation fit all call it.
//!
//! Rules, the same for every caller:
//! - a numeric central-difference Jacobian (step `1e-6 max(|p|, 1e-3)`);
//! - parameters the data cannot separate (a zero column, or a combination with an eigenvalue
//!   of the normalised normal matrix below a threshold) are held at their start values and
//!   named ([`observability`]); among collinear parameters the one LAST in the caller's order
//!   goes (callers put secondary effects after primary ones);
//! - Marquardt's diagonal scaling, damping 1e-3 shrinking tenfold on success;
//! - the covariance `(J^T J)^-1` is scaled by the reduced chi-square only upwards: residuals
//!   that scatter more than their stated errors widen the standard errors, residuals that
//!   scatter less never narrow them;
//! - a fitted value the caller rejects can be held and the rest refitted ([`refit_holding`]).
//!
//! Hand-written rather than the `levenberg-marquardt` crate: that crate needs an analytic or
//! separately-supplied Jacobian and stops on its own criteria; the observability analysis and
//! the exact stopping rule here (relative cost change, "no downhill step at any damping" as
//! convergence) are what the calibrations' standard-error tests are built on.

mod observability;

use nalgebra::{DMatrix, DVector};
use serde::Serialize;

pub use observability::{
    Weakest, find_unobservable, find_unobservable_keeping, jacobian, weakest_combination,
};

/// A least-squares problem: residuals as a function of the parameters, and the linear map that
/// whitens them (identity unless the problem says otherwise). The engine differentiates the raw
/// residuals and whitens the difference, so a whitening by a covariance factor is applied once
/// per Jacobian column, exactly as to the residuals.
pub trait Residuals {
    /// Raw residuals at `p` (always the same length).
    fn raw(&mut self, p: &[f64]) -> DVector<f64>;

    /// Whitens raw residuals (a linear map; identity by default).
    fn whiten(&self, raw: DVector<f64>) -> DVector<f64> {
        raw
    }

    /// Whitened residuals at `p`.
    fn residuals(&mut self, p: &[f64]) -> DVector<f64> {
        let raw = self.raw(p);
        self.whiten(raw)
    }
}

/// A closure returning residuals that are already whitened.
impl<F: FnMut(&[f64]) -> DVector<f64>> Residuals for F {
    fn raw(&mut self, p: &[f64]) -> DVector<f64> {
        self(p)
    }
}

/// Settings of the engine.
#[derive(Clone, Debug, PartialEq)]
pub struct LsqOptions {
    /// Iteration budget.
    pub max_iterations: usize,
    /// Stop when the relative cost change falls below this.
    pub tolerance: f64,
    /// Smallest eigenvalue of the normalised normal matrix (unit diagonal) still counted as
    /// observable.
    pub min_eigenvalue: f64,
    /// Appended to the reason of a parameter held for collinearity (what would separate it,
    /// in the caller's terms); empty for none.
    pub collinear_advice: String,
}

impl Default for LsqOptions {
    fn default() -> Self {
        LsqOptions {
            max_iterations: 100,
            tolerance: 1e-12,
            min_eigenvalue: 1e-8,
            collinear_advice: String::new(),
        }
    }
}

/// A parameter that was not fitted (held at its start value), and why.
///
/// Serialized as `{"name", "code", "reason"}`: `code` is [`NotFitted::code`] (stable, for
/// programs), `reason` its English sentence (for people).
#[derive(Clone, Debug, PartialEq)]
pub struct Unobservable {
    /// Parameter name.
    pub name: String,
    /// Why.
    pub reason: NotFitted,
}

impl Serialize for Unobservable {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let mut s = serializer.serialize_struct("Unobservable", 3)?;
        s.serialize_field("name", &self.name)?;
        s.serialize_field("code", self.reason.code())?;
        s.serialize_field("reason", &self.reason.to_string())?;
        s.end()
    }
}

/// Why a parameter was not fitted. Programs match on the variant (or its [`code`](Self::code));
/// the English is its `Display`, for reports only.
#[derive(Clone, Debug, PartialEq)]
pub enum NotFitted {
    /// The data do not excite it: its Jacobian column is zero.
    ZeroJacobian,
    /// The data cannot separate it from other parameters.
    Collinear {
        /// The parameters it is collinear with (empty: not named).
        with: Vec<String>,
        /// Smallest eigenvalue of the normalised normal matrix.
        eigenvalue: f64,
        /// What would separate it, in the caller's terms ([`LsqOptions::collinear_advice`]).
        advice: String,
    },
    /// A gauge freedom of the gravity-magnitude fit: a rotation of the whole frame is
    /// invisible to it, so the parameter is held at 0 and the accelerometer axes define the
    /// frame.
    Gauge,
    /// Held at its start value because the caller asked.
    Requested,
    /// Its fitted value makes the model invalid (the caller's check): held at 0, no such term.
    InvalidModel {
        /// The rejected fitted value.
        value: f64,
        /// Its standard error, if it had one.
        std_error: Option<f64>,
        /// What the caller's check said.
        message: String,
    },
}

impl NotFitted {
    /// The stable code: `zero_jacobian`, `collinear`, `gauge`, `requested`, `invalid_model`.
    pub fn code(&self) -> &'static str {
        match self {
            NotFitted::ZeroJacobian => "zero_jacobian",
            NotFitted::Collinear { .. } => "collinear",
            NotFitted::Gauge => "gauge",
            NotFitted::Requested => "requested",
            NotFitted::InvalidModel { .. } => "invalid_model",
        }
    }
}

impl std::fmt::Display for NotFitted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            NotFitted::ZeroJacobian => {
                write!(f, "the data do not excite it (zero Jacobian column)")
            }
            NotFitted::Collinear {
                with,
                eigenvalue,
                advice,
            } => {
                let with = if with.is_empty() {
                    "other parameters".to_string()
                } else {
                    with.join(", ")
                };
                write!(
                    f,
                    "collinear with {with} in these data (eigenvalue {eigenvalue:.1e} of the \
                     normalised normal matrix){advice}"
                )
            }
            NotFitted::Gauge => write!(
                f,
                "gauge: the gravity magnitude cannot see a rotation of the whole frame; held at 0 \
                 so that the accelerometer axes define the body frame"
            ),
            NotFitted::Requested => write!(f, "held at its start value (requested)"),
            NotFitted::InvalidModel {
                value,
                std_error,
                message,
            } => {
                let se = std_error.map_or_else(String::new, |s| format!(" +/- {s:.2e}"));
                write!(
                    f,
                    "fitted to {value:.3e}{se}, it makes the model invalid ({message}); held at 0 \
                     (no such term)"
                )
            }
        }
    }
}

/// Where [`minimize`] stopped.
#[derive(Clone, Debug, PartialEq)]
pub struct Minimum {
    /// Sum of squared whitened residuals.
    pub cost: f64,
    /// Whitened residuals at the minimum.
    pub residuals: DVector<f64>,
    /// Iterations taken.
    pub iterations: usize,
    /// True if the cost settled within the budget.
    pub converged: bool,
}

/// Levenberg-Marquardt from `p` over the parameters `free` (indices into `p`); `p` ends at the
/// minimum found.
pub fn minimize<R: Residuals + ?Sized>(
    f: &mut R,
    p: &mut Vec<f64>,
    free: &[usize],
    opts: &LsqOptions,
) -> Minimum {
    minimize_from(f, p, free, opts, None).0
}

/// [`minimize`] given the whitened residuals and the Jacobian at the start `p` (`start`, when
/// the caller has them: they are not evaluated again), also returning the Jacobian at the
/// minimum when the last one computed is there (the search ended with no downhill step), so
/// that the caller's covariance need not evaluate it again. The steps are those of
/// [`minimize`].
pub fn minimize_from<R: Residuals + ?Sized>(
    f: &mut R,
    p: &mut Vec<f64>,
    free: &[usize],
    opts: &LsqOptions,
    start: Option<(DVector<f64>, DMatrix<f64>)>,
) -> (Minimum, Option<DMatrix<f64>>) {
    let (mut r, mut next_j) = match start {
        Some((r, j)) => (r, Some(j)),
        None => (f.residuals(p), None),
    };
    let mut cost = r.norm_squared();
    let mut lambda = 1e-3;
    let mut iterations = 0;
    while iterations < opts.max_iterations {
        iterations += 1;
        let j = next_j.take().unwrap_or_else(|| jacobian(f, p, free));
        let a = j.transpose() * &j;
        let g = j.transpose() * &r;
        let mut improved = false;
        for _ in 0..20 {
            let mut damped = a.clone();
            for d in 0..free.len() {
                damped[(d, d)] += lambda * a[(d, d)].max(1e-30);
            }
            let Some(step) = damped.cholesky().map(|c| c.solve(&(-&g))) else {
                lambda *= 10.0;
                continue;
            };
            let mut q = p.clone();
            for (c, &i) in free.iter().enumerate() {
                q[i] += step[c];
            }
            let rq = f.residuals(&q);
            let cq = rq.norm_squared();
            if cq.is_finite() && cq <= cost {
                let change = (cost - cq) / cost.max(1e-300);
                *p = q;
                r = rq;
                cost = cq;
                lambda = (lambda / 10.0).max(1e-12);
                improved = true;
                if change < opts.tolerance {
                    let min = Minimum {
                        cost,
                        residuals: r,
                        iterations,
                        converged: true,
                    };
                    return (min, None);
                }
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            // No downhill step at any damping: at the minimum to machine precision.
            let min = Minimum {
                cost,
                residuals: r,
                iterations,
                converged: true,
            };
            return (min, Some(j));
        }
    }
    let min = Minimum {
        cost,
        residuals: r,
        iterations,
        converged: false,
    };
    (min, None)
}

/// Covariance of the free parameters from the whitened Jacobian at the minimum:
/// `(J^T J)^-1 max(1, reduced_chi2)`; `None` when the normal matrix is singular.
pub fn covariance(j: &DMatrix<f64>, reduced_chi2: f64) -> Option<DMatrix<f64>> {
    (j.transpose() * j)
        .try_inverse()
        .map(|inv| inv * reduced_chi2.max(1.0))
}

/// Correlation matrix of a covariance matrix.
pub fn correlation_matrix(cov: &DMatrix<f64>) -> Vec<Vec<f64>> {
    let n = cov.nrows();
    (0..n)
        .map(|a| {
            (0..n)
                .map(|b| cov[(a, b)] / (cov[(a, a)] * cov[(b, b)]).sqrt())
                .collect()
        })
        .collect()
}

/// Result of [`least_squares`].
#[derive(Clone, Debug, PartialEq)]
pub struct LsqSolution {
    /// All parameters (held ones at their start values).
    pub params: Vec<f64>,
    /// Indices of the fitted parameters.
    pub free: Vec<usize>,
    /// Parameters the data could not determine (held at their start values).
    pub unobservable: Vec<Unobservable>,
    /// Covariance of the free parameters (order of `free`), scaled by `max(1, reduced_chi2)`.
    pub covariance: DMatrix<f64>,
    /// Standard errors, layout of `params`; `None` for held parameters.
    pub std_errors: Vec<Option<f64>>,
    /// Correlation matrix of the free parameters (order of `free`).
    pub correlation: Vec<Vec<f64>>,
    /// Whitened residuals at the solution.
    pub residuals: DVector<f64>,
    /// Sum of squared whitened residuals.
    pub chi2: f64,
    /// Residuals minus free parameters.
    pub dof: usize,
    /// `chi2 / dof`.
    pub reduced_chi2: f64,
    /// Iterations taken.
    pub iterations: usize,
    /// True if the cost settled within the budget.
    pub converged: bool,
    /// Smallest eigenvalue of the normalised normal matrix of the free parameters at the
    /// solution (1 = independent parameters, 0 = inseparable).
    pub min_eigenvalue: f64,
    /// Names of the parameters with a large share (|component| > 0.3) in the weakest
    /// combination (the eigenvector of `min_eigenvalue`).
    pub weakest: Vec<String>,
}

/// Failures of [`least_squares`].
#[derive(Debug, thiserror::Error)]
pub enum LsqError {
    /// No free observable parameter is left.
    #[error("no free observable parameters")]
    NothingToFit,
    /// Not more residuals than free parameters.
    #[error(
        "{n_residuals} residuals cannot determine {n_free} parameters with any degrees of freedom left"
    )]
    TooFewResiduals {
        /// Residuals.
        n_residuals: usize,
        /// Free parameters.
        n_free: usize,
    },
    /// The residual closure returned a non-finite value at the start.
    #[error("the residuals are not finite at the starting parameters")]
    NotFinite,
}

/// The whole recipe in one call: minimise `|residual(p)|^2` over the parameters not marked in
/// `fixed` (layout of `p0`; empty = all free), starting from `p0`, after holding the
/// unobservable ones; `names` (layout of `p0`) name parameters in the result.
pub fn least_squares<R: Residuals>(
    mut residual: R,
    p0: &[f64],
    fixed: &[bool],
    names: &[String],
    opts: &LsqOptions,
) -> Result<LsqSolution, LsqError> {
    let mut p = p0.to_vec();
    let r0 = residual.residuals(&p);
    if r0.iter().any(|v| !v.is_finite()) {
        return Err(LsqError::NotFinite);
    }
    let n_res = r0.len();
    let mut free: Vec<usize> = (0..p.len())
        .filter(|&i| !fixed.get(i).copied().unwrap_or(false))
        .collect();
    let (unobservable, j0) = find_unobservable_keeping(&mut residual, &p, &mut free, names, opts);
    if free.is_empty() {
        return Err(LsqError::NothingToFit);
    }
    if n_res <= free.len() {
        return Err(LsqError::TooFewResiduals {
            n_residuals: n_res,
            n_free: free.len(),
        });
    }
    // The start's residuals and Jacobian are the ones just computed; the Jacobian at the
    // minimum is evaluated only if the search did not end on it.
    let (min, j_min) = minimize_from(&mut residual, &mut p, &free, opts, Some((r0, j0)));
    let dof = n_res - free.len();
    let reduced_chi2 = min.cost / dof as f64;
    let j = j_min.unwrap_or_else(|| jacobian(&mut residual, &p, &free));
    let nf = free.len();
    let covariance =
        covariance(&j, reduced_chi2).unwrap_or_else(|| DMatrix::from_element(nf, nf, f64::NAN));
    let mut std_errors = vec![None; p.len()];
    for (c, &i) in free.iter().enumerate() {
        std_errors[i] = Some(covariance[(c, c)].max(0.0).sqrt());
    }
    let correlation = correlation_matrix(&covariance);
    let weak = weakest_combination(&j);
    let weakest = weak
        .members
        .iter()
        .map(|&c| names[free[c]].clone())
        .collect();
    Ok(LsqSolution {
        params: p,
        free,
        unobservable,
        covariance,
        std_errors,
        correlation,
        residuals: min.residuals,
        chi2: min.cost,
        dof,
        reduced_chi2,
        iterations: min.iterations,
        converged: min.converged,
        min_eigenvalue: weak.eigenvalue,
        weakest,
    })
}

/// Fit, let the caller check the result, and while it rejects a parameter hold that one and
/// refit: `fit(held)` fits with the parameters in `held` held (the caller's own handle type
/// `H`); `reject(result, held)` returns the next parameter to hold, or `None` to accept.
/// Returns the accepted result with everything held on the way.
pub fn refit_holding<T, H, E>(
    mut fit: impl FnMut(&[H]) -> Result<T, E>,
    mut reject: impl FnMut(&T, &[H]) -> Result<Option<H>, E>,
) -> Result<(T, Vec<H>), E> {
    let mut held = Vec::new();
    loop {
        let result = fit(&held)?;
        match reject(&result, &held)? {
            None => return Ok((result, held)),
            Some(h) => held.push(h),
        }
    }
}

#[cfg(test)]
mod tests;
