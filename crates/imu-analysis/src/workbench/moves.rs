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
        use crate::calibrate::reference_free::fit_gains;
        let triad = Triad::Gyro;
        let gain_model = |kinds: &[EffectKind]| {
            let mut g = TriadModel::default();
            for k in kinds {
                g.add(*k);
            }
            merged(&g, &[full])
        };
        let kinds: Vec<EffectKind> = full.kinds().into_iter().filter(|k| k.is_gain()).collect();
        let lsq = imu_stats::lsq::LsqOptions {
            max_iterations: self.opts.fit.max_iterations,
            tolerance: self.opts.fit.tolerance,
            min_eigenvalue: self.opts.fit.min_eigenvalue,
            ..imu_stats::lsq::LsqOptions::default()
        };
        let n_res = 2 * self.moves().0.len();
        // Whitened residuals of a gain model (nothing fitted when it has no parameters).
        let whitened = |g: &TriadModel| -> Vec<f64> {
            self.moves()
                .0
                .iter()
                .flat_map(|m| m.residual(g).map(|v| v / m.sigma_rad))
                .collect()
        };
        let raw_rms = |g: &TriadModel| -> f64 {
            let sq: f64 = self
                .moves()
                .0
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
                let sol = fit_gains(self.moves().0, g, &vec![false; g.n_params()], &lsq).map_err(
                    |e| match e {
                        imu_stats::lsq::LsqError::TooFewResiduals {
                            n_residuals,
                            n_free,
                        } => FitError::TooFewObservations {
                            triad,
                            n_points: self.moves().0.len(),
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
            .moves()
            .0
            .iter()
            .map(|m| m.sigma_rad * m.sigma_rad)
            .sum::<f64>()
            / self.moves().0.len().max(1) as f64)
            .sqrt();
        let verdict = MovesVerdict {
            n_moves: self.moves().0.len(),
            skipped: self.moves().1,
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
        let mut candidates: Vec<Candidate> = EffectKind::ALL
            .into_iter()
            .filter(|k| k.is_gain() && !kinds.contains(k))
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
                    .filter(|u| of_effect(&g.param_ids(), &u.name, k))
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
                let mut spec = full.clone();
                spec.add(k);
                let (ids, units) = (g.param_ids(), g.param_units(triad));
                let params = effect_params(
                    k,
                    ParamTable {
                        ids: &ids,
                        units: &units,
                        params: &sol.params,
                        std_errors: &sol.std_errors,
                    },
                );
                let best = most_significant(&params)
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
                let model = merged(&spec, &[offsets, &g]);
                CandidateScore {
                    effect: k,
                    triad,
                    new_params,
                    not_observable: not_obs,
                    chi2: chi2_1,
                    dof: sol.dof,
                    f,
                    p_value: p,
                    likelihood_ratio: lr,
                    explained_chi2: (chi2_0 - chi2_1).max(0.0),
                    excess_chi2: excess,
                    residual_rms: [rms; 3],
                    explanation: format!(
                        "{}{best}: the rotations integrated over the moves between poses \
                         need it; direction error after the moves {:.2e} rad RMS with it, \
                         {:.2e} rad without",
                        k.description(),
                        rms,
                        verdict.residual_rms_rad
                    ),
                    model_change: model_change(triad, &model, k),
                    params,
                    model,
                    pattern,
                }
                .into_candidate(self.opts.alpha)
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
