//! The warnings of a calibration fit as data: programs match on [`FitWarningKind`] (or its
//! stable [`code`](FitWarningKind::code)); the English is each warning's `Display`, written
//! only where a report or the JSON's `warnings` list needs it.

use std::fmt;
use std::ops::{Deref, DerefMut};

use imu_model::Triad;
use serde::ser::SerializeMap;

use super::Unobservable;
use super::reference_free::POSE_ADVICE;

/// What a fit's conditioning was judged on (the words "these data", "these poses", ...).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Evidence {
    /// The observations of a referenced fit.
    Data,
    /// The still poses of a reference-free fit.
    Poses,
    /// The moves between still poses (reference-free gyro gains).
    Moves,
}

impl Evidence {
    fn words(self) -> &'static str {
        match self {
            Evidence::Data => "data",
            Evidence::Poses => "poses",
            Evidence::Moves => "moves",
        }
    }
}

/// Which part of a calibration a warning is about (the prefix of its sentence).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WarningScope {
    /// The fit the warning belongs to (no prefix).
    Fit,
    /// One triad of a reference-free calibration (`accel: `).
    Triad(Triad),
    /// The reference-free gyro's fit of its offsets to the still poses
    /// (`gyro (still poses): `).
    GyroStillPoses,
}

/// What a warning says.
#[derive(Clone, Debug, PartialEq)]
pub enum FitWarningKind {
    /// The normal matrix is not invertible: no standard errors.
    NoStandardErrors,
    /// Two free parameters are correlated beyond 0.99.
    Correlated {
        /// The first parameter.
        a: String,
        /// The second parameter.
        b: String,
        /// Their correlation.
        correlation: f64,
        /// What failed to separate them.
        evidence: Evidence,
    },
    /// A parameter was not fitted (held).
    NotFitted(Unobservable),
    /// The fit stopped at its iteration budget.
    NotConverged {
        /// Iterations taken.
        iterations: usize,
    },
    /// The smallest eigenvalue of the normalised normal matrix is below the weak threshold.
    WeaklySeparated {
        /// The parameters of the weakest combination.
        parameters: Vec<String>,
        /// The eigenvalue.
        eigenvalue: f64,
        /// What barely separates them.
        evidence: Evidence,
    },
    /// Fewer than two still poses per free parameter.
    FewPoses {
        /// Poses used.
        poses: usize,
        /// Free parameters.
        parameters: usize,
    },
    /// An accelerometer axis never pointed within 45 degrees of up, of down, or of either.
    AxisNeverPointed {
        /// The axis (0 = x).
        axis: usize,
        /// It never pointed up.
        up: bool,
        /// It never pointed down.
        down: bool,
        /// Smallest gravity component along it over the poses, g.
        lo_g: f64,
        /// Largest, g.
        hi_g: f64,
    },
}

impl FitWarningKind {
    /// The stable code: `no_standard_errors`, `correlated`, `not_fitted`, `not_converged`,
    /// `weakly_separated`, `few_poses`, `axis_never_pointed`.
    pub fn code(&self) -> &'static str {
        match self {
            FitWarningKind::NoStandardErrors => "no_standard_errors",
            FitWarningKind::Correlated { .. } => "correlated",
            FitWarningKind::NotFitted(_) => "not_fitted",
            FitWarningKind::NotConverged { .. } => "not_converged",
            FitWarningKind::WeaklySeparated { .. } => "weakly_separated",
            FitWarningKind::FewPoses { .. } => "few_poses",
            FitWarningKind::AxisNeverPointed { .. } => "axis_never_pointed",
        }
    }
}

/// One warning of a fit: where it applies and what it says.
#[derive(Clone, Debug, PartialEq)]
pub struct FitWarning {
    /// Where.
    pub scope: WarningScope,
    /// What.
    pub kind: FitWarningKind,
}

impl FitWarning {
    /// A warning about the fit itself.
    pub fn of_fit(kind: FitWarningKind) -> Self {
        FitWarning {
            scope: WarningScope::Fit,
            kind,
        }
    }

    /// The same warning about another part of a calibration.
    pub fn in_scope(self, scope: WarningScope) -> Self {
        FitWarning { scope, ..self }
    }
}

impl fmt::Display for FitWarning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.scope {
            WarningScope::Fit => {}
            WarningScope::Triad(t) => write!(f, "{t}: ")?,
            WarningScope::GyroStillPoses => f.write_str("gyro (still poses): ")?,
        }
        match &self.kind {
            FitWarningKind::NoStandardErrors => {
                f.write_str("normal matrix not invertible: no standard errors")
            }
            FitWarningKind::Correlated {
                a,
                b,
                correlation,
                evidence,
            } => write!(
                f,
                "{a} and {b} are correlated {correlation:.3}: poorly separated by these {}",
                evidence.words()
            ),
            FitWarningKind::NotFitted(u) => write!(f, "{} not fitted: {}", u.name, u.reason),
            FitWarningKind::NotConverged { iterations } => {
                write!(f, "not converged after {iterations} iterations")
            }
            FitWarningKind::WeaklySeparated {
                parameters,
                eigenvalue,
                evidence,
            } => write!(
                f,
                "the {} barely separate {} (smallest eigenvalue {eigenvalue:.1e} of the \
                 normalised normal matrix): {POSE_ADVICE}",
                evidence.words(),
                parameters.join(", ")
            ),
            FitWarningKind::FewPoses { poses, parameters } => write!(
                f,
                "only {poses} poses for {parameters} parameters: standard errors are rough; \
                 {POSE_ADVICE}"
            ),
            FitWarningKind::AxisNeverPointed {
                axis,
                up,
                down,
                lo_g,
                hi_g,
            } => {
                let towards = match (up, down) {
                    (true, true) => "up or down",
                    (true, false) => "up",
                    _ => "down",
                };
                write!(
                    f,
                    "accel {}: the axis never pointed within 45 degrees of {towards} (its gravity \
                     component spans {lo_g:.2}..{hi_g:.2} g): {POSE_ADVICE}",
                    ["x", "y", "z"][(*axis).min(2)]
                )
            }
        }
    }
}

/// The warnings of a fit. Serialized (flattened into the fit) as `warnings`, the sentences as
/// before, and `warning_codes`, each one's stable code in the same order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Warnings(pub Vec<FitWarning>);

impl Deref for Warnings {
    type Target = Vec<FitWarning>;
    fn deref(&self) -> &Self::Target {
        &self.0
    }
}

impl DerefMut for Warnings {
    fn deref_mut(&mut self) -> &mut Self::Target {
        &mut self.0
    }
}

impl<'a> IntoIterator for &'a Warnings {
    type Item = &'a FitWarning;
    type IntoIter = std::slice::Iter<'a, FitWarning>;
    fn into_iter(self) -> Self::IntoIter {
        self.0.iter()
    }
}

impl From<Vec<FitWarning>> for Warnings {
    fn from(v: Vec<FitWarning>) -> Self {
        Warnings(v)
    }
}

impl serde::Serialize for Warnings {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let text: Vec<String> = self.0.iter().map(ToString::to_string).collect();
        let codes: Vec<&str> = self.0.iter().map(|w| w.kind.code()).collect();
        let mut m = serializer.serialize_map(Some(2))?;
        m.serialize_entry("warnings", &text)?;
        m.serialize_entry("warning_codes", &codes)?;
        m.end()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use imu_stats::lsq::NotFitted;

    #[derive(serde::Serialize)]
    struct Holder {
        n: u32,
        #[serde(flatten)]
        warnings: Warnings,
    }

    /// The JSON keeps the sentences under `warnings` and adds the codes beside them.
    #[test]
    fn warnings_serialize_as_sentences_and_codes() {
        let w = Warnings(vec![
            FitWarning::of_fit(FitWarningKind::NotConverged { iterations: 100 }),
            FitWarning::of_fit(FitWarningKind::NotFitted(Unobservable {
                name: "bias.x".into(),
                reason: NotFitted::ZeroJacobian,
            }))
            .in_scope(WarningScope::GyroStillPoses),
        ]);
        let json = serde_json::to_value(Holder { n: 1, warnings: w }).unwrap();
        assert_eq!(json["n"], 1);
        assert_eq!(
            json["warnings"],
            serde_json::json!([
                "not converged after 100 iterations",
                "gyro (still poses): bias.x not fitted: the data do not excite it (zero Jacobian \
                 column)"
            ])
        );
        assert_eq!(
            json["warning_codes"],
            serde_json::json!(["not_converged", "not_fitted"])
        );
    }

    #[test]
    fn an_axis_warning_names_the_missing_direction() {
        let w = FitWarning {
            scope: WarningScope::Fit,
            kind: FitWarningKind::AxisNeverPointed {
                axis: 2,
                up: false,
                down: true,
                lo_g: -0.5,
                hi_g: 1.0,
            },
        };
        assert_eq!(w.kind.code(), "axis_never_pointed");
        assert!(
            w.to_string()
                .starts_with("accel z: the axis never pointed within 45 degrees of down ("),
            "{w}"
        );
    }
}
