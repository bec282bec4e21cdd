//! Holding a model against the observations: verdict per axis, residual structure, spectral
//! lines and every library effect not in the model tried as a candidate.

use super::*;

/// What every candidate is held against: the model's fit and the statistics of its residuals.
pub(super) struct CandidateBase<'b> {
    /// Which triad.
    pub(super) triad: Triad,
    /// The fittable model under test.
    model: &'b TriadModel,
    /// The flicker family of the model's profiled drift, per axis.
    pub(super) family: [bool; 3],
    /// The model's profiled fit.
    pub(super) profiled: &'b Profiled,
    /// The triad's fit points.
    pub(super) points: &'b [FitPoint],
    /// The floor measured in the segments, per axis.
    shared: &'b [SharedNoise; 3],
    /// The model's chi-square against `shared`.
    chi2: f64,
    /// The model's chi-square over its degrees of freedom (at least 1e-12).
    excess: f64,
    /// Number of residuals.
    n_obs: f64,
    /// The model's residuals, each over its standard error.
    base_pattern: Vec<f64>,
}

/// The residuals held against a profiled drift as well as the measured floor.
struct DriftCheck {
    /// The profiled drift per axis, in the triad's units.
    wander: [Wander; 3],
    /// P-value of the chi-square with the drift added to the floor.
    p_value: f64,
    /// Expected residual RMS per axis with the drift added.
    floor_rms: [f64; 3],
}

/// The model's residuals held against the measured floor, for [`Workbench::diagnose`].
struct ResidualExamination {
    /// Chi-square per axis.
    chi2_axis: [f64; 3],
    /// Their sum.
    chi2: f64,
    /// Its p-value at the fit's degrees of freedom.
    p_value: f64,
    /// Residual per segment.
    segments: Vec<SegmentResidual>,
    /// The worst segments (indices into `segments`).
    worst: Vec<usize>,
    /// What the residuals of each axis correlate with.
    structure: [Structure; 3],
}

impl<'a> Workbench<'a> {
    /// Holds `model` against the recording's `triad`: verdict, residuals, structure, and every
    /// library effect not in the model tried as a candidate.
    pub fn diagnose(
        &self,
        triad: Triad,
        model: &TriadModel,
    ) -> Result<TriadDiagnosis, DiagnoseError> {
        let full_model = model.clone();
        let (model, _) = self.fittable(triad, model);
        let profiled = self.fit(triad, &model, None)?;
        let base = profiled.fit.clone();
        let (_, _, floor) = self.points(triad);
        let dof = base.dof;
        let shared = self.shared(triad);
        let ResidualExamination {
            chi2_axis,
            chi2,
            p_value,
            segments,
            worst,
            structure,
        } = self.examine_residuals(triad, &base, &shared);
        let spectral_lines = self.spectral[usize::from(triad == Triad::Gyro)].clone();

        // Candidates.
        let context = self.candidate_base(triad, &model, &profiled, &shared, chi2);
        let mut candidates = self.candidates(&context);
        let consistent_before = p_value >= self.opts.alpha;
        let ambiguities = rank_and_claim(&mut candidates, consistent_before, triad, &self.opts);
        self.confirm_claim(&context, &mut candidates);
        let drift = self.drift_check(triad, &profiled, &base, &shared);
        let (wander, p_value_with_drift) = (drift.wander, drift.p_value);
        let axes = self.axis_verdicts(triad, &base, &chi2_axis, &shared, drift.floor_rms);
        let consistent = consistent_before && spectral_lines.is_empty();
        let consistent_with_drift = (consistent_before || p_value_with_drift >= self.opts.alpha)
            && spectral_lines.is_empty();
        let facts = VerdictFacts {
            triad,
            model: &model,
            consistent: consistent_before,
            with_drift: (p_value_with_drift >= self.opts.alpha)
                .then_some((p_value_with_drift, wander)),
            p_value,
            axes: &axes,
            candidates: &candidates,
            ambiguities: &ambiguities,
            structure: &structure,
            lines: &spectral_lines,
        };
        let (verdict, state) = (verdict(&facts), verdict_state(&facts));
        let mut diagnosis = TriadDiagnosis {
            triad,
            effects: model.kinds(),
            noise_scale: profiled.scale,
            drift_random_walk: wander.map(|w| w.random_walk_q.sqrt()),
            drift_bias_instability: wander.map(|w| w.bias_instability()),
            chi2,
            dof,
            p_value,
            consistent,
            consistent_with_drift,
            p_value_with_drift,
            axes,
            segments,
            worst,
            structure,
            spectral_lines,
            candidates,
            ambiguities,
            verdict,
            state,
            fit: base,
            noise_floor: floor.clone(),
            moves: None,
        };
        if triad == Triad::Gyro && self.reference_free_magnitude().is_some() {
            self.add_moves(&full_model, &mut diagnosis)?;
        }
        Ok(diagnosis)
    }

    /// What every candidate for `triad` is held against: the `model`'s `profiled` fit, its
    /// chi-square `chi2` against the measured floor `shared` and its residual pattern.
    fn candidate_base<'b>(
        &'b self,
        triad: Triad,
        model: &'b TriadModel,
        profiled: &'b Profiled,
        shared: &'b [SharedNoise; 3],
        chi2: f64,
    ) -> CandidateBase<'b> {
        let (points, _, _) = self.points(triad);
        let base = &profiled.fit;
        CandidateBase {
            triad,
            model,
            family: profiled.wander.map(|w| w.flicker),
            profiled,
            points,
            shared,
            chi2,
            excess: (chi2 - base.dof as f64).max(1e-12),
            n_obs: self.n_residuals(triad) as f64,
            base_pattern: normalised(&base.residuals, points),
        }
    }

    /// The verdict's statistics: the residuals of `base` against the floor measured in the
    /// segments (white and flicker); a random walk the segments cannot resolve is not assumed
    /// (the candidate tests profile it). Also per segment, the worst, and their structure.
    fn examine_residuals(
        &self,
        triad: Triad,
        base: &FitResult,
        shared: &[SharedNoise; 3],
    ) -> ResidualExamination {
        let (points, _, _) = self.points(triad);
        let chi2_axis = self.chi2_axes(triad, &base.residuals, shared);
        let chi2: f64 = chi2_axis.iter().sum();
        let p_value = distributions::chi2_sf(chi2, base.dof as f64);
        let segments = self.segment_residuals(triad, &base.residuals, shared);
        let worst = worst_segments(&segments);
        let signals = signals(points, triad);
        let structure = std::array::from_fn(|a| residual_structure(&segments, &signals, a));
        ResidualExamination {
            chi2_axis,
            chi2,
            p_value,
            segments,
            worst,
            structure,
        }
    }

    /// The verdict per axis against the measured floor; `with_drift_rms` is the floor with the
    /// profiled drift added (from [`Workbench::drift_check`]).
    fn axis_verdicts(
        &self,
        triad: Triad,
        base: &FitResult,
        chi2_axis: &[f64; 3],
        shared: &[SharedNoise; 3],
        with_drift_rms: [f64; 3],
    ) -> [AxisVerdict; 3] {
        let n = self.points(triad).0.len();
        let dof = base.dof;
        let axis_dof: [f64; 3] = match self.magnitude(triad) {
            // One residual per pose, shared by the axes by their squared direction cosines.
            Some(mag) => std::array::from_fn(|a| {
                let share = mag.dirs.iter().map(|u| u[a] * u[a]).sum::<f64>() / n.max(1) as f64;
                (share * dof as f64).max(1.0)
            }),
            None => [(n as f64 - base.free.len() as f64 / 3.0).max(1.0); 3],
        };
        let floor_expected = self.expected_rms(triad, &base.jacobian_raw, shared);
        std::array::from_fn(|a| {
            let dof_a = axis_dof[a];
            AxisVerdict {
                residual_rms: base.residual_rms[a],
                noise_floor_rms: floor_expected[a],
                noise_floor_with_drift_rms: with_drift_rms[a],
                chi2: chi2_axis[a],
                dof: dof_a,
                p_value: distributions::chi2_sf(chi2_axis[a], dof_a),
            }
        })
    }

    /// Each fit point's residual with its noise floor and z-score.
    fn segment_residuals(
        &self,
        triad: Triad,
        residuals: &[[f64; 3]],
        shared: &[SharedNoise; 3],
    ) -> Vec<SegmentResidual> {
        let (points, index, _) = self.points(triad);
        let n = points.len();
        let magnitude_sd: Option<Vec<f64>> = self.magnitude(triad).map(|mag| {
            let c = mag.covariance(points, shared);
            (0..n).map(|k| c[(k, k)].max(0.0).sqrt()).collect()
        });
        points
            .iter()
            .zip(index)
            .zip(residuals)
            .enumerate()
            .map(|(k, ((p, &i), r))| {
                let s = &self.obs.segmentation.segments[i];
                let fl: [f64; 3] = match (&magnitude_sd, self.magnitude(triad)) {
                    // The magnitude's noise, split like the residual along the pose's direction.
                    (Some(sd), Some(mag)) => {
                        std::array::from_fn(|a| (sd[k] * mag.dirs[k][a].abs()).max(1e-300))
                    }
                    _ => [p.std_error[0], p.std_error[1], p.std_error[2]],
                };
                SegmentResidual {
                    segment: i,
                    kind: s.kind,
                    start_s: s.start_s,
                    end_s: s.end_s,
                    residual: *r,
                    floor: fl,
                    z: std::array::from_fn(|a| r[a] / fl[a]),
                }
            })
            .collect()
    }

    /// Every library effect that applies to the triad and is not in the model, tested (each
    /// on its own, so spread over the cores).
    fn candidates(&self, c: &CandidateBase) -> Vec<Candidate> {
        let kinds: Vec<EffectKind> = EffectKind::ALL
            .into_iter()
            .filter(|k| k.applies_to(c.triad) && !c.model.has(*k))
            .collect();
        parallel_map(&kinds, |&k| self.candidate(c, k))
            .into_iter()
            .flatten()
            .collect()
    }

    /// Effect `k` added to the model and tested: a scored candidate, or one that says why it
    /// cannot be observed; `None` when its fit fails.
    fn candidate(&self, c: &CandidateBase, k: EffectKind) -> Option<Candidate> {
        let (triad, base) = (c.triad, &c.profiled.fit);
        let mut m = c.model.clone();
        m.add(k);
        let (m, held) = self.fittable(triad, &m);
        if !m.has(k) {
            return Some(unobservable_candidate(
                k,
                triad,
                vec![held.map_or(NotObservable::NotFittable, NotObservable::Held)],
            ));
        }
        let prof = self.fit_candidate(triad, &m, k, c.family)?;
        let r = prof.fit.clone();
        let new_params = r.free.len().saturating_sub(base.free.len());
        let not_obs: Vec<NotObservable> = r
            .unobservable
            .iter()
            .filter(|u| of_effect(&r.model.param_ids(), &u.name, k))
            .map(|u| NotObservable::Parameter(u.clone()))
            .collect();
        if new_params == 0 || r.dof == 0 {
            return Some(unobservable_candidate(k, triad, not_obs));
        }
        // Likelihood ratio with the noise scale and drift profiled in both models, as an
        // F statistic (exact for a linear model with one profiled scale).
        let lr = (2.0 * (prof.loglik - c.profiled.loglik)).max(0.0);
        let dof2 = (c.n_obs - r.free.len() as f64 - self.n_profiled(triad)).max(1.0);
        let f = (lr / c.n_obs).exp_m1() * dof2 / new_params as f64;
        let p = distributions::f_sf(f, new_params as f64, dof2);
        if p >= self.opts.alpha {
            // Not significant, and its values say nothing: show why instead of them.
            let weak = barely_excited(k, &r, span_s(c.points));
            if !weak.is_empty() {
                return Some(unobservable_candidate(k, triad, weak));
            }
        }
        let cand_chi2: f64 = self.chi2_axes(triad, &r.residuals, c.shared).iter().sum();
        let d_chi2 = (c.chi2 - cand_chi2).max(0.0);
        let pattern: Vec<f64> = normalised(&r.residuals, c.points)
            .iter()
            .zip(&c.base_pattern)
            .map(|(a, b)| b - a)
            .collect();
        let ids = r.model.param_ids();
        let params = effect_params(k, ParamTable::of(&r, &ids));
        let score = CandidateScore {
            effect: k,
            triad,
            new_params,
            not_observable: not_obs,
            chi2: cand_chi2,
            dof: r.dof,
            f,
            p_value: p,
            likelihood_ratio: lr,
            explained_chi2: d_chi2,
            excess_chi2: c.excess,
            residual_rms: r.residual_rms,
            explanation: explain(k, triad, &params, r.residual_rms),
            model_change: model_change(triad, &r.model, k),
            params,
            model: r.model,
            pattern,
        };
        Some(score.into_candidate(self.opts.alpha))
    }

    /// The residuals of `base` held against the floor plus the drift profiled in its fit.
    fn drift_check(
        &self,
        triad: Triad,
        profiled: &Profiled,
        base: &FitResult,
        shared: &[SharedNoise; 3],
    ) -> DriftCheck {
        let wander: [Wander; 3] =
            std::array::from_fn(|a| profiled.wander[a].absolute(profiled.scale[a]));
        let with_drift: [SharedNoise; 3] = std::array::from_fn(|a| wander[a].added(&shared[a]));
        let chi2_drift: f64 = self
            .chi2_axes(triad, &base.residuals, &with_drift)
            .iter()
            .sum();
        let mut drift_params = wander.iter().filter(|w| !w.is_none()).count();
        if self.magnitude(triad).is_some() {
            // One wander, common to the axes.
            drift_params = drift_params.min(1);
        }
        let p_value = distributions::chi2_sf(
            chi2_drift,
            base.dof.saturating_sub(drift_params).max(1) as f64,
        );
        let floor_rms = self.expected_rms(triad, &base.jacobian_raw, &with_drift);
        DriftCheck {
            wander,
            p_value,
            floor_rms,
        }
    }

    /// Reference-free gyro: the gains are held against the moves between poses. Merges the
    /// gains into the fit and the candidates' models, adds the moves' candidates, ambiguities,
    /// text and verdict to `d`.
    fn add_moves(
        &self,
        full_model: &TriadModel,
        d: &mut TriadDiagnosis,
    ) -> Result<(), DiagnoseError> {
        let m = self.diagnose_moves(full_model, &d.fit.model)?;
        d.consistent &= m.verdict.consistent;
        d.consistent_with_drift &= m.verdict.consistent;
        if !m.verdict.consistent
            && matches!(
                d.state,
                VerdictState::Consistent
                    | VerdictState::BiasWander
                    | VerdictState::PeriodicComponent
            )
        {
            d.state = VerdictState::GainsInconsistent;
        }
        d.verdict.moves = Some(m.finding);
        // Every model handed on (to the ladder, into the calibration) is the whole gyro
        // model: the offsets from the still poses, the gains from the moves.
        d.fit.model = merged(full_model, &[&d.fit.model, &m.gains]);
        for c in &mut d.candidates {
            if let Some(model) = c.model.as_mut() {
                let mut spec = full_model.clone();
                spec.add(c.effect);
                *model = merged(&spec, &[model, &m.gains]);
            }
        }
        d.candidates.extend(m.candidates);
        sort_candidates(&mut d.candidates);
        d.ambiguities.extend(m.ambiguities);
        d.moves = Some(m.verdict);
        Ok(())
    }
}

/// Indices of the five segments with the largest |z| on any axis, largest first.
fn worst_segments(segments: &[SegmentResidual]) -> Vec<usize> {
    let mut worst: Vec<usize> = (0..segments.len()).collect();
    let zmax = |s: &SegmentResidual| s.z.iter().map(|v| v.abs()).fold(0.0, f64::max);
    worst.sort_by(|&a, &b| zmax(&segments[b]).total_cmp(&zmax(&segments[a])));
    worst.truncate(5);
    worst
}
