//! Reference-free: the gyro gains held against the rotations integrated over the moves between
//! poses.

use super::*;

impl<'a> Workbench<'a> {
    /// Reference-free: the gyro gain effects of `full` fitted to the rotations integrated over
    /// the moves between poses, their verdict against the moves' noise, and every library gain
    /// effect not in the model tried as a candidate (F test with the scale profiled, AIC,
    /// share of the excess). `offsets` is the still-pose fit (its values join each candidate's
    /// model).
    pub(super) fn diagnose_moves(
        &self,
        full: &TriadModel,
        offsets: &TriadModel,
    ) -> Result<MovesDiagnosis, DiagnoseError> {
        use crate::calibrate::reference_free::{GYRO_GAIN_KINDS, fit_gains};
        let triad = Triad::Gyro;
        let gain_model = |kinds: &[EffectKind]| {
            let mut g = TriadModel::default();
            for k in kinds {
                g.add(*k);
            }
            merged(&g, &[full])
        };
        let kinds: Vec<EffectKind> = full
            .kinds()
            .into_iter()
            .filter(|k| GYRO_GAIN_KINDS.contains(k))
            .collect();
        let lsq = imu_stats::lsq::LsqOptions {
            max_iterations: self.opts.fit.max_iterations,
            tolerance: self.opts.fit.tolerance,
            min_eigenvalue: self.opts.fit.min_eigenvalue,
            ..imu_stats::lsq::LsqOptions::default()
        };
        let n_res = 2 * self.moves.len();
        // Whitened residuals of a gain model (nothing fitted when it has no parameters).
        let whitened = |g: &TriadModel| -> Vec<f64> {
            self.moves
                .iter()
                .flat_map(|m| m.residual(g).map(|v| v / m.sigma_rad))
                .collect()
        };
        let raw_rms = |g: &TriadModel| -> f64 {
            let sq: f64 = self
                .moves
                .iter()
                .map(|m| m.residual(g).iter().map(|v| v * v).sum::<f64>())
                .sum();
            (sq / n_res.max(1) as f64).sqrt()
        };
        let fit =
            |g: &TriadModel| -> Result<(TriadModel, Option<imu_stats::lsq::LsqSolution>), FitError> {
                if g.n_params() == 0 {
                    return Ok((g.clone(), None));
                }
                let sol = fit_gains(&self.moves, g, &vec![false; g.n_params()], &lsq).map_err(
                    |e| match e {
                        imu_stats::lsq::LsqError::TooFewResiduals {
                            n_residuals,
                            n_free,
                        } => FitError::TooFewObservations {
                            triad,
                            n_points: self.moves.len(),
                            n_obs: n_residuals,
                            n_free,
                        },
                        _ => FitError::NothingToFit { triad },
                    },
                )?;
                let mut m = g.clone();
                m.set_params(&sol.params);
                Ok((m, Some(sol)))
            };
        let chi2_of = |g: &TriadModel| whitened(g).iter().map(|v| v * v).sum::<f64>();
        let (gains, sol0) = fit(&gain_model(&kinds))?;
        let free0 = sol0.as_ref().map_or(0, |s| s.free.len());
        let chi2_0 = chi2_of(&gains);
        let dof_0 = n_res.saturating_sub(free0).max(1);
        let p0 = distributions::chi2_sf(chi2_0, dof_0 as f64);
        let expected_rms_rad = (self
            .moves
            .iter()
            .map(|m| m.sigma_rad * m.sigma_rad)
            .sum::<f64>()
            / self.moves.len().max(1) as f64)
            .sqrt();
        let verdict = MovesVerdict {
            n_moves: self.moves.len(),
            skipped: self.moves_skipped,
            effects: kinds.clone(),
            residual_rms_rad: raw_rms(&gains),
            expected_rms_rad,
            chi2: chi2_0,
            dof: dof_0,
            p_value: p0,
            consistent: p0 >= self.opts.alpha,
        };
        let base_pattern = whitened(&gains);
        let excess = (chi2_0 - dof_0 as f64).max(1e-12);
        let mut candidates: Vec<Candidate> = GYRO_GAIN_KINDS
            .into_iter()
            .filter(|k| !kinds.contains(k))
            .map(|k| {
                let mut with = kinds.clone();
                with.push(k);
                let Ok((g, Some(sol))) = fit(&gain_model(&with)) else {
                    return unobservable_candidate(k, triad, "the moves cannot fit it".into());
                };
                let new_params = sol.free.len().saturating_sub(free0);
                let not_obs: Vec<String> = sol
                    .unobservable
                    .iter()
                    .filter(|u| u.name.starts_with(k.id()))
                    .map(|u| format!("{}: {}", u.name, u.reason))
                    .collect();
                if new_params == 0 || sol.dof == 0 {
                    let mut c = unobservable_candidate(k, triad, not_obs.join("; "));
                    c.not_observable = not_obs;
                    return c;
                }
                let chi2_1 = chi2_of(&g).max(1e-300);
                let f = ((chi2_0 - chi2_1).max(0.0) / new_params as f64)
                    / (chi2_1 / sol.dof.max(1) as f64);
                let p = distributions::f_sf(f, new_params as f64, sol.dof.max(1) as f64);
                let lr = n_res as f64 * (chi2_0 / chi2_1).ln();
                let pattern: Vec<f64> = whitened(&g)
                    .iter()
                    .zip(&base_pattern)
                    .map(|(a, b)| b - a)
                    .collect();
                let rms = raw_rms(&g);
                let residuals: Vec<[f64; 3]> = self
                    .moves
                    .iter()
                    .map(|m| {
                        let [a, b] = m.residual(&g);
                        [a, b, 0.0]
                    })
                    .collect();
                let mut spec = full.clone();
                spec.add(k);
                let r = FitResult {
                    triad,
                    model: merged(&spec, &[offsets, &g]),
                    names: g.param_names(triad),
                    units: g.param_units(triad),
                    params: sol.params.clone(),
                    std_errors: sol.std_errors.clone(),
                    correlation: sol.correlation.clone(),
                    free: sol.free.clone(),
                    unobservable: sol.unobservable.clone(),
                    residual_rms: [rms; 3],
                    residuals,
                    jacobian_raw: DMatrix::zeros(0, 0),
                    chi2: chi2_1,
                    chi2_axis: [chi2_1 / 3.0; 3],
                    dof: sol.dof,
                    reduced_chi2: sol.reduced_chi2,
                    drift_random_walk: [0.0; 3],
                    iterations: sol.iterations,
                    converged: sol.converged,
                    warnings: Vec::new(),
                };
                let params = effect_params(&r, k);
                let best = params
                    .iter()
                    .max_by(|a, b| {
                        let t = |p: &ParamValue| p.std_error.map_or(0.0, |s| (p.value / s).abs());
                        t(a).total_cmp(&t(b))
                    })
                    .map(|p| {
                        format!(
                            " ({} = {:.3e}{} {})",
                            p.name,
                            p.value,
                            p.std_error
                                .map_or(String::new(), |e| format!(" +/- {e:.1e}")),
                            p.unit
                        )
                    })
                    .unwrap_or_default();
                Candidate {
                    effect: k,
                    triad,
                    new_params,
                    not_observable: not_obs,
                    chi2: chi2_1,
                    dof: sol.dof,
                    f,
                    p_value: p,
                    delta_aic: lr - 2.0 * new_params as f64,
                    share_of_excess: (chi2_0 - chi2_1).max(0.0) / excess,
                    residual_rms: [rms; 3],
                    significant: p < self.opts.alpha,
                    claimed: false,
                    explanation: format!(
                        "{}{best}: the rotations integrated over the moves between poses \
                         need it; direction error after the moves {:.2e} rad RMS with it, \
                         {:.2e} rad without",
                        k.description(),
                        rms,
                        verdict.residual_rms_rad
                    ),
                    model_change: model_change(triad, &r.model, k),
                    params,
                    fit: Some(r),
                    pattern,
                }
            })
            .collect();
        let ambiguities = rank_and_claim(&mut candidates, verdict.consistent, triad, &self.opts);
        let mut text = format!(
            "Gyro gains [{}] against {} moves between poses: direction error {:.2e} rad RMS vs \
             {:.2e} expected (p = {:.1e}): {}.",
            kinds.iter().map(|k| k.id()).collect::<Vec<_>>().join(", "),
            verdict.n_moves,
            verdict.residual_rms_rad,
            verdict.expected_rms_rad,
            p0,
            if verdict.consistent {
                "consistent"
            } else {
                "NOT consistent"
            }
        );
        if let Some(c) = candidates.iter().find(|c| c.claimed) {
            let _ = write!(
                text,
                " Missing gain effect: {} (F-test p = {:.1e}, explains {:.0} % of the excess).",
                c.explanation,
                c.p_value,
                100.0 * c.share_of_excess.min(1.0)
            );
        }
        Ok(MovesDiagnosis {
            verdict,
            candidates,
            ambiguities,
            gains,
            text,
        })
    }
}
