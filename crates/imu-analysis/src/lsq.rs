//! A generic weighted nonlinear least-squares core: a closure maps a parameter vector to
//! WHITENED residuals (each divided by its standard deviation), and [`least_squares`] returns
//! the Levenberg-Marquardt minimum with standard errors.
//!
//! It follows the same rules as the segment fit in `fit.rs` (which keeps its own variant with
//! per-axis whitening of segment means): a numeric central-difference Jacobian, Marquardt's
//! diagonal scaling, parameters the data cannot separate (a zero column, or a combination with
//! an eigenvalue of the normalised normal matrix below a threshold) held at their start values
//! and named, and a covariance `(J^T J)^-1` scaled by the reduced chi-square when that exceeds 1
//! (residuals that scatter more than their stated errors widen the standard errors; residuals
//! that scatter less never narrow them). Used where the residual is not `forward(true) -
//! measured` of one triad, e.g. the gravity-magnitude and integrated-rotation residuals of the
//! reference-free calibration.

use imu_model::nalgebra::{DMatrix, DVector, SymmetricEigen};

use crate::fit::Unobservable;

/// Settings of [`least_squares`].
#[derive(Clone, Debug, PartialEq)]
pub struct LsqOptions {
    /// Iteration budget.
    pub max_iterations: usize,
    /// Stop when the relative cost change falls below this.
    pub tolerance: f64,
    /// Smallest eigenvalue of the normalised normal matrix (unit diagonal) still counted as
    /// observable.
    pub min_eigenvalue: f64,
}

impl Default for LsqOptions {
    fn default() -> Self {
        LsqOptions {
            max_iterations: 100,
            tolerance: 1e-12,
            min_eigenvalue: 1e-8,
        }
    }
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

/// Numeric Jacobian of `f` at `p` with respect to the parameters `free` (central differences).
pub(crate) fn jacobian<F: FnMut(&[f64]) -> DVector<f64>>(
    f: &mut F,
    p: &[f64],
    free: &[usize],
    n_res: usize,
) -> DMatrix<f64> {
    let mut j = DMatrix::zeros(n_res, free.len());
    let mut q = p.to_vec();
    for (c, &i) in free.iter().enumerate() {
        let h = 1e-6 * p[i].abs().max(1e-3);
        q[i] = p[i] + h;
        let up = f(&q);
        q[i] = p[i] - h;
        let down = f(&q);
        q[i] = p[i];
        j.set_column(c, &((up - down) / (2.0 * h)));
    }
    j
}

/// Column norms and the eigen-decomposition of the normalised normal matrix.
fn normalised_eigen(j: &DMatrix<f64>) -> (Vec<f64>, SymmetricEigen<f64, imu_model::nalgebra::Dyn>) {
    let norms: Vec<f64> = (0..j.ncols()).map(|c| j.column(c).norm()).collect();
    let mut jn = j.clone();
    for (c, n) in norms.iter().enumerate() {
        jn.column_mut(c).unscale_mut(n.max(1e-300));
    }
    (norms, SymmetricEigen::new(jn.transpose() * &jn))
}

/// Drop from `free` the parameters the Jacobian at `p` cannot separate: zero columns first,
/// then, while the normalised normal matrix has an eigenvalue below `min_eig`, the parameter
/// with a large share in that eigenvector that comes LAST in `free` (callers order parameters
/// so that secondary effects come after the primary ones).
fn find_unobservable<F: FnMut(&[f64]) -> DVector<f64>>(
    f: &mut F,
    p: &[f64],
    free: &mut Vec<usize>,
    names: &[String],
    n_res: usize,
    min_eig: f64,
) -> Vec<Unobservable> {
    let mut out = Vec::new();
    while !free.is_empty() {
        let j = jacobian(f, p, free, n_res);
        let (norms, eig) = normalised_eigen(&j);
        let max_norm = norms.iter().copied().fold(0.0, f64::max);
        if let Some(c) = norms
            .iter()
            .position(|n| *n <= 1e-12 * max_norm.max(1e-300))
        {
            out.push(Unobservable {
                name: names[free[c]].clone(),
                reason: "the data do not excite it (zero Jacobian column)".into(),
            });
            free.remove(c);
            continue;
        }
        let (k, lam) = eig
            .eigenvalues
            .iter()
            .copied()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .expect("non-empty");
        if lam >= min_eig {
            break;
        }
        let v = eig.eigenvectors.column(k);
        let involved: Vec<usize> = (0..free.len()).filter(|&c| v[c].abs() > 0.1).collect();
        let drop = *involved.last().unwrap_or(&(free.len() - 1));
        let others: Vec<&str> = involved
            .iter()
            .filter(|&&c| c != drop)
            .map(|&c| names[free[c]].as_str())
            .collect();
        out.push(Unobservable {
            name: names[free[drop]].clone(),
            reason: format!(
                "collinear with {} in these data (eigenvalue {lam:.1e} of the normalised normal \
                 matrix)",
                if others.is_empty() {
                    "other parameters".to_string()
                } else {
                    others.join(", ")
                }
            ),
        });
        free.remove(drop);
    }
    out
}

/// Minimise `|residual(p)|^2` over the parameters not marked in `fixed` (layout of `p0`;
/// empty = all free), starting from `p0`. `residual` must return whitened residuals of a
/// fixed length. `names` (layout of `p0`) name parameters in the result.
pub fn least_squares<F: FnMut(&[f64]) -> DVector<f64>>(
    mut residual: F,
    p0: &[f64],
    fixed: &[bool],
    names: &[String],
    opts: &LsqOptions,
) -> Result<LsqSolution, LsqError> {
    let mut p = p0.to_vec();
    let mut r = residual(&p);
    if r.iter().any(|v| !v.is_finite()) {
        return Err(LsqError::NotFinite);
    }
    let n_res = r.len();
    let mut free: Vec<usize> = (0..p.len())
        .filter(|&i| !fixed.get(i).copied().unwrap_or(false))
        .collect();
    let unobservable = find_unobservable(
        &mut residual,
        &p,
        &mut free,
        names,
        n_res,
        opts.min_eigenvalue,
    );
    if free.is_empty() {
        return Err(LsqError::NothingToFit);
    }
    if n_res <= free.len() {
        return Err(LsqError::TooFewResiduals {
            n_residuals: n_res,
            n_free: free.len(),
        });
    }

    let mut cost = r.norm_squared();
    let mut lambda = 1e-3;
    let mut iterations = 0;
    let mut converged = false;
    'outer: while iterations < opts.max_iterations {
        iterations += 1;
        let j = jacobian(&mut residual, &p, &free, n_res);
        let a = j.transpose() * &j;
        let g = j.transpose() * &r;
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
            let rq = residual(&q);
            let cq = rq.norm_squared();
            if cq.is_finite() && cq <= cost {
                let change = (cost - cq) / cost.max(1e-300);
                p = q;
                r = rq;
                cost = cq;
                lambda = (lambda / 10.0).max(1e-12);
                if change < opts.tolerance {
                    converged = true;
                    break 'outer;
                }
                continue 'outer;
            }
            lambda *= 10.0;
        }
        // No downhill step at any damping: at the minimum to machine precision.
        converged = true;
        break;
    }

    let dof = n_res - free.len();
    let reduced_chi2 = cost / dof as f64;
    let j = jacobian(&mut residual, &p, &free, n_res);
    let covariance = match (j.transpose() * &j).try_inverse() {
        Some(inv) => inv * reduced_chi2.max(1.0),
        None => DMatrix::from_element(free.len(), free.len(), f64::NAN),
    };
    let mut std_errors = vec![None; p.len()];
    for (c, &i) in free.iter().enumerate() {
        std_errors[i] = Some(covariance[(c, c)].max(0.0).sqrt());
    }
    let nf = free.len();
    let correlation: Vec<Vec<f64>> = (0..nf)
        .map(|a| {
            (0..nf)
                .map(|b| covariance[(a, b)] / (covariance[(a, a)] * covariance[(b, b)]).sqrt())
                .collect()
        })
        .collect();
    let (_, eig) = normalised_eigen(&j);
    let (k, min_eigenvalue) = eig
        .eigenvalues
        .iter()
        .copied()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .expect("non-empty");
    let v = eig.eigenvectors.column(k);
    let weakest = (0..nf)
        .filter(|&c| v[c].abs() > 0.3)
        .map(|c| names[free[c]].clone())
        .collect();
    Ok(LsqSolution {
        params: p,
        free,
        unobservable,
        covariance,
        std_errors,
        correlation,
        residuals: r,
        chi2: cost,
        dof,
        reduced_chi2,
        iterations,
        converged,
        min_eigenvalue,
        weakest,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A straight line through noisy points: the fit, its standard errors (scaled by the
    /// scatter) and an unobservable duplicate parameter.
    #[test]
    fn fits_a_line_and_names_a_duplicate_parameter() {
        let xs: Vec<f64> = (0..20).map(|i| i as f64).collect();
        // Deterministic +/-0.5 scatter, so the reduced chi-square with sigma = 0.1 is large.
        let ys: Vec<f64> = xs
            .iter()
            .enumerate()
            .map(|(i, x)| 2.0 + 0.5 * x + if i % 2 == 0 { 0.5 } else { -0.5 })
            .collect();
        let sigma = 0.1;
        let f = |p: &[f64]| {
            DVector::from_iterator(
                xs.len(),
                xs.iter()
                    .zip(&ys)
                    .map(|(x, y)| (p[0] + p[2] + p[1] * x - y) / sigma),
            )
        };
        let names: Vec<String> = ["a", "b", "a2"].iter().map(|s| s.to_string()).collect();
        let s = least_squares(f, &[0.0, 0.0, 0.0], &[], &names, &LsqOptions::default()).unwrap();
        assert_eq!(s.free, vec![0, 1]);
        assert_eq!(s.unobservable.len(), 1);
        assert_eq!(s.unobservable[0].name, "a2");
        assert!(s.unobservable[0].reason.contains("collinear with a"));
        assert!((s.params[1] - 0.5).abs() < 0.01, "{:?}", s.params);
        assert!((s.params[0] - 2.0).abs() < 0.3, "{:?}", s.params);
        assert_eq!(s.std_errors[2], None);
        // Ordinary least squares of a line: se(b) = s / sqrt(sum (x - mean)^2), with s the
        // residual standard deviation (the chi-square scaling replaces the stated 0.1).
        let n = xs.len() as f64;
        let mean = xs.iter().sum::<f64>() / n;
        let sxx: f64 = xs.iter().map(|x| (x - mean).powi(2)).sum();
        let res_sd = (s.chi2 / s.dof as f64).sqrt() * sigma;
        let want = res_sd / sxx.sqrt();
        assert!(
            (s.std_errors[1].unwrap() / want - 1.0).abs() < 1e-4,
            "{:?} vs {want}",
            s.std_errors[1]
        );
        assert!(s.reduced_chi2 > 10.0);
        assert!(s.converged);

        let e = least_squares(
            |p: &[f64]| DVector::from_vec(vec![p[0] - 1.0, p[1] - 2.0]),
            &[0.0, 0.0],
            &[],
            &names[..2],
            &LsqOptions::default(),
        )
        .unwrap_err();
        assert!(matches!(e, LsqError::TooFewResiduals { .. }), "{e}");
    }
}
