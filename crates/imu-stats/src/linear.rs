//! Small dense linear least squares by the normal equations (nalgebra's LU with partial
//! pivoting), with the inverse normal matrix that the callers turn into standard errors.

use nalgebra::{DMatrix, DVector};

/// Solves `a x = b` for a small square system and returns `x` and `a^-1`; `None` when a pivot
/// of the partially pivoted LU factorisation is at most `min_pivot` in magnitude (singular for
/// the caller's purpose).
pub fn solve_with_inverse(
    a: &DMatrix<f64>,
    b: &DVector<f64>,
    min_pivot: f64,
) -> Option<(DVector<f64>, DMatrix<f64>)> {
    let n = a.nrows();
    if n == 0 || a.ncols() != n || b.len() != n {
        return None;
    }
    let lu = a.clone().lu();
    if lu.u().diagonal().iter().any(|d| d.abs() <= min_pivot) {
        return None;
    }
    let inverse = lu.try_inverse()?;
    let x = &inverse * b;
    Some((x, inverse))
}

/// Ordinary least squares of `y` on the regressor `rows` (one row per observation): the
/// coefficients and `(X^T X)^-1`; `None` with no rows or a (numerically) singular normal
/// matrix (a pivot below `1e-14` of its largest element).
pub fn ordinary_least_squares(rows: &[Vec<f64>], y: &[f64]) -> Option<(Vec<f64>, DMatrix<f64>)> {
    let p = rows.first()?.len();
    let mut ata = DMatrix::<f64>::zeros(p, p);
    let mut aty = DVector::zeros(p);
    for (r, &yv) in rows.iter().zip(y) {
        for i in 0..p {
            aty[i] += r[i] * yv;
            for j in 0..p {
                ata[(i, j)] += r[i] * r[j];
            }
        }
    }
    let scale = ata.amax().max(f64::MIN_POSITIVE);
    let (_, inverse) = solve_with_inverse(&ata, &aty, scale * 1e-14)?;
    // The coefficients as (X^T X)^-1 X^T y, the same product the standard errors come from.
    let c = (0..p)
        .map(|i| (0..p).map(|j| inverse[(i, j)] * aty[j]).sum())
        .collect();
    Some((c, inverse))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_through_exact_points() {
        let rows: Vec<Vec<f64>> = (0..5).map(|i| vec![1.0, i as f64]).collect();
        let y: Vec<f64> = (0..5).map(|i| 3.0 - 0.5 * i as f64).collect();
        let (c, inv) = ordinary_least_squares(&rows, &y).unwrap();
        assert!(
            (c[0] - 3.0).abs() < 1e-12 && (c[1] + 0.5).abs() < 1e-12,
            "{c:?}"
        );
        // (X^T X)^-1 of x = 0..4: [[0.6, -0.2], [-0.2, 0.1]].
        assert!((inv[(0, 0)] - 0.6).abs() < 1e-12 && (inv[(1, 1)] - 0.1).abs() < 1e-12);
    }

    #[test]
    fn singular_systems_are_refused() {
        let rows: Vec<Vec<f64>> = (0..5).map(|i| vec![i as f64, 2.0 * i as f64]).collect();
        assert!(ordinary_least_squares(&rows, &[1.0; 5]).is_none());
        assert!(ordinary_least_squares(&[], &[]).is_none());
        let a = DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.0, 1e-14]);
        assert!(solve_with_inverse(&a, &DVector::from_vec(vec![1.0, 1.0]), 1e-13).is_none());
    }
}
