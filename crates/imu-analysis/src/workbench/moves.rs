//! Reference-free: the gyro gains held against the rotations integrated over the moves between
//! poses.

use super::*;
use crate::calibrate::reference_free::{MoveData, fit_gains, move_residuals};
use imu_stats::lsq::{LsqError, LsqOptions, LsqSolution};

/// Gain models fitted to the moves between poses, and their residuals.
struct MovesFitter<'w> {
    /// The moves (the rate corrected by the model's offsets).
    moves: &'w [MoveData],
    /// The whole gyro model (its values seed the gain models).
    full: &'w TriadModel,
    /// Settings of the least-squares engine.
    lsq: LsqOptions,
    /// Number of residuals: two per move.
    n_res: usize,
}

impl MovesFitter<'_> {
    /// The gain model with effects `kinds`, its values taken from the whole model.
    fn gain_model(&self, kinds: &[EffectKind]) -> TriadModel {
        let mut g = TriadModel::default();
        for k in kinds {
            g.add(*k);
        }
        merged(&g, &[self.full])
    }

    /// Whitened residuals of a gain model (nothing fitted when it has no parameters).
    fn whitened(&self, g: &TriadModel) -> Vec<f64> {
        self.moves
            .iter()
            .zip(move_residuals(self.moves, g))
            .flat_map(|(m, r)| r.map(|v| v / m.sigma_rad))
            .collect()
    }

    /// RMS of the direction errors of a gain model, rad.
    fn raw_rms(&self, g: &TriadModel) -> f64 {
        let sq: f64 = move_residuals(self.moves, g)
            .iter()
            .map(|r| r.iter().map(|v| v * v).sum::<f64>())
            .sum();
        (sq / self.n_res.max(1) as f64).sqrt()
    }

    /// Chi-square of the whitened residuals of a gain model.
    fn chi2_of(&self, g: &TriadModel) -> f64 {
        self.whitened(g).iter().map(|v| v * v).sum::<f64>()
    }

    /// Fits gain model `g` to the moves (returned as is, without a solution, when it has no
    /// parameters).
    fn fit(&self, g: &TriadModel) -> Result<(TriadModel, Option<LsqSolution>), FitError> {
        let triad = Triad::Gyro;
        if g.n_params() == 0 {
            return Ok((g.clone(), None));
        }
        let sol =
            fit_gains(self.moves, g, &vec![false; g.n_params()], &self.lsq).map_err(
                |e| match e {
                    LsqError::TooFewResiduals {
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
    }
}

/// The model's gain fit, that every candidate is held against.
struct MovesBaseline<'b> {
    /// The model's gain effects.
    kinds: &'b [EffectKind],
    /// The still-pose fit (its values join each candidate's model).
    offsets: &'b TriadModel,
    /// Number of free parameters of the model's gain fit.
    free0: usize,
    /// Chi-square of the model's gain fit.
    chi2_0: f64,
    /// The model's whitened residuals.
    base_pattern: Vec<f64>,
    /// The chi-square over its degrees of freedom (at least 1e-12).
    excess: f64,
    /// RMS direction error of the model's gain fit, rad.
    residual_rms_rad: f64,
}

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
        let triad = Triad::Gyro;
        let kinds: Vec<EffectKind> = full.kinds().into_iter().filter(|k| k.is_gain()).collect();
        let (moves, skipped) = self.moves_for(offsets);
        let fitter = self.moves_fitter(&moves, full);
        let (gains, sol0) = fitter.fit(&fitter.gain_model(&kinds))?;
        let free0 = sol0.as_ref().map_or(0, |s| s.free.len());
        let chi2_0 = fitter.chi2_of(&gains);
        let dof_0 = fitter.n_res.saturating_sub(free0).max(1);
        let p0 = distributions::chi2_sf(chi2_0, dof_0 as f64);
        let expected_rms_rad = (moves.iter().map(|m| m.sigma_rad * m.sigma_rad).sum::<f64>()
            / moves.len().max(1) as f64)
            .sqrt();
        let verdict = MovesVerdict {
            n_moves: moves.len(),
            skipped,
            effects: kinds.clone(),
            residual_rms_rad: fitter.raw_rms(&gains),
            expected_rms_rad,
            chi2: chi2_0,
            dof: dof_0,
            p_value: p0,
            consistent: p0 >= self.opts.alpha,
        };
        let baseline = MovesBaseline {
            kinds: &kinds,
            offsets,
            free0,
            chi2_0,
            base_pattern: fitter.whitened(&gains),
            excess: (chi2_0 - dof_0 as f64).max(1e-12),
            residual_rms_rad: verdict.residual_rms_rad,
        };
        // Each candidate's gain fit is kept for the held-out check of a claim (the same fit).
        let (mut candidates, fitted): (Vec<Candidate>, Vec<(EffectKind, Option<TriadModel>)>) =
            EffectKind::ALL
                .into_iter()
                .filter(|k| k.is_gain() && !kinds.contains(k))
                .map(|k| {
                    let (c, g) = self.moves_candidate(&fitter, &baseline, k);
                    (c, (k, g))
                })
                .unzip();
        let ambiguities = rank_and_claim(&mut candidates, verdict.consistent, triad, &self.opts);
        for c in candidates.iter_mut().filter(|c| c.claimed) {
            let fit = fitted.iter().find(|(k, _)| *k == c.effect);
            c.held_out = fit
                .and_then(|(_, g)| g.as_ref())
                .and_then(|cand| self.moves_held_out(&fitter, &gains, cand));
            c.claimed = c.held_out.as_ref().is_some_and(|h| h.confirmed);
        }
        let finding = moves_finding(&verdict, &candidates);
        Ok(MovesDiagnosis {
            verdict,
            candidates,
            ambiguities,
            gains,
            finding,
        })
    }

    /// Gain effect `k` added to the model's gains and fitted to the moves: a scored
    /// candidate, or one that says why the moves cannot observe it; with the fitted gain model
    /// when the fit succeeded.
    fn moves_candidate(
        &self,
        fitter: &MovesFitter,
        b: &MovesBaseline,
        k: EffectKind,
    ) -> (Candidate, Option<TriadModel>) {
        let mut with = b.kinds.to_vec();
        with.push(k);
        match fitter.fit(&fitter.gain_model(&with)) {
            Ok((g, Some(sol))) => {
                let c = self.moves_candidate_scored(fitter, b, k, &g, &sol);
                (c, Some(g))
            }
            _ => (
                unobservable_candidate(k, Triad::Gyro, vec![NotObservable::MovesCannotFit]),
                None,
            ),
        }
    }

    /// Gain effect `k` scored from its fit `g` (solution `sol`) to the moves.
    fn moves_candidate_scored(
        &self,
        fitter: &MovesFitter,
        b: &MovesBaseline,
        k: EffectKind,
        g: &TriadModel,
        sol: &LsqSolution,
    ) -> Candidate {
        let triad = Triad::Gyro;
        let (n_res, chi2_0) = (fitter.n_res, b.chi2_0);
        let new_params = sol.free.len().saturating_sub(b.free0);
        let not_obs: Vec<NotObservable> = sol
            .unobservable
            .iter()
            .filter(|u| of_effect(&g.param_ids(), &u.name, k))
            .map(|u| NotObservable::Parameter(u.clone()))
            .collect();
        if new_params == 0 || sol.dof == 0 {
            return unobservable_candidate(k, triad, not_obs);
        }
        let chi2_1 = fitter.chi2_of(g).max(1e-300);
        let f = ((chi2_0 - chi2_1).max(0.0) / new_params as f64) / (chi2_1 / sol.dof.max(1) as f64);
        let p = distributions::f_sf(f, new_params as f64, sol.dof.max(1) as f64);
        let lr = n_res as f64 * (chi2_0 / chi2_1).ln();
        let pattern: Vec<f64> = fitter
            .whitened(g)
            .iter()
            .zip(&b.base_pattern)
            .map(|(a, b)| b - a)
            .collect();
        let rms = fitter.raw_rms(g);
        let mut spec = fitter.full.clone();
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
        let model = merged(&spec, &[b.offsets, g]);
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
            excess_chi2: b.excess,
            residual_rms: [rms; 3],
            explanation: Explanation::Moves {
                effect: k,
                most_significant: most_significant(&params).cloned(),
                rms_with_rad: rms,
                rms_without_rad: b.residual_rms_rad,
            },
            model_change: model_change(triad, &model, k),
            params,
            model,
            pattern,
        }
        .into_candidate(self.opts.alpha)
    }
}

impl<'a> Workbench<'a> {
    /// The moves between poses with the rate corrected for the `offsets` model: the moves
    /// prepared once when its offsets do not vary along a move (a bias), else prepared again
    /// with its offset effects evaluated at every sample.
    fn moves_for(&self, offsets: &TriadModel) -> (std::borrow::Cow<'_, [MoveData]>, usize) {
        let varies = !crate::calibrate::reference_free::varying_offsets(offsets).is_empty();
        match &self.mode {
            Mode::ReferenceFree { setup, .. } if varies => {
                let (m, skipped) = setup.prepare(self.series, &self.obs, Some(offsets));
                (std::borrow::Cow::Owned(m), skipped)
            }
            _ => {
                let (m, skipped) = self.moves();
                (std::borrow::Cow::Borrowed(m), skipped)
            }
        }
    }

    /// The gain fitter over `moves`, seeded from the whole model `full`.
    fn moves_fitter<'w>(&self, moves: &'w [MoveData], full: &'w TriadModel) -> MovesFitter<'w> {
        MovesFitter {
            moves,
            full,
            lsq: LsqOptions {
                max_iterations: self.opts.fit.max_iterations,
                tolerance: self.opts.fit.tolerance,
                min_eigenvalue: self.opts.fit.min_eigenvalue,
                ..LsqOptions::default()
            },
            n_res: 2 * moves.len(),
        }
    }

    /// A candidate gain model `cand` (a gain effect added to the model's gains, fitted to all
    /// moves) held against held-out moves with the model's gains `gains` (also fitted to all
    /// moves): both gain models refitted on the training folds.
    fn moves_held_out(
        &self,
        fitter: &MovesFitter,
        gains: &TriadModel,
        cand: &TriadModel,
    ) -> Option<HeldOut> {
        let sums = |g: &TriadModel, moves: &[MoveData], which: &[usize]| {
            let mut s = WeightedSums::default();
            for &i in which {
                let [a, b] = moves[i].residual(g);
                // Two components per move: their mean square, alike on the three axes.
                let r = ((a * a + b * b) / 2.0).sqrt();
                s.add([r; 3], [moves[i].sigma_rad; 3]);
            }
            s
        };
        let all: Vec<usize> = (0..fitter.moves.len()).collect();
        let in_sample = (
            sums(gains, fitter.moves, &all),
            sums(cand, fitter.moves, &all),
        );
        cross_validate(all.len(), HeldOutUnit::Moves, in_sample, |train, test| {
            let moves: Vec<MoveData> = train.iter().map(|&i| fitter.moves[i].clone()).collect();
            let sub = self.moves_fitter(&moves, fitter.full);
            let g0 = sub.fit(gains).ok()?.0;
            let g1 = sub.fit(cand).ok()?.0;
            Some((sums(&g0, fitter.moves, test), sums(&g1, fitter.moves, test)))
        })
    }
}

/// What the moves say: the verdict, and the claimed missing gain effect or the best gain
/// candidate that held-out moves did not confirm.
fn moves_finding(verdict: &MovesVerdict, candidates: &[Candidate]) -> MovesFinding {
    let outcome = if let Some(c) = candidates.iter().find(|c| c.claimed) {
        MovesOutcome::Claimed(CandidateFacts::of(c))
    } else if let Some(c) = candidates.iter().find(|c| c.held_out.is_some()) {
        MovesOutcome::NotConfirmed(CandidateFacts::of(c))
    } else {
        MovesOutcome::Nothing
    };
    MovesFinding {
        verdict: verdict.clone(),
        outcome,
    }
}
