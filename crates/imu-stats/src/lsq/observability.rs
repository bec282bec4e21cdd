//! What the data determine: the numeric Jacobian, the parameters the data cannot separate
//! (held and named before the fit) and the weakest parameter combination after it.

use nalgebra::{DMatrix, Dyn, SymmetricEigen};

use super::{LsqOptions, NotFitted, Residuals, Unobservable};

/// Numeric Jacobian of the whitened residuals of `f` at `p` with respect to the parameters
/// `free`: central differences of the raw residuals (step `1e-6 max(|p_i|, 1e-3)`), whitened.
pub fn jacobian<R: Residuals + ?Sized>(f: &mut R, p: &[f64], free: &[usize]) -> DMatrix<f64> {
    let mut q = p.to_vec();
    let mut j: Option<DMatrix<f64>> = None;
    for (c, &i) in free.iter().enumerate() {
        let h = 1e-6 * p[i].abs().max(1e-3);
        q[i] = p[i] + h;
        let up = f.raw(&q);
        q[i] = p[i] - h;
        let down = f.raw(&q);
        q[i] = p[i];
        let column = f.whiten((up - down) / (2.0 * h));
        let j = j.get_or_insert_with(|| DMatrix::zeros(column.len(), free.len()));
        j.set_column(c, &column);
    }
    j.unwrap_or_else(|| DMatrix::zeros(f.residuals(p).len(), 0))
}

/// Column norms and the eigen-decomposition of the normalised normal matrix.
fn normalised_eigen(j: &DMatrix<f64>) -> (Vec<f64>, SymmetricEigen<f64, Dyn>) {
    let norms: Vec<f64> = (0..j.ncols()).map(|c| j.column(c).norm()).collect();
    let mut jn = j.clone();
    for (c, n) in norms.iter().enumerate() {
        jn.column_mut(c).unscale_mut(n.max(1e-300));
    }
    (norms, SymmetricEigen::new(jn.transpose() * &jn))
}

/// Index and value of the smallest eigenvalue.
fn smallest(eig: &SymmetricEigen<f64, Dyn>) -> (usize, f64) {
    eig.eigenvalues
        .iter()
        .copied()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .expect("non-empty")
}

/// Drop from `free` the parameters the Jacobian at `p` cannot separate: zero columns first,
/// then, while the normalised normal matrix has an eigenvalue below `opts.min_eigenvalue`,
/// the parameter with a large share (|component| > 0.1) in that eigenvector that comes LAST
/// in `free`. `names` is in the layout of `p`.
pub fn find_unobservable<R: Residuals + ?Sized>(
    f: &mut R,
    p: &[f64],
    free: &mut Vec<usize>,
    names: &[String],
    opts: &LsqOptions,
) -> Vec<Unobservable> {
    find_unobservable_keeping(f, p, free, names, opts).0
}

/// [`find_unobservable`], also returning the Jacobian at `p` of the parameters left in `free`
/// (the first step of a fit from `p` needs it). The Jacobian is evaluated once: each column
/// perturbs its own parameter alone, so a dropped parameter's column is dropped, not the
/// matrix recomputed, and the columns kept are bit-for-bit those a new evaluation would give.
pub fn find_unobservable_keeping<R: Residuals + ?Sized>(
    f: &mut R,
    p: &[f64],
    free: &mut Vec<usize>,
    names: &[String],
    opts: &LsqOptions,
) -> (Vec<Unobservable>, DMatrix<f64>) {
    let mut out = Vec::new();
    if free.is_empty() {
        return (out, DMatrix::zeros(0, 0));
    }
    let full = jacobian(f, p, free);
    // The columns of `full` of the parameters still in `free`.
    let mut columns: Vec<usize> = (0..free.len()).collect();
    while !free.is_empty() {
        let j = full.select_columns(columns.iter());
        let (norms, eig) = normalised_eigen(&j);
        let max_norm = norms.iter().copied().fold(0.0, f64::max);
        if let Some(c) = norms
            .iter()
            .position(|n| *n <= 1e-12 * max_norm.max(1e-300))
        {
            out.push(Unobservable {
                name: names[free[c]].clone(),
                reason: NotFitted::ZeroJacobian,
            });
            free.remove(c);
            columns.remove(c);
            continue;
        }
        let (k, lam) = smallest(&eig);
        if lam >= opts.min_eigenvalue {
            break;
        }
        let v = eig.eigenvectors.column(k);
        let involved: Vec<usize> = (0..free.len()).filter(|&c| v[c].abs() > 0.1).collect();
        let drop = *involved.last().unwrap_or(&(free.len() - 1));
        let with: Vec<String> = involved
            .iter()
            .filter(|&&c| c != drop)
            .map(|&c| names[free[c]].clone())
            .collect();
        out.push(Unobservable {
            name: names[free[drop]].clone(),
            reason: NotFitted::Collinear {
                with,
                eigenvalue: lam,
                advice: opts.collinear_advice.clone(),
            },
        });
        free.remove(drop);
        columns.remove(drop);
    }
    (out, full.select_columns(columns.iter()))
}

/// The weakest parameter combination of a Jacobian.
#[derive(Clone, Debug, PartialEq)]
pub struct Weakest {
    /// Smallest eigenvalue of the normalised normal matrix (1 = independent, 0 = inseparable).
    pub eigenvalue: f64,
    /// Columns with a large share (|component| > 0.3) in its eigenvector.
    pub members: Vec<usize>,
}

/// The weakest combination of the columns of `j` (at least one column).
pub fn weakest_combination(j: &DMatrix<f64>) -> Weakest {
    let (_, eig) = normalised_eigen(j);
    let (k, eigenvalue) = smallest(&eig);
    let v = eig.eigenvectors.column(k);
    Weakest {
        eigenvalue,
        members: (0..j.ncols()).filter(|&c| v[c].abs() > 0.3).collect(),
    }
}
