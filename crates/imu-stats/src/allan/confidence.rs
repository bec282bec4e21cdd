//! Confidence intervals of the deviations: equivalent degrees of freedom and chi-square
//! bounds (quantiles from `statrs` through `crate::distributions`).

use super::NoiseType;
use crate::distributions::chi2_quantile;

/// Equivalent degrees of freedom of the overlapping Allan variance (NIST SP 1065 Table 5) for
/// `n_phase` phase points at averaging factor `m`, capped as explained in the body.
pub fn edf_oadev(n_phase: usize, m: usize, noise: NoiseType) -> f64 {
    let edf = edf_sp1065(n_phase, m, noise);
    // No noise gives more degrees of freedom than about 3(N-1)/(2m) at long averaging times
    // (the white-FM limit). The cap matters when the per-tau noise type is picked from a noisy
    // local slope at the longest taus: a spurious slope of -1 would select the white-PM formula,
    // whose EDF stays near N/2, and give the least certain points the greatest weight.
    let cap = 3.0 * (n_phase as f64 - 1.0) / (2.0 * m as f64);
    if edf.is_finite() {
        edf.min(cap).max(1.0)
    } else {
        1.0
    }
}

/// The NIST SP 1065 Table 5 EDF formulas as printed (no cap); flicker-walk and random-run FM,
/// which the table lacks, use the random-walk FM form.
pub(super) fn edf_sp1065(n_phase: usize, m: usize, noise: NoiseType) -> f64 {
    let n = n_phase as f64;
    let m = m as f64;
    match noise {
        NoiseType::WhitePm => (n + 1.0) * (n - 2.0 * m) / (2.0 * (n - m)),
        NoiseType::FlickerPm => {
            let a = ((n - 1.0) / (2.0 * m)).ln();
            let b = ((2.0 * m + 1.0) * (n - 1.0) / 4.0).ln();
            (a * b).max(0.0).sqrt().exp()
        }
        NoiseType::WhiteFm => {
            (3.0 * (n - 1.0) / (2.0 * m) - 2.0 * (n - 2.0) / n) * 4.0 * m * m / (4.0 * m * m + 5.0)
        }
        NoiseType::FlickerFm => {
            if m <= 1.0 {
                2.0 * (n - 2.0).powi(2) / (2.3 * n - 4.9)
            } else {
                5.0 * n * n / (4.0 * m * (n + 3.0 * m))
            }
        }
        NoiseType::RandomWalkFm | NoiseType::FlickerWalkFm | NoiseType::RandomRunFm => {
            (n - 2.0) / m * ((n - 1.0).powi(2) - 3.0 * m * (n - 1.0) + 4.0 * m * m)
                / (n - 3.0).powi(2)
        }
    }
}

/// Two-sided confidence interval `(lo, hi)` on a deviation with `edf` degrees of freedom.
pub fn confidence_interval(dev: f64, edf: f64, confidence: f64) -> (f64, f64) {
    let alpha = 1.0 - confidence;
    let lo = dev * (edf / chi2_quantile(1.0 - alpha / 2.0, edf)).sqrt();
    let hi = dev * (edf / chi2_quantile(alpha / 2.0, edf)).sqrt();
    (lo, hi)
}
