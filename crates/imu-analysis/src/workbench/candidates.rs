//! Scoring and ranking candidate effects: merging a candidate into a model, claims and
//! ambiguities, barely excited or unobservable candidates, parameter values.

use super::*;

/// `spec`'s effects with their values taken, by parameter name, from the first of `parts` that
/// has them (else `spec`'s own).
pub(super) fn merged(spec: &TriadModel, parts: &[&TriadModel]) -> TriadModel {
    let t = Triad::Gyro;
    let names = spec.param_names(t);
    let mut p = spec.params();
    for (i, n) in names.iter().enumerate() {
        if let Some(v) = parts.iter().find_map(|m| {
            m.param_names(t)
                .iter()
                .position(|x| x == n)
                .map(|j| m.params()[j])
        }) {
            p[i] = v;
        }
    }
    let mut out = spec.clone();
    out.set_params(&p);
    out
}

/// Observable candidates first, by AIC improvement.
pub(super) fn sort_candidates(c: &mut [Candidate]) {
    c.sort_by(|a, b| {
        (b.new_params > 0)
            .cmp(&(a.new_params > 0))
            .then(b.delta_aic.total_cmp(&a.delta_aic))
    });
}

/// Sorts `candidates`, finds the pairs this recording cannot tell apart (significant, their
/// explained patterns correlated, comparable AIC), and claims the best one when the model is
/// not `consistent` with the noise, it is significant, explains a substantial share of the
/// excess and is not confused with another.
pub(super) fn rank_and_claim(
    candidates: &mut [Candidate],
    consistent: bool,
    triad: Triad,
    opts: &DiagnoseOptions,
) -> Vec<Ambiguity> {
    sort_candidates(candidates);
    let mut ambiguities = Vec::new();
    let sig: Vec<usize> = (0..candidates.len())
        .filter(|&i| candidates[i].significant)
        .collect();
    for (ai, &i) in sig.iter().enumerate() {
        for &j in &sig[ai + 1..] {
            let (ci, cj) = (&candidates[i], &candidates[j]);
            let r = descriptive::correlation(&ci.pattern, &cj.pattern).unwrap_or(0.0);
            // Comparable likelihoods: an AIC difference under 10 (a likelihood ratio under
            // e^5) does not pick one of two non-nested models with confidence.
            let comparable = (ci.delta_aic - cj.delta_aic).abs() < AMBIGUOUS_AIC;
            if r.abs() >= opts.ambiguity_correlation && comparable {
                ambiguities.push(Ambiguity {
                    triad,
                    effects: [ci.effect, cj.effect],
                    correlation: r,
                    separating_recording: Separation::of(ci.effect, cj.effect),
                });
            }
        }
    }
    if let Some(top) = candidates.first_mut() {
        let confused = ambiguities.iter().any(|a| a.effects.contains(&top.effect));
        top.claimed = !consistent
            && top.significant
            && top.share_of_excess.is_some_and(|s| s >= opts.min_share)
            && !confused;
    }
    ambiguities
}

/// Physical upper bound of a lever arm inside an IMU package, m.
pub(super) const MAX_LEVER_ARM_M: f64 = 1.0;

/// Parameters of candidate `k` that the recording excites so weakly that their standard error
/// exceeds any physically possible value (a lever arm seen only through Earth's rate, a
/// time constant longer than the recording): what to say instead of their fitted values.
pub(super) fn barely_excited(k: EffectKind, r: &FitResult, span_s: f64) -> Vec<NotObservable> {
    let ids = r.model.param_ids();
    (0..r.names.len())
        .filter(|&i| ids.get(i).is_some_and(|id| id.effect == k))
        .filter_map(|i| {
            let se = r.std_errors[i]?;
            let name = &r.names[i];
            match k {
                EffectKind::LeverArm if se > MAX_LEVER_ARM_M => {
                    Some(NotObservable::LeverArmBarelyExcited {
                        name: name.clone(),
                        std_error_m: se,
                        max_m: MAX_LEVER_ARM_M,
                    })
                }
                EffectKind::Warmup if ids[i].is_time_constant() && se > span_s => {
                    Some(NotObservable::DecayNotResolved {
                        name: name.clone(),
                        std_error_s: se,
                        span_s,
                    })
                }
                _ => None,
            }
        })
        .collect()
}

/// A candidate for effect `k` that cannot be observed, for the reasons `why`.
pub(super) fn unobservable_candidate(
    k: EffectKind,
    triad: Triad,
    why: Vec<NotObservable>,
) -> Candidate {
    let reasons = NotObservables(why);
    Candidate {
        effect: k,
        triad,
        new_params: 0,
        not_observable: reasons.clone(),
        chi2: f64::NAN,
        dof: 0,
        f: f64::NAN,
        p_value: f64::NAN,
        delta_aic: f64::NEG_INFINITY,
        share_of_excess: None,
        residual_rms: [f64::NAN; 3],
        significant: false,
        claimed: false,
        held_out: None,
        explanation: Explanation::NotObservable { effect: k, reasons },
        params: Vec::new(),
        model_change: String::new(),
        model: None,
        pattern: Vec::new(),
    }
}

pub(super) fn effect_params(k: EffectKind, table: ParamTable<'_>) -> Vec<ParamValue> {
    (0..table.ids.len())
        .filter(|&i| table.ids[i].effect == k)
        .map(|i| ParamValue {
            name: table.ids[i].name.clone(),
            value: table.params[i],
            std_error: table.std_errors[i],
            unit: table.units[i].clone(),
            id: table.ids[i].clone(),
        })
        .collect()
}

/// Whether the parameter named `name` (as in `TriadModel::param_names`) of a model with
/// parameters `ids` belongs to effect `k`.
pub(super) fn of_effect(ids: &[imu_model::ParamId], name: &str, k: EffectKind) -> bool {
    ids.iter().any(|id| id.name == name && id.effect == k)
}

/// A fitted parameter vector with its names, units and standard errors (parallel slices).
#[derive(Clone, Copy)]
pub(super) struct ParamTable<'a> {
    pub(super) ids: &'a [imu_model::ParamId],
    pub(super) units: &'a [String],
    pub(super) params: &'a [f64],
    pub(super) std_errors: &'a [Option<f64>],
}

impl<'a> ParamTable<'a> {
    /// The parameters of a triad fit (`ids` of its model).
    pub(super) fn of(r: &'a FitResult, ids: &'a [imu_model::ParamId]) -> ParamTable<'a> {
        ParamTable {
            ids,
            units: &r.units,
            params: &r.params,
            std_errors: &r.std_errors,
        }
    }
}

/// What both kinds of observation (segments against a reference, moves between poses) measure
/// of a candidate; [`CandidateScore::into_candidate`] is the one place that turns it into a
/// verdict (significance, AIC, share of the excess).
pub(super) struct CandidateScore {
    pub(super) effect: EffectKind,
    pub(super) triad: Triad,
    /// Parameters the candidate adds that the data determine.
    pub(super) new_params: usize,
    pub(super) not_observable: Vec<NotObservable>,
    /// Chi-square and degrees of freedom with the candidate.
    pub(super) chi2: f64,
    pub(super) dof: usize,
    /// F statistic and its p-value.
    pub(super) f: f64,
    pub(super) p_value: f64,
    /// Likelihood-ratio statistic (2 ln L1/L0) of the nested comparison.
    pub(super) likelihood_ratio: f64,
    /// Chi-square the candidate explains, and the model's excess over its dof.
    pub(super) explained_chi2: f64,
    pub(super) excess_chi2: f64,
    pub(super) residual_rms: [f64; 3],
    pub(super) explanation: Explanation,
    pub(super) params: Vec<ParamValue>,
    pub(super) model_change: String,
    pub(super) model: TriadModel,
    pub(super) pattern: Vec<f64>,
}

impl CandidateScore {
    /// The candidate's verdict at significance level `alpha` (claims are made later, by
    /// [`rank_and_claim`], across candidates).
    pub(super) fn into_candidate(self, alpha: f64) -> Candidate {
        Candidate {
            effect: self.effect,
            triad: self.triad,
            new_params: self.new_params,
            not_observable: NotObservables(self.not_observable),
            chi2: self.chi2,
            dof: self.dof,
            f: self.f,
            p_value: self.p_value,
            delta_aic: self.likelihood_ratio - 2.0 * self.new_params as f64,
            share_of_excess: super::share_of(self.explained_chi2, self.excess_chi2),
            residual_rms: self.residual_rms,
            significant: self.p_value < alpha,
            claimed: false,
            held_out: None,
            explanation: self.explanation,
            params: self.params,
            model_change: self.model_change,
            model: Some(self.model),
            pattern: self.pattern,
        }
    }
}
