//! The workbench's words: what drives each effect's parameters, what a fitted candidate means
//! physically, the model change, which recording separates two effects, and the verdict text.

use super::*;

pub(super) const AXES: [&str; 3] = ["x", "y", "z"];

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

/// One line on a fitted candidate: what it is, what drives its most significant parameter, its
/// value, and the residual RMS with it.
pub(super) fn explain(
    k: EffectKind,
    triad: Triad,
    params: &[ParamValue],
    residual_rms: [f64; 3],
) -> String {
    let best = most_significant(params);
    let mut s = k.description().to_string();
    if let Some(p) = best {
        let _ = write!(
            s,
            ": {} ({} = {:.3e}{} {})",
            p.id.driver(triad),
            p.name,
            p.value,
            p.std_error
                .map_or(String::new(), |e| format!(" +/- {e:.1e}")),
            p.unit
        );
    }
    if let Some(tau) = params.iter().find(|p| p.id.is_time_constant()) {
        let _ = write!(s, ", time constant {:.0} s", tau.value);
    }
    let _ = write!(
        s,
        "; residual RMS with it: {:.3e} {:.3e} {:.3e} {}",
        residual_rms[0],
        residual_rms[1],
        residual_rms[2],
        triad.unit()
    );
    s
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

/// The recording that separates two effects the present one cannot.
pub(super) fn separating_recording(a: EffectKind, b: EffectKind) -> String {
    use EffectKind::*;
    let has = |x: EffectKind| a == x || b == x;
    if has(Warmup) && (has(TempBias) || has(TempScale)) {
        "a temperature cycle after the warm-up has settled (heat and cool the sensor, e.g. in a \
         chamber or with the sinusoidal temperature profile): temperature then changes without \
         the time since power-on, and the two stop moving together"
            .into()
    } else if has(ScaleNonlinearity) && has(AsymmetricScale) {
        "inputs of both signs at several magnitudes (e.g. rate steps of +/-20, 40, 60, 80 deg/s): \
         a square bends both signs the same way, an asymmetry changes the gain with the sign"
            .into()
    } else if has(LeverArm) {
        "rotations at several rates about each axis, with the sensor off the table axis in \
         different directions: the centripetal term grows with the square of the rate and points \
         along the offset"
            .into()
    } else if has(GSensitivity) {
        "more static orientations (each axis up and down, and at 45 degrees): the g-dependent \
         bias follows the specific force, the other effect does not"
            .into()
    } else {
        format!(
            "a recording in which the signals that drive {a} and {b} vary independently of each \
             other"
        )
    }
}

/// What a triad's verdict says, for [`verdict_text`].
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

/// What the verdict of one triad says, decided once from its facts: the words of the verdict
/// ([`verdict_text`]) and the report's heading both follow it, so they cannot disagree.
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

/// The verdict of one triad in words: consistent or not, the worst axis, the wander or the
/// missing effect that explains the excess, ambiguities, structure and spectral lines.
pub(super) fn verdict_text(facts: &VerdictFacts<'_>) -> String {
    let ids: Vec<&str> = facts.model.kinds().iter().map(|k| k.id()).collect();
    let mut s = format!("{} model [{}]: ", facts.triad, ids.join(", "));
    let state = verdict_state(facts);
    if facts.consistent {
        facts.write_consistent(&mut s);
    } else {
        let worst = facts.write_inconsistent(&mut s);
        match (state, facts.with_drift) {
            (VerdictState::BiasWander, Some((pd, w))) => facts.write_wander(&mut s, pd, &w),
            (VerdictState::MissingEffect, _) => {
                if let Some(c) = facts.candidates.first() {
                    write_missing_effect(&mut s, c)
                }
            }
            (VerdictState::NotConfirmed, _) => {
                if let Some(c) = facts.candidates.first() {
                    write_not_confirmed(&mut s, c, facts.triad)
                }
                facts.write_unexplained(&mut s, worst)
            }
            (VerdictState::Ambiguous, _) => {
                if let Some(a) = facts.ambiguities.first() {
                    write_ambiguity(&mut s, a)
                }
            }
            _ => facts.write_unexplained(&mut s, worst),
        }
    }
    facts.write_lines(&mut s);
    s
}

impl VerdictFacts<'_> {
    fn write_consistent(&self, s: &mut String) {
        let (p, u, axes) = (self.p_value, self.triad.unit(), self.axes);
        let _ = write!(
            s,
            "consistent with the noise floor (p = {p:.3}); residual RMS {} vs floor {} {u}.",
            fmt3(axes.each_ref().map(|a| a.residual_rms)),
            fmt3(axes.each_ref().map(|a| a.noise_floor_rms))
        );
    }

    /// The excess over the floor and its worst axis, which it returns.
    fn write_inconsistent(&self, s: &mut String) -> usize {
        let (p, u, axes) = (self.p_value, self.triad.unit(), self.axes);
        let worst = (0..3)
            .max_by(|&a, &b| {
                (axes[a].residual_rms / axes[a].noise_floor_rms)
                    .total_cmp(&(axes[b].residual_rms / axes[b].noise_floor_rms))
            })
            .unwrap_or(0);
        let _ = write!(
            s,
            "NOT consistent with the noise floor (p = {p:.1e}); residual RMS {} vs floor {} {u}, \
             worst on {} ({:.1}x the floor).",
            fmt3(axes.each_ref().map(|a| a.residual_rms)),
            fmt3(axes.each_ref().map(|a| a.noise_floor_rms)),
            AXES[worst],
            axes[worst].residual_rms / axes[worst].noise_floor_rms
        );
        worst
    }

    /// The excess is the bias wander `w` (p-value `pd` with it).
    fn write_wander(&self, s: &mut String, pd: f64, w: &[Wander; 3]) {
        let u = self.triad.unit();
        let per_axis: Vec<String> = w
            .iter()
            .zip(AXES)
            .map(|(w, x)| {
                if w.flicker_var > 0.0 {
                    format!("{x}: bias instability {:.2e} {u}", w.bias_instability())
                } else if w.random_walk_q > 0.0 {
                    format!(
                        "{x}: random walk {:.2e} {u}/sqrt(s)",
                        w.random_walk_q.sqrt()
                    )
                } else {
                    format!("{x}: none")
                }
            })
            .collect();
        let _ = write!(
            s,
            " The excess is a slow wander of the bias between segments, not a missing effect: \
             with it ({}) the residuals are consistent with the floor (p = {pd:.3}). (Bias \
             instability and random walk the segments are too short to show; a long static \
             recording through imu-noise measures them.)",
            per_axis.join(", ")
        );
    }

    /// No library effect explains the excess: the best candidate, and the worst axis's
    /// strongest correlate and dominant period.
    fn write_unexplained(&self, s: &mut String, worst: usize) {
        let _ = write!(
            s,
            " No effect of the library explains it: unexplained structure remains."
        );
        if let Some(c) = self.candidates.first().filter(|c| c.new_params > 0) {
            let _ = write!(
                s,
                " (Best candidate {}: p = {:.1e}, {}.)",
                c.effect,
                c.p_value,
                c.share_of_excess_text()
            );
        }
        let a = worst;
        let structure = self.structure;
        if let Some(cr) = structure[a].correlates.first() {
            let _ = write!(
                s,
                " On {}: strongest correlate {} (r = {:.2}), lag-1 autocorrelation \
                 {:.2}",
                AXES[a], cr.signal, cr.r, structure[a].lag1_autocorrelation
            );
        }
        if let Some((period, share)) = structure[a].dominant_period_s {
            let _ = write!(
                s,
                ", dominant period {period:.0} s ({:.0} % of the variance)",
                100.0 * share
            );
        }
        s.push('.');
    }

    /// The spectral lines inside the static segments.
    fn write_lines(&self, s: &mut String) {
        let (triad, u) = (self.triad, self.triad.unit());
        for l in self.lines {
            let _ = write!(
                s,
                " Unexplained structure: a periodic component at {:.3} Hz, amplitude {:.2e} {u} on \
                 {}-{triad} ({:.0}x the local noise) inside the static segments; no library effect \
                 models a periodic disturbance (look for vibration or electrical interference at \
                 that frequency).",
                l.frequency_hz, l.amplitude, AXES[l.axis], l.ratio
            );
        }
    }
}

/// The best candidate `c`, which wins in these data but not on held-out observations.
fn write_not_confirmed(s: &mut String, c: &Candidate, triad: Triad) {
    if let Some(h) = &c.held_out {
        let _ = write!(
            s,
            " The best candidate, {}, fits these data better (F-test p = {:.1e}, {}) but does \
             not lower the error on held-out {}: {}; not claimed.",
            c.effect,
            c.p_value,
            c.share_of_excess_text(),
            h.unit.noun(),
            h.summary(h.rms_unit(triad))
        );
    }
}

/// The claimed candidate `c` as the missing effect, with its held-out check.
fn write_missing_effect(s: &mut String, c: &Candidate) {
    let _ = write!(
        s,
        " Missing effect: {} (F-test p = {:.1e}, {}",
        c.explanation,
        c.p_value,
        c.share_of_excess_text()
    );
    if let Some(h) = &c.held_out {
        let _ = write!(
            s,
            "; held-out weighted RMS {} -> {} {}, {}",
            fmt3(h.held_out_rms_before),
            fmt3(h.held_out_rms_after),
            h.rms_unit(c.triad),
            h.verdict_text()
        );
    }
    s.push_str(").");
}

/// Two effects that both explain the excess and this recording cannot tell apart.
fn write_ambiguity(s: &mut String, a: &Ambiguity) {
    let _ = write!(
        s,
        " {} and {} both explain the residual and cannot be told apart in this \
         recording (their explained patterns correlate {:.2}); to separate them \
         record {}.",
        a.effects[0], a.effects[1], a.correlation, a.separating_recording
    );
}

pub(super) fn fmt3(v: [f64; 3]) -> String {
    format!("{:.2e}/{:.2e}/{:.2e}", v[0], v[1], v[2])
}
