//! Profiling the residuals' white scale and bias wander (random walk or extra flicker) out of a
//! fit: generalised least squares over the segment-mean covariance.

use super::*;

// ------------------------------------------------------------------------------ helpers

/// A fit with its noise scale and drift profiled out.
#[derive(Clone, Debug)]
pub(super) struct Profiled {
    pub(super) fit: FitResult,
    /// Gaussian log-likelihood of the residuals (constants dropped).
    pub(super) loglik: f64,
    /// Residual variance over the floor's, per axis.
    pub(super) scale: [f64; 3],
    /// Bias wander beyond the floor, in units of the scale, per axis.
    pub(super) wander: [Wander; 3],
}

/// The bias wander between segments beyond the noise floor: a random walk (rate variance `q`)
/// or extra flicker (bias instability the segments are too short to measure), whichever the
/// residuals make likelier.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Wander {
    /// Random-walk rate variance, U^2/s.
    pub(super) random_walk_q: f64,
    /// Extra flicker Allan variance floor, U^2.
    pub(super) flicker_var: f64,
    /// The family: extra flicker (else a random walk).
    pub(super) flicker: bool,
}

impl Wander {
    /// The floor's `shared` noise with this wander, all of it times the white `scale` (the
    /// profiled covariance).
    pub(super) fn scaled(&self, shared: &SharedNoise, scale: f64) -> SharedNoise {
        SharedNoise {
            random_walk_q: scale * self.random_walk_q,
            flicker_var: scale * (shared.flicker_var + self.flicker_var),
            ..*shared
        }
    }

    /// The floor's `shared` noise (as measured) plus this wander (absolute).
    pub(super) fn added(&self, shared: &SharedNoise) -> SharedNoise {
        SharedNoise {
            random_walk_q: shared.random_walk_q + self.random_walk_q,
            flicker_var: shared.flicker_var + self.flicker_var,
            ..*shared
        }
    }

    /// In absolute units, for a profiled white `scale`.
    pub(super) fn absolute(&self, scale: f64) -> Wander {
        Wander {
            random_walk_q: scale * self.random_walk_q,
            flicker_var: scale * self.flicker_var,
            flicker: self.flicker,
        }
    }

    pub(super) fn is_none(&self) -> bool {
        self.random_walk_q <= 0.0 && self.flicker_var <= 0.0
    }

    /// Bias instability `B` of the extra flicker (`flicker_var = (0.664 B)^2`).
    pub(super) fn bias_instability(&self) -> f64 {
        self.flicker_var.max(0.0).sqrt() / imu_stats::noise_terms::BIAS_INSTABILITY_FACTOR
    }

    /// Settled: both parts within 0.1 % of `other`'s.
    pub(super) fn near(&self, other: &Wander) -> bool {
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-3 * b.max(1e-300);
        close(self.random_walk_q, other.random_walk_q) && close(self.flicker_var, other.flicker_var)
    }
}

/// Maximum-likelihood white scale and bias wander of residuals `r` whose covariance with
/// wander `w` is `cov(w)` (scale 1): a random walk or extra flicker ([`profile_rho`], around
/// `units` = (random-walk rate, flicker variance) scales); `flicker` fixes the family, None
/// profiles both and keeps the likelier. Nested models are compared within one family (the
/// base model's), so that the likelihood ratio is the effect's alone.
pub(super) fn profile_wander(
    r: &[f64],
    cov: impl Fn(Wander) -> DMatrix<f64>,
    units: (f64, f64),
    flicker: Option<bool>,
) -> (f64, Wander, f64) {
    let of = |flicker: bool, x: f64| Wander {
        random_walk_q: if flicker { 0.0 } else { x },
        flicker_var: if flicker { x } else { 0.0 },
        flicker,
    };
    let run = |f: bool| {
        let (scale, x, ll) = profile_rho(r, |x| cov(of(f, x)), if f { units.1 } else { units.0 });
        (scale, of(f, x), ll)
    };
    match flicker {
        Some(f) => run(f),
        None => {
            let (rw, fl) = (run(false), run(true));
            if fl.2 > rw.2 { fl } else { rw }
        }
    }
}

/// `r^T C^-1 r` and `ln |C|` for residuals `r` with covariance `c`.
pub(super) fn gls(r: &[f64], c: DMatrix<f64>) -> Option<(f64, f64)> {
    let ch = c.cholesky()?;
    let logdet = 2.0 * ch.l().diagonal().iter().map(|d| d.ln()).sum::<f64>();
    let z = ch.solve(&DVector::from_column_slice(r));
    Some((r.iter().zip(z.iter()).map(|(a, b)| a * b).sum(), logdet))
}

/// Generalised chi-square per axis against the noise floor (white part from the points'
/// standard errors, shared part `shared`).
pub(super) fn floor_chi2(
    res: &[[f64; 3]],
    points: &[FitPoint],
    shared: &[SharedNoise; 3],
) -> [f64; 3] {
    std::array::from_fn(|a| {
        let r: Vec<f64> = res.iter().map(|v| v[a]).collect();
        gls(&r, segment_covariance(points, a, &shared[a], 1.0)).map_or(f64::INFINITY, |(c, _)| c)
    })
}

/// Maximum-likelihood white scale and random-walk rate (relative to the scale) of residuals
/// `r` whose covariance at rate `rho` is `cov(rho)` (scale 1), and the log-likelihood there:
/// `rho` on a log grid around `unit` refined by golden section, the scale in closed form.
pub(super) fn profile_rho(
    r: &[f64],
    cov: impl Fn(f64) -> DMatrix<f64>,
    unit: f64,
) -> (f64, f64, f64) {
    let n = r.len() as f64;
    let ll = |rho: f64| -> Option<(f64, f64)> {
        let (chi2, logdet) = gls(r, cov(rho))?;
        let scale = (chi2 / n).max(1e-300);
        Some((scale, -0.5 * (n * scale.ln() + logdet + n)))
    };
    let grid: Vec<f64> = std::iter::once(0.0)
        .chain((0..=32).map(|k| unit * 10f64.powf(-4.0 + k as f64 * 0.25)))
        .collect();
    let mut best = (0.0, f64::NEG_INFINITY, 1.0);
    let mut best_k = 0;
    for (k, &rho) in grid.iter().enumerate() {
        if let Some((scale, l)) = ll(rho)
            && l > best.1
        {
            best = (rho, l, scale);
            best_k = k;
        }
    }
    if best_k > 0 {
        // Golden section in log rho between the neighbours of the best grid point.
        let lo = grid[best_k - 1].max(unit * 1e-5).ln();
        let hi = grid[(best_k + 1).min(grid.len() - 1)].ln();
        let (mut x0, mut x1) = (lo, hi);
        let g = 0.618_033_988_749_895;
        for _ in 0..30 {
            let (c, d) = (x1 - g * (x1 - x0), x0 + g * (x1 - x0));
            let lc = ll(c.exp()).map_or(f64::NEG_INFINITY, |v| v.1);
            let ld = ll(d.exp()).map_or(f64::NEG_INFINITY, |v| v.1);
            if lc > ld {
                x1 = d;
            } else {
                x0 = c;
            }
        }
        let rho = (0.5 * (x0 + x1)).exp();
        if let Some((scale, l)) = ll(rho)
            && l > best.1
        {
            best = (rho, l, scale);
        }
    }
    (best.2, best.0, best.1)
}

/// Time span of the points, s.
pub(super) fn span_s(points: &[FitPoint]) -> f64 {
    points
        .iter()
        .map(|p| p.t_s)
        .fold(f64::NEG_INFINITY, f64::max)
        - points.iter().map(|p| p.t_s).fold(f64::INFINITY, f64::min)
}

/// [`profile_wander`] for one axis's residuals under [`segment_covariance`].
pub(super) fn profile_axis(
    r: &[f64],
    points: &[FitPoint],
    a: usize,
    shared: &SharedNoise,
    flicker: Option<bool>,
) -> (f64, Wander, f64) {
    let n = r.len() as f64;
    let s2 = points.iter().map(|p| p.std_error[a].powi(2)).sum::<f64>() / n;
    let cov = |w: Wander| segment_covariance(points, a, &w.scaled(shared, 1.0), 1.0);
    profile_wander(r, cov, (s2 / span_s(points).max(1e-9), s2), flicker)
}

/// Expected covariance of the residuals of a generalised least-squares fit with raw Jacobian
/// `x` when the observations have covariance `c`: with the residual maker
/// `M = I - X (X^T C^-1 X)^-1 X^T C^-1`, `M C M^T` (`c` itself when `x` is empty or singular).
pub(super) fn residual_covariance(c: DMatrix<f64>, x: &DMatrix<f64>) -> DMatrix<f64> {
    let big = c.nrows();
    if x.nrows() != big || x.ncols() == 0 {
        return c;
    }
    let Some(ch) = c.clone().cholesky() else {
        return c;
    };
    let cinv_x = ch.solve(x);
    let Some(info_inv) = (x.transpose() * &cinv_x).try_inverse() else {
        return c;
    };
    let m = DMatrix::identity(big, big) - x * info_inv * cinv_x.transpose();
    &m * &c * m.transpose()
}

/// RMS per axis the residuals of a fit with raw Jacobian `x` (rows `3 k + axis`) would have if
/// the model were right and the means had their own floor plus the `shared` noise. The fit is
/// generalised least squares, whose estimates (the bias above all) are not plain means when the
/// means are correlated: see [`residual_covariance`].
pub(super) fn expected_residual_rms(
    points: &[FitPoint],
    x: &DMatrix<f64>,
    shared: &[SharedNoise; 3],
) -> [f64; 3] {
    let n = points.len();
    let big = 3 * n;
    let mut c = DMatrix::zeros(big, big);
    for (a, sh) in shared.iter().enumerate() {
        let ca = segment_covariance(points, a, sh, 1.0);
        for k in 0..n {
            for l in 0..n {
                c[(3 * k + a, 3 * l + a)] = ca[(k, l)];
            }
        }
    }
    let e = residual_covariance(c, x);
    std::array::from_fn(|a| {
        ((0..n).map(|k| e[(3 * k + a, 3 * k + a)]).sum::<f64>() / n.max(1) as f64)
            .max(0.0)
            .sqrt()
    })
}
