//! The reference-free accel observation: one residual per pose, the gravity magnitude minus the
//! corrected mean's norm, with its covariance projected from the per-axis floor.

use super::*;

// ------------------------------------------------------------------------------ magnitude

/// Accel observations without a reference (still poses in unknown orientations): only the
/// magnitude of the corrected specific force is known, local gravity. Each pose gives one
/// residual, `g - |corrected mean|`, stored as a vector along the pose's measured direction
/// (so per-axis summaries keep their meaning); its noise is the mean's per-axis noise projected
/// on that direction.
#[derive(Clone, Debug)]
pub(super) struct Magnitude {
    /// Local gravity, m/s^2.
    pub(super) g_m_s2: f64,
    /// Unit direction of each pose's measured specific force (order of the accel points).
    pub(super) dirs: Vec<Vec3>,
    /// Local gravity as given (for the final reference-free calibration).
    pub(super) gravity_m_s2: Option<f64>,
    /// Latitude as given, deg.
    pub(super) latitude_deg: Option<f64>,
}

impl Magnitude {
    /// Covariance of the magnitude residuals: the per-axis covariance of the means
    /// ([`segment_covariance`]: white floor, flicker, random walk) projected on each pose's
    /// direction, `C_kl = sum_a u_ka u_la C^a_kl`.
    pub(super) fn covariance(
        &self,
        points: &[FitPoint],
        shared: &[SharedNoise; 3],
    ) -> DMatrix<f64> {
        let n = points.len();
        let mut c = DMatrix::zeros(n, n);
        for (a, sh) in shared.iter().enumerate() {
            let ca = segment_covariance(points, a, sh, 1.0);
            for k in 0..n {
                for l in 0..n {
                    c[(k, l)] += self.dirs[k][a] * self.dirs[l][a] * ca[(k, l)];
                }
            }
        }
        c
    }

    /// The scalar residuals of stored residual vectors.
    pub(super) fn scalar(&self, res: &[[f64; 3]]) -> Vec<f64> {
        res.iter()
            .zip(&self.dirs)
            .map(|(r, u)| Vec3::from(*r).dot(u))
            .collect()
    }

    /// `chi2` split over the axes by each pose's squared direction cosines (the magnitude mixes
    /// the axes: the split is the diagonal's, the total the full generalised chi-square).
    pub(super) fn split(&self, chi2: f64, e: &[f64], c: &DMatrix<f64>) -> [f64; 3] {
        let w: [f64; 3] = std::array::from_fn(|a| {
            e.iter()
                .enumerate()
                .map(|(k, v)| self.dirs[k][a].powi(2) * v * v / c[(k, k)].max(1e-300))
                .sum()
        });
        let total: f64 = w.iter().sum();
        if total > 0.0 {
            w.map(|v| chi2 * v / total)
        } else {
            [chi2 / 3.0; 3]
        }
    }

    /// Generalised chi-square (split over the axes) of stored residuals.
    pub(super) fn chi2(
        &self,
        res: &[[f64; 3]],
        points: &[FitPoint],
        shared: &[SharedNoise; 3],
    ) -> [f64; 3] {
        let e = self.scalar(res);
        let c = self.covariance(points, shared);
        match gls(&e, c.clone()) {
            Some((chi2, _)) => self.split(chi2, &e, &c),
            None => [f64::INFINITY; 3],
        }
    }

    /// Expected residual RMS per axis (as [`expected_residual_rms`], rows of `x` per pose).
    pub(super) fn expected_rms(
        &self,
        points: &[FitPoint],
        x: &DMatrix<f64>,
        shared: &[SharedNoise; 3],
    ) -> [f64; 3] {
        let e = residual_covariance(self.covariance(points, shared), x);
        let n = points.len().max(1) as f64;
        std::array::from_fn(|a| {
            (self
                .dirs
                .iter()
                .enumerate()
                .map(|(k, u)| u[a] * u[a] * e[(k, k)])
                .sum::<f64>()
                / n)
                .max(0.0)
                .sqrt()
        })
    }

    /// `g - |corrected mean|` per pose under `m`.
    pub(super) fn residuals(&self, m: &TriadModel, points: &[FitPoint]) -> DVector<f64> {
        DVector::from_iterator(
            points.len(),
            points
                .iter()
                .map(|p| self.g_m_s2 - m.inverse(p.measured, &p.conditions).norm()),
        )
    }
}

pub(super) fn normalised(res: &[[f64; 3]], points: &[FitPoint]) -> Vec<f64> {
    res.iter()
        .zip(points)
        .flat_map(|(r, p)| (0..3).map(move |a| r[a] / p.std_error[a]))
        .collect()
}
