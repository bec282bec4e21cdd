//! The workbench's findings as typed values: why a candidate cannot be observed
//! ([`NotObservable`]), what a fitted candidate means ([`Explanation`]), which recording would
//! separate two effects ([`Separation`]) and a triad's verdict ([`Verdict`]). Programs match on
//! the variants or their stable `code()`s; the English sentence is each type's `Display`, written
//! only when a report or `--json` is. In JSON each sits beside its code: `verdict` and
//! `verdict_codes`, `explanation` and `explanation_code`, `not_observable` and
//! `not_observable_codes`, `separating_recording` and `separating_recording_code`. The verdict
//! and its parts are in `verdict.rs`.

use std::fmt;

use serde::Serialize;
use serde::ser::SerializeStruct;

use super::{
    Ambiguity, Candidate, Correlate, HeldOut, MovesVerdict, NotFitted, ParamValue, SpectralLine,
    Unobservable,
};
use imu_model::{EffectKind, Triad};

/// Axis names, for words.
pub(super) const AXES: [&str; 3] = ["x", "y", "z"];

mod verdict;
pub use verdict::*;

/// `1.00e-3/2.00e-3/3.00e-3`: three values in one cell.
pub(crate) fn fmt3(v: [f64; 3]) -> String {
    format!("{:.2e}/{:.2e}/{:.2e}", v[0], v[1], v[2])
}

/// `explains 62 % of the excess`, or that there was none.
pub(crate) fn share_of_excess_text(share: Option<f64>) -> String {
    match share {
        Some(s) => format!("explains {:.0} % of the excess", 100.0 * s),
        None => "the model shows no excess to explain".into(),
    }
}

/// ` (name = value +/- error unit)` of a parameter.
struct ParamText<'a>(&'a ParamValue);

impl fmt::Display for ParamText<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let p = self.0;
        write!(f, "{} = {:.3e}", p.name, p.value)?;
        if let Some(e) = p.std_error {
            write!(f, " +/- {e:.1e}")?;
        }
        write!(f, " {}", p.unit)
    }
}

// ------------------------------------------------------------------------- not observable

/// Why a candidate effect (or one of its parameters) cannot be observed in this recording.
#[derive(Clone, Debug, PartialEq)]
pub enum NotObservable {
    /// The workbench holds the effect out of this kind of fit (e.g. reference-free gyro gains
    /// come from the moves, not the still poses): the note says why.
    Held(crate::note::Note),
    /// The model with the effect cannot be fitted on this recording.
    NotFittable,
    /// One of the effect's parameters was not fitted (the least-squares engine's reason).
    Parameter(Unobservable),
    /// A lever arm's standard error exceeds any lever arm inside an IMU package: the recording
    /// barely excites it.
    LeverArmBarelyExcited {
        /// The parameter.
        name: String,
        /// Its standard error, m.
        std_error_m: f64,
        /// The largest lever arm inside a package, m.
        max_m: f64,
    },
    /// A warm-up's time constant has a standard error longer than the recording: no decay is
    /// resolved.
    DecayNotResolved {
        /// The parameter.
        name: String,
        /// Its standard error, s.
        std_error_s: f64,
        /// The recording's span, s.
        span_s: f64,
    },
    /// The gain fit to the moves between poses failed with the effect.
    MovesCannotFit,
}

impl NotObservable {
    /// Stable code: `held`, `not_fittable`, `lever_arm_barely_excited`, `decay_not_resolved`,
    /// `moves_cannot_fit`, or for a parameter the least-squares reason's code
    /// ([`NotFitted::code`], e.g. `zero_jacobian`).
    pub fn code(&self) -> &'static str {
        match self {
            NotObservable::Held(_) => "held",
            NotObservable::NotFittable => "not_fittable",
            NotObservable::Parameter(u) => NotFitted::code(&u.reason),
            NotObservable::LeverArmBarelyExcited { .. } => "lever_arm_barely_excited",
            NotObservable::DecayNotResolved { .. } => "decay_not_resolved",
            NotObservable::MovesCannotFit => "moves_cannot_fit",
        }
    }
}

impl fmt::Display for NotObservable {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            NotObservable::Held(note) => write!(f, "{note}"),
            NotObservable::NotFittable => write!(f, "not fittable on this recording"),
            NotObservable::Parameter(u) => write!(f, "{}: {}", u.name, u.reason),
            NotObservable::LeverArmBarelyExcited {
                name,
                std_error_m,
                max_m,
            } => write!(
                f,
                "{name}: standard error {std_error_m:.1e} m, more than any lever arm inside an \
                 IMU package ({max_m} m): the recording barely excites it (rotate about each \
                 axis at several rates)"
            ),
            NotObservable::DecayNotResolved {
                name,
                std_error_s,
                span_s,
            } => write!(
                f,
                "{name}: standard error {std_error_s:.0} s, longer than the recording \
                 ({span_s:.0} s): no decay is resolved (record from power-on)"
            ),
            NotObservable::MovesCannotFit => write!(f, "the moves cannot fit it"),
        }
    }
}

/// A candidate's reasons for not being observable. Flattened into JSON as `not_observable`
/// (the sentences) and `not_observable_codes` (each [`NotObservable::code`], in order).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NotObservables(pub Vec<NotObservable>);

impl NotObservables {
    /// The codes, in order.
    pub fn codes(&self) -> Vec<&'static str> {
        self.0.iter().map(NotObservable::code).collect()
    }
}

impl std::ops::Deref for NotObservables {
    type Target = Vec<NotObservable>;
    fn deref(&self) -> &Vec<NotObservable> {
        &self.0
    }
}

impl fmt::Display for NotObservables {
    /// The reasons joined by `; `.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, r) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str("; ")?;
            }
            write!(f, "{r}")?;
        }
        Ok(())
    }
}

impl Serialize for NotObservables {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let sentences: Vec<String> = self.0.iter().map(ToString::to_string).collect();
        let mut s = serializer.serialize_struct("NotObservables", 2)?;
        s.serialize_field("not_observable", &sentences)?;
        s.serialize_field("not_observable_codes", &self.codes())?;
        s.end()
    }
}

// ----------------------------------------------------------------------------- explanation

/// What a candidate means: its effect, what drives its most significant parameter and the
/// error with it, or why it cannot be observed.
#[derive(Clone, Debug, PartialEq)]
pub enum Explanation {
    /// Fitted to the segments or poses.
    Fitted {
        /// The effect.
        effect: EffectKind,
        /// Triad.
        triad: Triad,
        /// The parameter with the largest |value / se| (never a time constant).
        most_significant: Option<ParamValue>,
        /// The effect's time constant, s, if it has one.
        time_constant_s: Option<f64>,
        /// Residual RMS per axis with the effect, U.
        residual_rms: [f64; 3],
    },
    /// A gyro gain fitted to the rotations integrated over the moves between poses.
    Moves {
        /// The effect.
        effect: EffectKind,
        /// The parameter with the largest |value / se|.
        most_significant: Option<ParamValue>,
        /// Direction error after the moves with the effect, rad RMS.
        rms_with_rad: f64,
        /// The same without it, rad RMS.
        rms_without_rad: f64,
    },
    /// Not observable in this recording.
    NotObservable {
        /// The effect.
        effect: EffectKind,
        /// Why.
        reasons: NotObservables,
    },
}

impl Explanation {
    /// Stable code: `fitted`, `moves` or `not_observable`.
    pub fn code(&self) -> &'static str {
        match self {
            Explanation::Fitted { .. } => "fitted",
            Explanation::Moves { .. } => "moves",
            Explanation::NotObservable { .. } => "not_observable",
        }
    }
}

impl fmt::Display for Explanation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Explanation::Fitted {
                effect,
                triad,
                most_significant,
                time_constant_s,
                residual_rms,
            } => {
                f.write_str(effect.description())?;
                if let Some(p) = most_significant {
                    write!(f, ": {} ({})", p.id.driver(*triad), ParamText(p))?;
                }
                if let Some(tau) = time_constant_s {
                    write!(f, ", time constant {tau:.0} s")?;
                }
                write!(
                    f,
                    "; residual RMS with it: {:.3e} {:.3e} {:.3e} {}",
                    residual_rms[0],
                    residual_rms[1],
                    residual_rms[2],
                    triad.unit()
                )
            }
            Explanation::Moves {
                effect,
                most_significant,
                rms_with_rad,
                rms_without_rad,
            } => {
                f.write_str(effect.description())?;
                if let Some(p) = most_significant {
                    write!(f, " ({})", ParamText(p))?;
                }
                write!(
                    f,
                    ": the rotations integrated over the moves between poses need it; direction \
                     error after the moves {rms_with_rad:.2e} rad RMS with it, \
                     {rms_without_rad:.2e} rad without"
                )
            }
            Explanation::NotObservable { effect, reasons } => write!(
                f,
                "{}: not observable in this recording ({reasons})",
                effect.description()
            ),
        }
    }
}

/// `{"explanation": sentence, "explanation_code": code}`: use with `#[serde(flatten)]`.
impl Serialize for Explanation {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut s = serializer.serialize_struct("Explanation", 2)?;
        s.serialize_field("explanation", &self.to_string())?;
        s.serialize_field("explanation_code", self.code())?;
        s.end()
    }
}

// ------------------------------------------------------------------------------ separation

/// The recording that separates two effects the present one cannot tell apart.
#[derive(Clone, Debug, PartialEq)]
pub enum Separation {
    /// Warm-up against a temperature effect: a temperature cycle after the warm-up.
    TemperatureCycle,
    /// Nonlinearity against asymmetry: inputs of both signs at several magnitudes.
    BothSignsSeveralMagnitudes,
    /// A lever arm: rotations at several rates with the sensor off the axis.
    RatesOffAxis,
    /// A g-sensitivity: more static orientations.
    MoreOrientations,
    /// Any other pair: a recording in which their driving signals vary independently.
    Independent(EffectKind, EffectKind),
}

impl Separation {
    /// The recording that separates `a` from `b`.
    pub fn of(a: EffectKind, b: EffectKind) -> Separation {
        use EffectKind::*;
        let has = |x: EffectKind| a == x || b == x;
        if has(Warmup) && (has(TempBias) || has(TempScale)) {
            Separation::TemperatureCycle
        } else if has(ScaleNonlinearity) && has(AsymmetricScale) {
            Separation::BothSignsSeveralMagnitudes
        } else if has(LeverArm) {
            Separation::RatesOffAxis
        } else if has(GSensitivity) {
            Separation::MoreOrientations
        } else {
            Separation::Independent(a, b)
        }
    }

    /// Stable code: `temperature_cycle`, `both_signs_several_magnitudes`, `rates_off_axis`,
    /// `more_orientations` or `independent_signals`.
    pub fn code(&self) -> &'static str {
        match self {
            Separation::TemperatureCycle => "temperature_cycle",
            Separation::BothSignsSeveralMagnitudes => "both_signs_several_magnitudes",
            Separation::RatesOffAxis => "rates_off_axis",
            Separation::MoreOrientations => "more_orientations",
            Separation::Independent(..) => "independent_signals",
        }
    }
}

impl fmt::Display for Separation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Separation::TemperatureCycle => f.write_str(
                "a temperature cycle after the warm-up has settled (heat and cool the sensor, \
                 e.g. in a chamber or with the sinusoidal temperature profile): temperature then \
                 changes without the time since power-on, and the two stop moving together",
            ),
            Separation::BothSignsSeveralMagnitudes => f.write_str(
                "inputs of both signs at several magnitudes (e.g. rate steps of +/-20, 40, 60, \
                 80 deg/s): a square bends both signs the same way, an asymmetry changes the \
                 gain with the sign",
            ),
            Separation::RatesOffAxis => f.write_str(
                "rotations at several rates about each axis, with the sensor off the table axis \
                 in different directions: the centripetal term grows with the square of the rate \
                 and points along the offset",
            ),
            Separation::MoreOrientations => f.write_str(
                "more static orientations (each axis up and down, and at 45 degrees): the \
                 g-dependent bias follows the specific force, the other effect does not",
            ),
            Separation::Independent(a, b) => write!(
                f,
                "a recording in which the signals that drive {a} and {b} vary independently of \
                 each other"
            ),
        }
    }
}

/// `{"separating_recording": sentence, "separating_recording_code": code}`: use with
/// `#[serde(flatten)]`.
impl Serialize for Separation {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut s = serializer.serialize_struct("Separation", 2)?;
        s.serialize_field("separating_recording", &self.to_string())?;
        s.serialize_field("separating_recording_code", self.code())?;
        s.end()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_sit_beside_the_sentences_in_json() {
        #[derive(Serialize)]
        struct Row {
            #[serde(flatten)]
            explanation: Explanation,
            #[serde(flatten)]
            not_observable: NotObservables,
        }
        let reasons = NotObservables(vec![
            NotObservable::NotFittable,
            NotObservable::DecayNotResolved {
                name: "warmup.tau".into(),
                std_error_s: 900.0,
                span_s: 300.0,
            },
        ]);
        let row = Row {
            explanation: Explanation::NotObservable {
                effect: EffectKind::Warmup,
                reasons: reasons.clone(),
            },
            not_observable: reasons,
        };
        let v = serde_json::to_value(&row).unwrap();
        assert_eq!(v["explanation_code"], "not_observable");
        assert_eq!(
            v["not_observable_codes"],
            serde_json::json!(["not_fittable", "decay_not_resolved"])
        );
        assert_eq!(
            v["not_observable"][1],
            "warmup.tau: standard error 900 s, longer than the recording (300 s): no decay is \
             resolved (record from power-on)"
        );
        let e = v["explanation"].as_str().unwrap();
        assert!(
            e.ends_with(
                ": not observable in this recording (not fittable on this recording; warmup.tau: \
                 standard error 900 s, longer than the recording (300 s): no decay is resolved \
                 (record from power-on))"
            ),
            "{e}"
        );
    }

    #[test]
    fn every_separation_has_its_own_code() {
        use EffectKind::*;
        let pairs = [
            (Warmup, TempBias, "temperature_cycle"),
            (
                ScaleNonlinearity,
                AsymmetricScale,
                "both_signs_several_magnitudes",
            ),
            (LeverArm, Scale, "rates_off_axis"),
            (GSensitivity, Bias, "more_orientations"),
            (Scale, Bias, "independent_signals"),
        ];
        for (a, b, code) in pairs {
            assert_eq!(Separation::of(a, b).code(), code);
            assert_eq!(Separation::of(b, a).code(), code);
        }
    }
}
