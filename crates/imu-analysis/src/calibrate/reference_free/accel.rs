//! The accel fit against the gravity magnitude at each pose, with the rotation gauge held.

use super::*;

/// The accel fit from the gravity magnitude at each pose.
pub(super) struct AccelOutcome {
    pub(super) fit: TriadFit,
    pub(super) up: Vec<Vec3>,
    pub(super) magnitude_error_m_s2: Vec<f64>,
    /// Where the fit started, when not from the model as given.
    pub(super) start_note: Option<Note>,
}

/// Moves the free bias and scale parameters of `p0` to the closed-form ellipsoid through the
/// poses when that fits the magnitudes better than `p0` does (raw data: offsets of a g, scale
/// errors of percent, where a start at zero can diverge), and says so.
fn start_from_ellipsoid(
    model: &TriadModel,
    fixed: &[bool],
    measured: &[Vec3],
    g_m_s2: f64,
    p0: &mut [f64],
    residual: &mut impl FnMut(&[f64]) -> DVector<f64>,
) -> Option<Note> {
    use imu_model::ParamRole;
    let start = ellipsoid::ellipsoid_start(measured, g_m_s2)?;
    let mut candidate = p0.to_vec();
    for (i, id) in model.param_ids().iter().enumerate() {
        match (id.effect, id.role) {
            (EffectKind::Bias, ParamRole::Axis(a)) if !fixed[i] => {
                candidate[i] = start.bias_m_s2[a]
            }
            (EffectKind::Scale, ParamRole::Axis(a)) if !fixed[i] => candidate[i] = start.scale[a],
            _ => {}
        }
    }
    let cost = |r: DVector<f64>| r.norm_squared();
    let (new_cost, old_cost) = (cost(residual(&candidate)), cost(residual(p0)));
    // A NaN cost (a start the model cannot invert) never wins, and always loses.
    if !(new_cost.is_finite() && new_cost.total_cmp(&old_cost).is_lt()) {
        return None;
    }
    p0.copy_from_slice(&candidate);
    let (b, s) = (start.bias_m_s2, start.scale);
    Some(Note::AccelStartEllipsoid {
        offset_m_s2: [b.x, b.y, b.z],
        scale_error: [s.x, s.y, s.z],
    })
}

/// Fits the accel model of `opts` to the gravity magnitude `g_m_s2` at the still `poses`,
/// with the rotation gauge (misalignment xy, xz, yz) held at 0. `still_s` is the shortest
/// still pose detection accepts, for messages.
pub(super) fn fit_accel(
    series: &ImuSeries,
    poses: &[&Segment],
    opts: &ReferenceFreeOptions,
    g_m_s2: f64,
    still_s: f64,
) -> Result<AccelOutcome, ReferenceFreeError> {
    let triad = Triad::Accel;
    let mut model = opts.accel.effects_only();
    let names = model.param_names(triad);
    let units = model.param_units(triad);
    let mut p0 = model.params();
    let gauge = gauge(&model.param_ids());
    let mut fixed = held(triad, &names, &opts.hold);
    let requested = fixed.clone();
    for &i in &gauge {
        p0[i] = 0.0;
        fixed[i] = true;
    }
    let n_free = fixed.iter().filter(|f| !**f).count();
    check_enough_poses(&model, poses.len(), n_free, still_s)?;
    let measured: Vec<Vec3> = poses.iter().map(|s| s.mean_accel()).collect();
    let conditions: Vec<Conditions> = poses.iter().map(|s| pose_conditions(series, s)).collect();
    let sigma_m_s2 = magnitude_sigma_m_s2(poses, &measured);
    let mut work = model.clone();
    let mut residual =
        |p: &[f64]| magnitude_residuals(&mut work, p, &measured, &conditions, &sigma_m_s2, g_m_s2);
    let start_note =
        start_from_ellipsoid(&model, &fixed, &measured, g_m_s2, &mut p0, &mut residual);
    let sol = least_squares(residual, &p0, &fixed, &names, &opts.lsq)
        .map_err(|source| lsq_error(source, poses.len(), still_s))?;
    let ids = model.param_ids();
    check_primary_observable(&ids, &sol)?;

    model.set_params(&sol.params);
    let std_errors = with_bias_drift(&ids, &sol.std_errors, opts.accel_bias_drift_m_s2);
    store_std_errors(&mut model, &std_errors, &gauge);

    let pose_fit = PoseMagnitudes::of(&model, &measured, &conditions, g_m_s2);
    let (up, magnitude_error_m_s2, rms) = (pose_fit.up, pose_fit.error_m_s2, pose_fit.rms_m_s2);
    model.residual_rms = Some(pose_fit.axis_rms_m_s2);

    let warnings = accel_warnings(&sol, &names, opts, poses.len(), n_free, &up);
    let unobservable = accel_unobservable(&gauge, &names, &requested, &sol);
    Ok(AccelOutcome {
        fit: TriadFit {
            triad,
            model,
            names,
            units,
            params: sol.params.clone(),
            std_errors,
            free: sol.free.clone(),
            correlation: sol.correlation.clone(),
            unobservable,
            residual: "|corrected specific force| - g at each still pose".into(),
            residual_unit: "m/s^2".into(),
            residual_rms: rms,
            n_residuals: poses.len(),
            chi2: sol.chi2,
            dof: sol.dof,
            reduced_chi2: sol.reduced_chi2,
            min_eigenvalue: sol.min_eigenvalue,
            iterations: sol.iterations,
            converged: sol.converged,
            warnings: warnings.into(),
        },
        up,
        magnitude_error_m_s2,
        start_note,
    })
}

/// The accel fit's error for a least-squares failure `source` with `n_poses` poses.
fn lsq_error(source: LsqError, n_poses: usize, still_s: f64) -> ReferenceFreeError {
    let triad = Triad::Accel;
    match source {
        LsqError::TooFewResiduals { n_free, .. } => ReferenceFreeError::TooFewPoses {
            triad,
            found: n_poses,
            needed: n_free + 1,
            n_free,
            what: "after dropping unobservable parameters".into(),
            still_s,
        },
        source => ReferenceFreeError::Lsq { triad, source },
    }
}

/// The accel fit's warnings: conditioning, too few poses for `n_free` parameters, axes the
/// poses' `up` directions leave uncovered.
fn accel_warnings(
    sol: &LsqSolution,
    names: &[String],
    opts: &ReferenceFreeOptions,
    n_poses: usize,
    n_free: usize,
    up: &[Vec3],
) -> Vec<FitWarning> {
    let mut warnings = conditioning_warnings(
        Triad::Accel,
        sol,
        names,
        opts.weak_eigenvalue,
        Evidence::Poses,
    );
    if n_poses < 2 * n_free {
        warnings.push(FitWarning {
            scope: WarningScope::Triad(Triad::Accel),
            kind: FitWarningKind::FewPoses {
                poses: n_poses,
                parameters: n_free,
            },
        });
    }
    push_axis_coverage_warnings(up, &mut warnings);
    warnings
}

/// The standard error of each pose's |mean accel|: the mean's error along the gravity
/// direction (at least 1e-12 m/s^2).
fn magnitude_sigma_m_s2(poses: &[&Segment], measured: &[Vec3]) -> Vec<f64> {
    poses
        .iter()
        .zip(measured)
        .map(|(s, m)| {
            let u = m.normalize();
            let se = mean_se(s.std_accel_m_s2, s.n);
            (0..3)
                .map(|a| (u[a] * se[a]).powi(2))
                .sum::<f64>()
                .sqrt()
                .max(1e-12)
        })
        .collect()
}

/// An error when the fit cannot observe a bias, scale or misalignment parameter.
fn check_primary_observable(
    ids: &[imu_model::ParamId],
    sol: &LsqSolution,
) -> Result<(), ReferenceFreeError> {
    let effect_of = |name: &str| ids.iter().find(|id| id.name == name).map(|id| id.effect);
    let primary: Vec<&Unobservable> = sol
        .unobservable
        .iter()
        .filter(|u| {
            matches!(
                effect_of(&u.name),
                Some(EffectKind::Bias | EffectKind::Scale | EffectKind::Misalignment)
            )
        })
        .collect();
    if !primary.is_empty() {
        return Err(ReferenceFreeError::Unobservable {
            names: primary
                .iter()
                .map(|u| u.name.as_str())
                .collect::<Vec<_>>()
                .join(", "),
            reason: primary[0].reason.to_string(),
        });
    }
    Ok(())
}

/// The fit's standard errors with the bias drift between poses (`drift`, m/s^2 per axis)
/// added in quadrature to the bias errors.
fn with_bias_drift(
    ids: &[imu_model::ParamId],
    std_errors: &[Option<f64>],
    drift: Option<[f64; 3]>,
) -> Vec<Option<f64>> {
    let mut std_errors = std_errors.to_vec();
    if let Some(drift) = drift {
        for (i, id) in ids.iter().enumerate() {
            if id.effect == EffectKind::Bias
                && let Some(a) = id.role.axis()
                && let Some(se) = std_errors[i].as_mut()
            {
                *se = (*se * *se + drift[a] * drift[a]).sqrt();
            }
        }
    }
    std_errors
}

/// The corrected poses under the fitted model.
struct PoseMagnitudes {
    /// Corrected up direction of each pose.
    up: Vec<Vec3>,
    /// |corrected specific force| - g at each pose, m/s^2.
    error_m_s2: Vec<f64>,
    /// RMS of `error_m_s2`, m/s^2.
    rms_m_s2: f64,
    /// Per axis: RMS of the magnitude error as a vector along gravity, m/s^2.
    axis_rms_m_s2: [f64; 3],
}

impl PoseMagnitudes {
    /// Corrects each pose's `measured` mean under `model` and compares its magnitude with
    /// `g_m_s2`.
    fn of(model: &TriadModel, measured: &[Vec3], conditions: &[Conditions], g_m_s2: f64) -> Self {
        let corrected: Vec<Vec3> = measured
            .iter()
            .zip(conditions)
            .map(|(m, c)| model.inverse(*m, c))
            .collect();
        let magnitude_error_m_s2: Vec<f64> = corrected.iter().map(|f| f.norm() - g_m_s2).collect();
        let up: Vec<Vec3> = corrected.iter().map(|f| f.normalize()).collect();
        let n = corrected.len() as f64;
        let rms = (magnitude_error_m_s2.iter().map(|e| e * e).sum::<f64>() / n).sqrt();
        // Per axis: the magnitude error as a vector along gravity.
        let mut sq = [0.0; 3];
        for (u, e) in up.iter().zip(&magnitude_error_m_s2) {
            for a in 0..3 {
                sq[a] += (u[a] * e).powi(2) / n;
            }
        }
        PoseMagnitudes {
            up,
            error_m_s2: magnitude_error_m_s2,
            rms_m_s2: rms,
            axis_rms_m_s2: sq.map(f64::sqrt),
        }
    }
}

/// Warns of each accel axis that never pointed within 45 degrees of up or of down.
fn push_axis_coverage_warnings(up: &[Vec3], warnings: &mut Vec<FitWarning>) {
    for a in 0..3 {
        let hi = up.iter().map(|u| u[a]).fold(f64::NEG_INFINITY, f64::max);
        let lo = up.iter().map(|u| u[a]).fold(f64::INFINITY, f64::min);
        // 0.7 ~ cos 45 degrees.
        if hi < 0.7 || lo > -0.7 {
            // The sentence names its axis itself ("accel x: ..."): no scope prefix.
            warnings.push(FitWarning::of_fit(FitWarningKind::AxisNeverPointed {
                axis: a,
                up: hi < 0.7,
                down: lo > -0.7,
                lo_g: lo,
                hi_g: hi,
            }));
        }
    }
}

/// The whitened magnitude residual `(|corrected mean| - g) / sigma` of each pose with
/// parameters `p` set in `work`.
fn magnitude_residuals(
    work: &mut TriadModel,
    p: &[f64],
    measured: &[Vec3],
    conditions: &[Conditions],
    sigma_m_s2: &[f64],
    g_m_s2: f64,
) -> DVector<f64> {
    work.set_params(p);
    DVector::from_iterator(
        measured.len(),
        measured
            .iter()
            .zip(conditions)
            .zip(sigma_m_s2)
            .map(|((m, c), s)| (work.inverse(*m, c).norm() - g_m_s2) / s),
    )
}

/// The parameters the fit does not give: the gauge held at 0, those held on request, and
/// those the poses cannot observe.
fn accel_unobservable(
    gauge: &[usize],
    names: &[String],
    requested: &[bool],
    sol: &LsqSolution,
) -> Vec<Unobservable> {
    let mut unobservable: Vec<Unobservable> = gauge
        .iter()
        .map(|&i| Unobservable {
            name: names[i].clone(),
            reason: NotFitted::Gauge,
        })
        .collect();
    unobservable.extend(held_entries(names, requested));
    unobservable.extend(sol.unobservable.iter().cloned());
    unobservable
}

/// An error when there are no more poses than free parameters.
fn check_enough_poses(
    model: &TriadModel,
    n_poses: usize,
    n_free: usize,
    still_s: f64,
) -> Result<(), ReferenceFreeError> {
    if n_poses <= n_free {
        return Err(ReferenceFreeError::TooFewPoses {
            triad: Triad::Accel,
            found: n_poses,
            needed: n_free + 1,
            n_free,
            what: model
                .kinds()
                .iter()
                .map(|k| k.id())
                .collect::<Vec<_>>()
                .join(", "),
            still_s,
        });
    }
    Ok(())
}
