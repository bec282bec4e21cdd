//! Still poses: their means' standard errors and conditions, which parameters the options hold,
//! and what the fitted models' standard errors and conditioning say.

use super::*;

/// Mask of the parameters of `names` (one triad) that `opts.hold` names.
pub(super) fn held(triad: Triad, names: &[String], hold: &[String]) -> Vec<bool> {
    names
        .iter()
        .map(|n| hold.iter().any(|h| *h == format!("{triad}.{n}")))
        .collect()
}

/// Unobservable-list entries for the held parameters of `names`.
pub(super) fn held_entries(names: &[String], mask: &[bool]) -> Vec<Unobservable> {
    names
        .iter()
        .zip(mask)
        .filter(|(_, h)| **h)
        .map(|(n, _)| Unobservable {
            name: n.clone(),
            reason: NotFitted::Requested,
        })
        .collect()
}

/// Standard error of a segment mean per axis (floored so a quantised, noiseless axis cannot
/// take all the weight).
pub(crate) fn mean_se(std: [f64; 3], n: usize) -> Vec3 {
    Vec3::from(std.map(|s| (s / (n as f64).sqrt()).max(1e-12)))
}

pub(crate) fn pose_conditions(series: &ImuSeries, seg: &Segment) -> Conditions {
    let mid_s = 0.5 * (seg.start_s + seg.end_s);
    let temp_c = series.temp_at(mid_s);
    Conditions {
        temp_c: if temp_c.is_finite() {
            temp_c
        } else {
            imu_model::units::REFERENCE_TEMP_C
        },
        // The power-on time is unknown: recording time stands in (a warm-up effect would be
        // referred to the recording's start).
        time_since_power_on_s: mid_s,
        specific_force_m_s2: seg.mean_accel(),
        ..Conditions::default()
    }
}

/// Per-effect standard errors into `model`: `None` for an effect with a parameter neither
/// fitted nor gauge-fixed, 0 for gauge-fixed entries.
pub(crate) fn store_std_errors(model: &mut TriadModel, se: &[Option<f64>], gauge: &[usize]) {
    let mut offset = 0;
    for e in model.effects_mut() {
        let n = e.n_params();
        let mine: Option<Vec<f64>> = (offset..offset + n)
            .map(|i| if gauge.contains(&i) { Some(0.0) } else { se[i] })
            .collect();
        e.set_std_errors(mine);
        offset += n;
    }
}

/// Warnings about poorly separated parameters of a solution.
pub(crate) fn conditioning_warnings(
    triad: Triad,
    sol: &LsqSolution,
    names: &[String],
    weak: f64,
    evidence: Evidence,
) -> Vec<FitWarning> {
    let mut w = Vec::new();
    if sol.min_eigenvalue < weak {
        w.push(FitWarningKind::WeaklySeparated {
            parameters: sol.weakest.clone(),
            eigenvalue: sol.min_eigenvalue,
            evidence,
        });
    }
    for (a, row) in sol.correlation.iter().enumerate() {
        for (b, c) in row.iter().enumerate() {
            if a < b && c.abs() > 0.99 {
                w.push(FitWarningKind::Correlated {
                    a: names[sol.free[a]].clone(),
                    b: names[sol.free[b]].clone(),
                    correlation: *c,
                    evidence,
                });
            }
        }
    }
    for u in &sol.unobservable {
        w.push(FitWarningKind::NotFitted(u.clone()));
    }
    if !sol.converged {
        w.push(FitWarningKind::NotConverged {
            iterations: sol.iterations,
        });
    }
    w.into_iter()
        .map(|kind| FitWarning {
            scope: WarningScope::Triad(triad),
            kind,
        })
        .collect()
}
