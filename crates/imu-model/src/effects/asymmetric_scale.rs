//! Asymmetric scale factor: a different scale error for positive and negative input.

use crate::effect::{
    Effect, EffectDef, InvalidParam, arr3, check_finite, check_std_errors, fill, xyz_names,
};
use crate::{Conditions, EffectKind, Triad, Vec3, ParamRole};
use serde::{Deserialize, Serialize};

/// Asymmetric scale. Forward: `y_i = x_i (1 + a_i sgn(x_i))`, so positive input sees scale
/// `1 + a` and negative input `1 - a`. Because `|a| < 1`, `y` has the sign of `x`, which is what
/// makes the inverse `x_i = y_i / (1 + a_i sgn(y_i))` exact.
///
/// TOML `[<triad>.asymmetric-scale]`: `value = [x, y, z]` (dimensionless, |a| < 1),
/// optional `std-error = [x, y, z]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct AsymmetricScale {
    /// Half the difference between positive and negative scale, per axis, dimensionless.
    pub value: [f64; 3],
    /// One-sigma standard error, dimensionless.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub std_error: Option<[f64; 3]>,
}

/// sgn with sgn(0) = 0 (f64::signum gives +1 for +0.0).
fn sgn(v: f64) -> f64 {
    if v > 0.0 {
        1.0
    } else if v < 0.0 {
        -1.0
    } else {
        0.0
    }
}

impl Effect for AsymmetricScale {
    fn kind(&self) -> EffectKind {
        EffectKind::AsymmetricScale
    }
    fn param_roles(&self) -> Vec<ParamRole> {
        ParamRole::axes()
    }
    fn param_names(&self) -> Vec<String> {
        xyz_names()
    }
    fn param_units(&self, _triad: Triad) -> Vec<String> {
        vec!["1".to_string(); 3]
    }
    fn params(&self) -> Vec<f64> {
        self.value.to_vec()
    }
    fn set_params(&mut self, p: &[f64]) {
        fill(&mut self.value, p);
    }
    fn std_errors(&self) -> Option<Vec<f64>> {
        self.std_error.map(|s| s.to_vec())
    }
    fn set_std_errors(&mut self, se: Option<Vec<f64>>) {
        self.std_error = se.map(|s| arr3(&s));
    }
    fn forward(&self, x: Vec3, _c: &Conditions) -> Vec3 {
        Vec3::from_fn(|i, _| x[i] * (1.0 + self.value[i] * sgn(x[i])))
    }
    fn inverse(&self, y: Vec3, _c: &Conditions) -> Vec3 {
        Vec3::from_fn(|i, _| y[i] / (1.0 + self.value[i] * sgn(y[i])))
    }
}

impl EffectDef for AsymmetricScale {
    const ID: &'static str = "asymmetric-scale";
    const DESCRIPTION: &'static str = "asymmetric scale factor: positive input is scaled by (1 + a), negative input by (1 - a)";
    const GAIN: bool = true;
    fn neutral() -> Self {
        AsymmetricScale {
            value: [0.0; 3],
            std_error: None,
        }
    }
    fn field_units(_triad: Triad) -> Vec<(&'static str, String)> {
        vec![("value", "1 (dimensionless, |a| < 1)".to_string())]
    }
    fn validate(&self, _triad: Triad) -> Result<(), InvalidParam> {
        check_finite("value", &self.value)?;
        if let Some(i) = self.value.iter().position(|a| a.abs() >= 1.0) {
            return Err(InvalidParam::new(
                format!("value[{i}]"),
                format!(
                    "asymmetry {} must satisfy |a| < 1 (otherwise the output changes sign and cannot be inverted)",
                    self.value[i]
                ),
            ));
        }
        if let Some(se) = &self.std_error {
            check_std_errors("std-error", se)?;
        }
        Ok(())
    }
}
