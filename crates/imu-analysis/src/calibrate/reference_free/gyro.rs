//! The gyro: offsets (bias, g-sensitivity, ...) from the still-pose means with Earth's rate as
//! the input, merged with the gains from the moves.

use super::*;

/// Gyro offsets (bias, g-sensitivity, ...) from the still-pose means with `fit.rs`.
pub(super) fn fit_gyro_static(
    poses: &[&Segment],
    up: &[Vec3],
    conditions: &[Conditions],
    model: &TriadModel,
    opts: &ReferenceFreeOptions,
    g_m_s2: f64,
) -> Result<FitResult, FitError> {
    let (vertical_rad_s, horizontal_rad_s) = match opts.latitude_deg {
        Some(lat) => imu_model::earth::earth_rate_split_rad_s(lat),
        None => (0.0, EARTH_RATE_RAD_S),
    };
    let points: Vec<FitPoint> = poses
        .iter()
        .zip(up)
        .zip(conditions)
        .map(|((s, u), c)| FitPoint {
            // Specific force points up at rest, so up is the unit's z in the local level frame.
            true_input: u * vertical_rad_s,
            measured: s.mean_gyro(),
            std_error: mean_se(s.std_gyro_rad_s, s.n),
            conditions: Conditions {
                specific_force_m_s2: u * g_m_s2,
                ..*c
            },
            t_s: 0.5 * (s.start_s + s.end_s),
            duration_s: s.end_s - s.start_s,
        })
        .collect();
    let fit_opts = FitOptions {
        max_iterations: opts.lsq.max_iterations,
        tolerance: opts.lsq.tolerance,
        min_eigenvalue: opts.lsq.min_eigenvalue,
        fixed: held(Triad::Gyro, &model.param_names(Triad::Gyro), &opts.hold),
        bias_input_uncertainty: Some([horizontal_rad_s; 3]),
        mean_noise: crate::calibrate::MeanNoise::White {
            bias_drift: opts.gyro_bias_drift_rad_s,
        },
        excess_scatter: crate::calibrate::ExcessScatter::White,
    };
    fit_triad(model, Triad::Gyro, &points, &fit_opts)
}

/// One gyro result from the still-pose offset fit and the move gain fit.
pub(super) fn merge_gyro(
    model: &TriadModel,
    offsets: Option<&FitResult>,
    gains: Option<&LsqSolution>,
    moves: &[Move],
    weak: f64,
) -> TriadFit {
    let triad = Triad::Gyro;
    let mut model = model.clone();
    let names = model.param_names(triad);
    let units = model.param_units(triad);
    let mut m = Merged::new(model.params());
    if let Some(o) = offsets {
        m.add_offsets(o, &names);
    }
    if let Some(s) = gains {
        m.add_gains(s, &model, &names, weak);
    }
    m.free_src.sort_by_key(|f| f.0);
    let correlation = m.correlation(offsets, gains);
    let Merged {
        params,
        std_errors,
        unobservable,
        warnings,
        free_src,
    } = m;
    model.set_params(&params);
    store_std_errors(&mut model, &std_errors, &[]);
    if let Some(o) = offsets {
        model.residual_rms = Some(o.residual_rms);
    }
    let n = moves.len().max(1) as f64;
    let residual_rms = (moves.iter().map(|m| m.error_rad.powi(2)).sum::<f64>() / (2.0 * n)).sqrt();
    TriadFit {
        triad,
        model,
        names,
        units,
        params,
        std_errors,
        free: free_src.iter().map(|f| f.0).collect(),
        correlation,
        unobservable,
        residual: "predicted minus measured gravity direction after each move, per component"
            .into(),
        residual_unit: "rad".into(),
        residual_rms,
        n_residuals: 2 * moves.len(),
        chi2: gains.map_or(0.0, |s| s.chi2),
        dof: gains.map_or(0, |s| s.dof),
        reduced_chi2: gains.map_or(f64::NAN, |s| s.reduced_chi2),
        min_eigenvalue: gains.map_or(f64::NAN, |s| s.min_eigenvalue),
        iterations: gains.map_or(0, |s| s.iterations),
        converged: gains.is_none_or(|s| s.converged),
        warnings: warnings.into(),
    }
}

/// The gyro parameters being merged from the offset and gain fits, in the full model's layout.
struct Merged {
    params: Vec<f64>,
    std_errors: Vec<Option<f64>>,
    unobservable: Vec<Unobservable>,
    warnings: Vec<FitWarning>,
    /// (index in the merged layout, correlation block id, index in that block's free list)
    free_src: Vec<(usize, usize, usize)>,
}

impl Merged {
    /// Starting from the model's `params`, nothing fitted yet.
    fn new(params: Vec<f64>) -> Self {
        Merged {
            std_errors: vec![None; params.len()],
            params,
            unobservable: Vec::new(),
            warnings: Vec::new(),
            free_src: Vec::new(),
        }
    }

    /// Takes the still-pose offset fit `o` (correlation block 0).
    fn add_offsets(&mut self, o: &FitResult, names: &[String]) {
        for (c, &i) in o.free.iter().enumerate() {
            let j = names.iter().position(|n| *n == o.names[i]).expect("subset");
            self.free_src.push((j, 0, c));
        }
        for (i, n) in o.names.iter().enumerate() {
            let j = names.iter().position(|x| x == n).expect("subset");
            self.params[j] = o.params[i];
            self.std_errors[j] = o.std_errors[i];
        }
        self.unobservable.extend(o.unobservable.iter().cloned());
        self.warnings.extend(
            o.warnings
                .iter()
                .map(|w| w.clone().in_scope(WarningScope::GyroStillPoses)),
        );
    }

    /// Takes the move gain fit `s` of `model`'s gain effects (correlation block 1).
    fn add_gains(&mut self, s: &LsqSolution, model: &TriadModel, names: &[String], weak: f64) {
        let triad = Triad::Gyro;
        let gain_names: Vec<String> = {
            let mut g = TriadModel::default();
            for k in model.kinds() {
                if k.is_gain() {
                    g.add(k);
                }
            }
            g.param_names(triad)
        };
        for (c, &i) in s.free.iter().enumerate() {
            let j = names
                .iter()
                .position(|n| *n == gain_names[i])
                .expect("subset");
            self.free_src.push((j, 1, c));
        }
        for (i, n) in gain_names.iter().enumerate() {
            let j = names.iter().position(|x| x == n).expect("subset");
            self.params[j] = s.params[i];
            self.std_errors[j] = s.std_errors[i];
        }
        self.unobservable.extend(s.unobservable.iter().cloned());
        self.warnings.extend(conditioning_warnings(
            triad,
            s,
            &gain_names,
            weak,
            Evidence::Moves,
        ));
    }

    /// The correlation of the free parameters: each fit's own block, zero between the fits.
    fn correlation(
        &self,
        offsets: Option<&FitResult>,
        gains: Option<&LsqSolution>,
    ) -> Vec<Vec<f64>> {
        self.free_src
            .iter()
            .map(|a| {
                self.free_src
                    .iter()
                    .map(|b| match (a.1, b.1) {
                        (0, 0) => offsets.map_or(0.0, |o| o.correlation[a.2][b.2]),
                        (1, 1) => gains.map_or(0.0, |s| s.correlation[a.2][b.2]),
                        _ => 0.0,
                    })
                    .collect()
            })
            .collect()
    }
}

/// `diag(1 + s) (I + M)` of a triad model's scale and misalignment (identity where absent).
pub(super) fn gain_matrix(m: &TriadModel) -> Matrix3<f64> {
    let s = m.scale.as_ref().map_or([0.0; 3], |s| s.value);
    let mis = m
        .misalignment
        .as_ref()
        .map_or(Matrix3::identity(), |x| x.matrix());
    Matrix3::from_diagonal(&Vec3::new(1.0 + s[0], 1.0 + s[1], 1.0 + s[2])) * mis
}

/// Writes `k = diag(1 + s) (I + M)` back as scale and misalignment effects of `m`.
pub(super) fn set_gain_matrix(m: &mut TriadModel, k: &Matrix3<f64>) {
    m.add(EffectKind::Scale);
    m.add(EffectKind::Misalignment);
    if let Some(s) = m.scale.as_mut() {
        s.value = [k[(0, 0)] - 1.0, k[(1, 1)] - 1.0, k[(2, 2)] - 1.0];
    }
    if let Some(x) = m.misalignment.as_mut() {
        let r = |i: usize, j: usize| k[(i, j)] / k[(i, i)];
        (x.xy, x.xz, x.yx, x.yz, x.zx, x.zy) =
            (r(0, 1), r(0, 2), r(1, 0), r(1, 2), r(2, 0), r(2, 1));
    }
}
