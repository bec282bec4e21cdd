//! A triad's verdict as a typed value ([`Verdict`]: what explains the excess, the spectral lines,
//! the moves' finding), its codes and, as its `Display`, its sentence.

use super::*;

/// What a verdict says of a candidate.
#[derive(Clone, Debug)]
pub struct CandidateFacts {
    /// The effect.
    pub effect: EffectKind,
    /// Triad.
    pub triad: Triad,
    /// Its explanation.
    pub explanation: Explanation,
    /// F-test p-value.
    pub p_value: f64,
    /// Share of the excess chi-square it explains.
    pub share_of_excess: Option<f64>,
    /// Its held-out check, if it won in-sample.
    pub held_out: Option<HeldOut>,
}

impl CandidateFacts {
    /// The facts of candidate `c`.
    pub fn of(c: &Candidate) -> CandidateFacts {
        CandidateFacts {
            effect: c.effect,
            triad: c.triad,
            explanation: c.explanation.clone(),
            p_value: c.p_value,
            share_of_excess: c.share_of_excess,
            held_out: c.held_out.clone(),
        }
    }
}

/// A slow wander of one axis's bias between segments.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AxisWander {
    /// Extra bias instability, U.
    BiasInstability(f64),
    /// A random walk, U/sqrt(s).
    RandomWalk(f64),
    /// None on this axis.
    None,
}

/// When no library effect explains the excess: the best candidate and the structure of the
/// worst axis.
#[derive(Clone, Debug)]
pub struct Unexplained {
    /// The best observable candidate (not claimed).
    pub best: Option<CandidateFacts>,
    /// The worst axis (0 = x).
    pub axis: usize,
    /// Its strongest correlate.
    pub correlate: Option<Correlate>,
    /// Its lag-1 autocorrelation.
    pub lag1_autocorrelation: f64,
    /// Its dominant period, s, and share of the variance.
    pub dominant_period_s: Option<(f64, f64)>,
}

/// What explains a triad's excess over the noise floor, if anything.
#[derive(Clone, Debug)]
pub enum Finding {
    /// The residuals are consistent with the floor.
    Consistent,
    /// A slow wander of the bias explains the excess.
    BiasWander {
        /// The p-value with the wander allowed.
        p_value_with_drift: f64,
        /// The wander per axis.
        wander: [AxisWander; 3],
    },
    /// A library effect is missing: the claimed candidate.
    MissingEffect(Option<Box<CandidateFacts>>),
    /// The best candidate does not lower the error on held-out observations.
    NotConfirmed {
        /// The candidate.
        best: Option<Box<CandidateFacts>>,
        /// What remains.
        unexplained: Box<Unexplained>,
    },
    /// Two effects explain the excess alike.
    Ambiguous(Option<Ambiguity>),
    /// Nothing in the library explains it.
    Unexplained(Box<Unexplained>),
}

impl Finding {
    /// Stable code: `consistent`, `bias_wander`, `missing_effect`, `not_confirmed`,
    /// `ambiguous` or `unexplained`.
    pub fn code(&self) -> &'static str {
        match self {
            Finding::Consistent => "consistent",
            Finding::BiasWander { .. } => "bias_wander",
            Finding::MissingEffect(_) => "missing_effect",
            Finding::NotConfirmed { .. } => "not_confirmed",
            Finding::Ambiguous(_) => "ambiguous",
            Finding::Unexplained(_) => "unexplained",
        }
    }
}

/// What the moves between poses say of the reference-free gyro gains.
#[derive(Clone, Debug)]
pub enum MovesOutcome {
    /// A missing gain effect, claimed.
    Claimed(CandidateFacts),
    /// The best gain candidate, not confirmed on held-out moves.
    NotConfirmed(CandidateFacts),
    /// Neither.
    Nothing,
}

/// The gyro gains held against the moves, in a verdict.
#[derive(Clone, Debug)]
pub struct MovesFinding {
    /// The gains' verdict against the moves.
    pub verdict: MovesVerdict,
    /// A claimed or unconfirmed gain candidate.
    pub outcome: MovesOutcome,
}

impl MovesFinding {
    /// Stable codes: `gains_consistent` or `gains_inconsistent`, then `missing_gain_effect` or
    /// `gain_not_confirmed` if a candidate is named.
    pub fn codes(&self) -> Vec<&'static str> {
        let mut v = vec![if self.verdict.consistent {
            "gains_consistent"
        } else {
            "gains_inconsistent"
        }];
        match self.outcome {
            MovesOutcome::Claimed(_) => v.push("missing_gain_effect"),
            MovesOutcome::NotConfirmed(_) => v.push("gain_not_confirmed"),
            MovesOutcome::Nothing => {}
        }
        v
    }
}

impl fmt::Display for MovesFinding {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let v = &self.verdict;
        write!(
            f,
            "Gyro gains [{}] against {} moves between poses: direction error {:.2e} rad RMS vs \
             {:.2e} expected (p = {:.1e}): {}.",
            v.effects
                .iter()
                .map(|k| k.id())
                .collect::<Vec<_>>()
                .join(", "),
            v.n_moves,
            v.residual_rms_rad,
            v.expected_rms_rad,
            v.p_value,
            if v.consistent {
                "consistent"
            } else {
                "NOT consistent"
            }
        )?;
        match &self.outcome {
            MovesOutcome::Claimed(c) => {
                write!(
                    f,
                    " Missing gain effect: {} (F-test p = {:.1e}, {}",
                    c.explanation,
                    c.p_value,
                    share_of_excess_text(c.share_of_excess)
                )?;
                if let Some(h) = &c.held_out {
                    write!(
                        f,
                        "; held-out direction error {:.2e} -> {:.2e} rad, {}",
                        h.held_out_rms_before[0],
                        h.held_out_rms_after[0],
                        h.verdict_text()
                    )?;
                }
                f.write_str(").")
            }
            MovesOutcome::NotConfirmed(c) => {
                if let Some(h) = &c.held_out {
                    write!(
                        f,
                        " The best gain candidate, {}, fits these moves better (F-test p = \
                         {:.1e}) but does not lower the direction error over held-out moves: \
                         {}; not claimed.",
                        c.effect,
                        c.p_value,
                        h.summary(h.rms_unit(Triad::Gyro))
                    )?;
                }
                Ok(())
            }
            MovesOutcome::Nothing => Ok(()),
        }
    }
}

/// A triad's verdict: the model held against the noise floor, what explains any excess,
/// periodic components in the static segments and (reference-free gyro) the gains against
/// the moves. Its `Display` is the verdict in words; JSON has them as `verdict` and the codes
/// ([`Verdict::codes`]) as `verdict_codes`.
#[derive(Clone, Debug)]
pub struct Verdict {
    /// Triad.
    pub triad: Triad,
    /// The model's effects.
    pub effects: Vec<EffectKind>,
    /// Consistent with the floor as it stands (the chi-square test).
    pub consistent: bool,
    /// P-value of that test.
    pub p_value: f64,
    /// Residual RMS per axis, U.
    pub residual_rms: [f64; 3],
    /// Noise floor RMS per axis, U.
    pub floor_rms: [f64; 3],
    /// What explains the excess.
    pub finding: Finding,
    /// Periodic components inside the static segments.
    pub lines: Vec<SpectralLine>,
    /// Reference-free gyro: the gains against the moves.
    pub moves: Option<MovesFinding>,
}

impl Verdict {
    /// The axis with the largest residual over floor (0 = x).
    pub fn worst_axis(residual_rms: &[f64; 3], floor_rms: &[f64; 3]) -> usize {
        (0..3)
            .max_by(|&a, &b| {
                (residual_rms[a] / floor_rms[a]).total_cmp(&(residual_rms[b] / floor_rms[b]))
            })
            .unwrap_or(0)
    }

    /// The finding's code ([`Finding::code`]).
    pub fn code(&self) -> &'static str {
        self.finding.code()
    }

    /// Every part's stable code, in the order of the words: the finding's, `periodic_component`
    /// per spectral line, then the moves' ([`MovesFinding::codes`]).
    pub fn codes(&self) -> Vec<&'static str> {
        let mut v = vec![self.finding.code()];
        v.extend(self.lines.iter().map(|_| "periodic_component"));
        if let Some(m) = &self.moves {
            v.extend(m.codes());
        }
        v
    }
}

impl fmt::Display for Verdict {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (triad, u, p) = (self.triad, self.triad.unit(), self.p_value);
        let ids: Vec<&str> = self.effects.iter().map(|k| k.id()).collect();
        write!(f, "{triad} model [{}]: ", ids.join(", "))?;
        let (res, floor) = (self.residual_rms, self.floor_rms);
        if self.consistent {
            write!(
                f,
                "consistent with the noise floor (p = {p:.3}); residual RMS {} vs floor {} {u}.",
                fmt3(res),
                fmt3(floor)
            )?;
        } else {
            let worst = Verdict::worst_axis(&res, &floor);
            write!(
                f,
                "NOT consistent with the noise floor (p = {p:.1e}); residual RMS {} vs floor {} \
                 {u}, worst on {} ({:.1}x the floor).",
                fmt3(res),
                fmt3(floor),
                AXES[worst],
                res[worst] / floor[worst]
            )?;
            match &self.finding {
                Finding::Consistent => {}
                Finding::BiasWander {
                    p_value_with_drift,
                    wander,
                } => write_wander(f, u, *p_value_with_drift, wander)?,
                Finding::MissingEffect(c) => {
                    if let Some(c) = c {
                        write_missing_effect(f, c)?;
                    }
                }
                Finding::NotConfirmed { best, unexplained } => {
                    if let Some(c) = best {
                        write_not_confirmed(f, c)?;
                    }
                    write_unexplained(f, unexplained)?;
                }
                Finding::Ambiguous(a) => {
                    if let Some(a) = a {
                        write!(
                            f,
                            " {} and {} both explain the residual and cannot be told apart in \
                             this recording (their explained patterns correlate {:.2}); to \
                             separate them record {}.",
                            a.effects[0], a.effects[1], a.correlation, a.separating_recording
                        )?;
                    }
                }
                Finding::Unexplained(x) => write_unexplained(f, x)?,
            }
        }
        for l in &self.lines {
            write!(
                f,
                " Unexplained structure: a periodic component at {:.3} Hz, amplitude {:.2e} {u} \
                 on {}-{triad} ({:.0}x the local noise) inside the static segments; no library \
                 effect models a periodic disturbance (look for vibration or electrical \
                 interference at that frequency).",
                l.frequency_hz, l.amplitude, AXES[l.axis], l.ratio
            )?;
        }
        if let Some(m) = &self.moves {
            write!(f, " {m}")?;
        }
        Ok(())
    }
}

/// `{"verdict": sentence, "verdict_codes": [code...]}`: use with `#[serde(flatten)]`.
impl Serialize for Verdict {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut s = serializer.serialize_struct("Verdict", 2)?;
        s.serialize_field("verdict", &self.to_string())?;
        s.serialize_field("verdict_codes", &self.codes())?;
        s.end()
    }
}

/// The excess is the bias wander `w` (p-value `pd` with it).
fn write_wander(f: &mut fmt::Formatter<'_>, u: &str, pd: f64, w: &[AxisWander; 3]) -> fmt::Result {
    let per_axis: Vec<String> = w
        .iter()
        .zip(AXES)
        .map(|(w, x)| match w {
            AxisWander::BiasInstability(b) => format!("{x}: bias instability {b:.2e} {u}"),
            AxisWander::RandomWalk(q) => format!("{x}: random walk {q:.2e} {u}/sqrt(s)"),
            AxisWander::None => format!("{x}: none"),
        })
        .collect();
    write!(
        f,
        " The excess is a slow wander of the bias between segments, not a missing effect: with \
         it ({}) the residuals are consistent with the floor (p = {pd:.3}). (Bias instability \
         and random walk the segments are too short to show; a long static recording through \
         imu-noise measures them.)",
        per_axis.join(", ")
    )
}

/// No library effect explains the excess: the best candidate, and the worst axis's strongest
/// correlate and dominant period.
fn write_unexplained(f: &mut fmt::Formatter<'_>, x: &Unexplained) -> fmt::Result {
    f.write_str(" No effect of the library explains it: unexplained structure remains.")?;
    if let Some(c) = &x.best {
        write!(
            f,
            " (Best candidate {}: p = {:.1e}, {}.)",
            c.effect,
            c.p_value,
            share_of_excess_text(c.share_of_excess)
        )?;
    }
    if let Some(cr) = &x.correlate {
        write!(
            f,
            " On {}: strongest correlate {} (r = {:.2}), lag-1 autocorrelation {:.2}",
            AXES[x.axis], cr.signal, cr.r, x.lag1_autocorrelation
        )?;
    }
    if let Some((period, share)) = x.dominant_period_s {
        write!(
            f,
            ", dominant period {period:.0} s ({:.0} % of the variance)",
            100.0 * share
        )?;
    }
    f.write_str(".")
}

/// The best candidate `c`, which wins in these data but not on held-out observations.
fn write_not_confirmed(f: &mut fmt::Formatter<'_>, c: &CandidateFacts) -> fmt::Result {
    if let Some(h) = &c.held_out {
        write!(
            f,
            " The best candidate, {}, fits these data better (F-test p = {:.1e}, {}) but does \
             not lower the error on held-out {}: {}; not claimed.",
            c.effect,
            c.p_value,
            share_of_excess_text(c.share_of_excess),
            h.unit.noun(),
            h.summary(h.rms_unit(c.triad))
        )?;
    }
    Ok(())
}

/// The claimed candidate `c` as the missing effect, with its held-out check.
fn write_missing_effect(f: &mut fmt::Formatter<'_>, c: &CandidateFacts) -> fmt::Result {
    write!(
        f,
        " Missing effect: {} (F-test p = {:.1e}, {}",
        c.explanation,
        c.p_value,
        share_of_excess_text(c.share_of_excess)
    )?;
    if let Some(h) = &c.held_out {
        write!(
            f,
            "; held-out weighted RMS {} -> {} {}, {}",
            fmt3(h.held_out_rms_before),
            fmt3(h.held_out_rms_after),
            h.rms_unit(c.triad),
            h.verdict_text()
        )?;
    }
    f.write_str(").")
}
