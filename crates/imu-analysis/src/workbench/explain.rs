//! The workbench's findings decided: what a fitted candidate means ([`Explanation`]), the model
//! change, and the verdict ([`verdict_state`], [`verdict`]); their words are the `Display`s of
//! `words.rs`.

use super::*;

/// The parameter with the largest |value / se| (a time constant never: it names no pattern):
/// the one that names the candidate's pattern.
pub(super) fn most_significant(params: &[ParamValue]) -> Option<&ParamValue> {
    params
        .iter()
        .filter(|p| !p.id.is_time_constant())
        .max_by(|a, b| {
            let t = |p: &ParamValue| p.std_error.map_or(0.0, |s| (p.value / s).abs());
            t(a).total_cmp(&t(b))
        })
}

/// What a fitted candidate means: what drives its most significant parameter, its value, its
/// time constant if any, and the residual RMS with it.
pub(super) fn explain(
    k: EffectKind,
    triad: Triad,
    params: &[ParamValue],
    residual_rms: [f64; 3],
) -> Explanation {
    Explanation::Fitted {
        effect: k,
        triad,
        most_significant: most_significant(params).cloned(),
        time_constant_s: params
            .iter()
            .find(|p| p.id.is_time_constant())
            .map(|p| p.value),
        residual_rms,
    }
}

/// The TOML lines of `k` as fitted in `m` (what to add to the model file).
pub(super) fn model_change(triad: Triad, m: &TriadModel, k: EffectKind) -> String {
    let mut only = TriadModel::default();
    only.add(k);
    if let (Some(src), Some(dst)) = (m.get(k), only.get_mut(k)) {
        dst.set_params(&src.params());
    }
    let mut cal = imu_model::Calibration::identity();
    *cal.triad_mut(triad) = only;
    let text = cal.to_toml_string();
    let header = format!("[{}.{}", triad.name(), k.id());
    match text.find(&header) {
        Some(i) => text[i..].trim_end().to_string(),
        None => text,
    }
}

/// What a triad's verdict says, for [`verdict`].
#[derive(Clone, Copy)]
pub(super) struct VerdictFacts<'a> {
    pub(super) triad: Triad,
    pub(super) model: &'a TriadModel,
    /// Consistent with the floor as it stands.
    pub(super) consistent: bool,
    /// The p-value and the wander with which it is consistent, if a bias wander explains it.
    pub(super) with_drift: Option<(f64, [Wander; 3])>,
    pub(super) p_value: f64,
    pub(super) axes: &'a [AxisVerdict; 3],
    pub(super) candidates: &'a [Candidate],
    pub(super) ambiguities: &'a [Ambiguity],
    pub(super) structure: &'a [Structure; 3],
    pub(super) lines: &'a [SpectralLine],
}

/// What the verdict of one triad says, decided once from its facts: the verdict ([`verdict`])
/// and the report's heading both follow it, so they cannot disagree.
pub(super) fn verdict_state(facts: &VerdictFacts<'_>) -> VerdictState {
    if facts.consistent {
        return if facts.lines.is_empty() {
            VerdictState::Consistent
        } else {
            VerdictState::PeriodicComponent
        };
    }
    let any_significant = facts.candidates.iter().any(|c| c.significant);
    if facts.with_drift.is_some() && !any_significant {
        return VerdictState::BiasWander;
    }
    match facts.candidates.first() {
        Some(c) if c.claimed => VerdictState::MissingEffect,
        Some(c) if c.held_out.as_ref().is_some_and(|h| !h.confirmed) => VerdictState::NotConfirmed,
        _ if !facts.ambiguities.is_empty() => VerdictState::Ambiguous,
        _ => VerdictState::Unexplained,
    }
}

/// The verdict of one triad as a typed value (its `Display` is the words): consistent or not,
/// the wander or the missing effect that explains the excess, ambiguities, structure and
/// spectral lines.
pub(super) fn verdict(facts: &VerdictFacts<'_>) -> Verdict {
    let residual_rms = facts.axes.each_ref().map(|a| a.residual_rms);
    let floor_rms = facts.axes.each_ref().map(|a| a.noise_floor_rms);
    let worst = Verdict::worst_axis(&residual_rms, &floor_rms);
    let first = || {
        facts
            .candidates
            .first()
            .map(|c| Box::new(CandidateFacts::of(c)))
    };
    let unexplained = || {
        Box::new(Unexplained {
            best: facts
                .candidates
                .first()
                .filter(|c| c.new_params > 0)
                .map(CandidateFacts::of),
            axis: worst,
            correlate: facts.structure[worst].correlates.first().cloned(),
            lag1_autocorrelation: facts.structure[worst].lag1_autocorrelation,
            dominant_period_s: facts.structure[worst].dominant_period_s,
        })
    };
    let finding = if facts.consistent {
        Finding::Consistent
    } else {
        match (verdict_state(facts), facts.with_drift) {
            (VerdictState::BiasWander, Some((p_value_with_drift, w))) => Finding::BiasWander {
                p_value_with_drift,
                wander: w.map(|w| {
                    if w.flicker_var > 0.0 {
                        AxisWander::BiasInstability(w.bias_instability())
                    } else if w.random_walk_q > 0.0 {
                        AxisWander::RandomWalk(w.random_walk_q.sqrt())
                    } else {
                        AxisWander::None
                    }
                }),
            },
            (VerdictState::MissingEffect, _) => Finding::MissingEffect(first()),
            (VerdictState::NotConfirmed, _) => Finding::NotConfirmed {
                best: first(),
                unexplained: unexplained(),
            },
            (VerdictState::Ambiguous, _) => Finding::Ambiguous(facts.ambiguities.first().cloned()),
            _ => Finding::Unexplained(unexplained()),
        }
    };
    Verdict {
        triad: facts.triad,
        effects: facts.model.kinds(),
        consistent: facts.consistent,
        p_value: facts.p_value,
        residual_rms,
        floor_rms,
        finding,
        lines: facts.lines.to_vec(),
        moves: None,
    }
}
