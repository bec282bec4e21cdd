//! Typed parameter identities: which effect a parameter belongs to and what it acts on, so that
//! fits and explanations ask "is this a bias, on which axis" instead of parsing `"bias.x"`.

use std::fmt;

use crate::{EffectKind, Triad};

/// What one parameter of an effect acts on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ParamRole {
    /// One sensor axis (bias, scale, asymmetric scale, lever arm, warm-up amplitude).
    Axis(usize),
    /// A coupling of output axis `row` to input axis `col` (misalignment, g-sensitivity).
    Coupling {
        /// Output (sensor) axis.
        row: usize,
        /// Input axis (specific force for g-sensitivity).
        col: usize,
    },
    /// A polynomial term of one axis: the power of the input (scale nonlinearity: 2, 3) or of
    /// the temperature difference (temperature effects: 1, 2, ...).
    Power {
        /// The power.
        power: usize,
        /// The axis.
        axis: usize,
    },
    /// A scalar of the whole triad (the warm-up time constant).
    Scalar,
}

impl ParamRole {
    /// The sensor axis the parameter acts on (the output axis of a coupling; None for a
    /// scalar).
    pub fn axis(self) -> Option<usize> {
        match self {
            ParamRole::Axis(a) | ParamRole::Power { axis: a, .. } => Some(a),
            ParamRole::Coupling { row, .. } => Some(row),
            ParamRole::Scalar => None,
        }
    }

    /// The three axes in order.
    pub fn axes() -> Vec<ParamRole> {
        (0..3).map(ParamRole::Axis).collect()
    }
}

/// One parameter of a triad model: its effect, its role and its name (`<effect-id>.<name>`, as
/// in [`crate::TriadModel::param_names`]).
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct ParamId {
    /// The effect.
    pub effect: EffectKind,
    /// What it acts on.
    pub role: ParamRole,
    /// Its name, e.g. `bias.x`.
    pub name: String,
}

impl ParamId {
    /// True for the warm-up time constant (the one parameter that is a time, not an amount of
    /// an effect on an axis).
    pub fn is_time_constant(&self) -> bool {
        self.effect == EffectKind::Warmup && self.role == ParamRole::Scalar
    }

    /// What drives this parameter, in physical words (what pattern in the residuals of
    /// `triad` it explains).
    pub fn driver(&self, triad: Triad) -> String {
        const AXES: [&str; 3] = ["x", "y", "z"];
        let t = triad.name();
        let a = self.role.axis().map_or("?", |a| AXES[a]);
        match (self.effect, self.role) {
            (EffectKind::GSensitivity, ParamRole::Coupling { row, col }) => format!(
                "the {}-{t} residual follows the specific force along {}",
                AXES[row], AXES[col]
            ),
            (EffectKind::Misalignment, ParamRole::Coupling { row, col }) => format!(
                "the {}-{t} residual follows the input along {}",
                AXES[row], AXES[col]
            ),
            (EffectKind::ScaleNonlinearity, ParamRole::Power { power, .. }) => {
                let power = if power == 2 { "square" } else { "cube" };
                format!("the {a}-{t} residual follows the {power} of its input")
            }
            (EffectKind::AsymmetricScale, _) => {
                format!("the {a}-{t} gain differs between positive and negative input")
            }
            (EffectKind::Scale, _) => format!("the {a}-{t} residual is proportional to its input"),
            (EffectKind::Bias, _) => format!("a constant offset on {a}-{t}"),
            (EffectKind::TempBias, _) => format!("the {a}-{t} residual follows temperature"),
            (EffectKind::TempScale, _) => format!("the {a}-{t} gain follows temperature"),
            (EffectKind::Warmup, ParamRole::Scalar) => {
                format!("how fast the {t} residuals decay with time since power-on")
            }
            (EffectKind::Warmup, _) => {
                format!("the {a}-{t} residual decays with time since power-on")
            }
            (EffectKind::LeverArm, _) => format!(
                "the {t} residual follows the square of the rotation rate (centripetal \
                 acceleration of a proof mass offset along {a})"
            ),
            (
                EffectKind::GSensitivity | EffectKind::Misalignment | EffectKind::ScaleNonlinearity,
                _,
            ) => {
                format!("the {a}-{t} residual")
            }
        }
    }
}

impl ParamRole {
    /// The stable code of the role: `axis`, `coupling`, `power`, `scalar`.
    pub fn code(self) -> &'static str {
        match self {
            ParamRole::Axis(_) => "axis",
            ParamRole::Coupling { .. } => "coupling",
            ParamRole::Power { .. } => "power",
            ParamRole::Scalar => "scalar",
        }
    }
}

/// Serialized as `{"name", "effect", "role", "axis", "input_axis", "power"}`: the effect's id
/// (`bias`, `warmup`, ...), the role's [`ParamRole::code`], the sensor axis (0..3, null for a
/// scalar), the input axis of a coupling and the power of a polynomial term (null otherwise).
impl serde::Serialize for ParamId {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let (input_axis, power) = match self.role {
            ParamRole::Coupling { col, .. } => (Some(col), None),
            ParamRole::Power { power, .. } => (None, Some(power)),
            ParamRole::Axis(_) | ParamRole::Scalar => (None, None),
        };
        let mut s = serializer.serialize_struct("ParamId", 6)?;
        s.serialize_field("name", &self.name)?;
        s.serialize_field("effect", self.effect.id())?;
        s.serialize_field("role", self.role.code())?;
        s.serialize_field("axis", &self.role.axis())?;
        s.serialize_field("input_axis", &input_axis)?;
        s.serialize_field("power", &power)?;
        s.end()
    }
}

impl fmt::Display for ParamId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::TriadModel;

    #[test]
    fn the_warmup_time_constant_is_the_only_time_constant() {
        let mut m = TriadModel::default();
        for k in EffectKind::ALL {
            m.add(k);
        }
        let tau: Vec<String> = m
            .param_ids()
            .into_iter()
            .filter(ParamId::is_time_constant)
            .map(|id| id.name)
            .collect();
        assert_eq!(tau, ["warmup.tau_s"]);
    }

    #[test]
    fn a_parameter_id_serializes_its_effect_role_and_axes() {
        let mut m = TriadModel::default();
        m.add(EffectKind::Misalignment);
        let ids = m.param_ids();
        let json = serde_json::to_value(&ids[1]).unwrap();
        assert_eq!(json["name"], ids[1].name.as_str());
        assert_eq!(json["effect"], "misalignment");
        assert_eq!(json["role"], "coupling");
        let ParamRole::Coupling { row, col } = ids[1].role else {
            panic!("{:?}", ids[1])
        };
        assert_eq!(json["axis"], row);
        assert_eq!(json["input_axis"], col);
        assert!(json["power"].is_null());
    }

    #[test]
    fn every_parameter_has_a_role_and_physical_words() {
        for triad in [Triad::Accel, Triad::Gyro] {
            let mut m = TriadModel::default();
            for k in EffectKind::ALL.into_iter().filter(|k| k.applies_to(triad)) {
                m.add(k);
            }
            let (ids, names) = (m.param_ids(), m.param_names(triad));
            assert_eq!(ids.len(), names.len());
            for (id, name) in ids.iter().zip(&names) {
                assert_eq!(&id.name, name);
                let words = id.driver(triad);
                assert!(
                    !words.contains('?') && words.contains(triad.name()),
                    "{name}: {words}"
                );
            }
        }
        let mut m = TriadModel::default();
        m.add(EffectKind::Misalignment);
        let ids = m.param_ids();
        assert_eq!(ids[0].name, "misalignment.xy");
        assert_eq!(ids[0].role, ParamRole::Coupling { row: 0, col: 1 });
        assert_eq!(ids[5].role, ParamRole::Coupling { row: 2, col: 1 });
    }
}
