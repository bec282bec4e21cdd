//! Scale-factor error (the paper's S_A, S_G): each axis reads its input times (1 + s).

use crate::effect::{
    Effect, EffectDef, InvalidParam, arr3, check_finite, check_std_errors, fill, xyz_names,
};
use crate::{Conditions, EffectKind, Triad, Vec3, ParamRole};
use serde::{Deserialize, Serialize};

/// Per-axis scale-factor error. Forward: `y_i = x_i (1 + s_i)`; `s = 0` is nominal.
///
/// TOML `[<triad>.scale]`: `value = [x, y, z]` (dimensionless, e.g. 1e-3 = 0.1 %),
/// optional `std-error = [x, y, z]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct Scale {
    /// Scale-factor error per axis, dimensionless.
    pub value: [f64; 3],
    /// One-sigma standard error, dimensionless.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub std_error: Option<[f64; 3]>,
}

impl Effect for Scale {
    fn kind(&self) -> EffectKind {
        EffectKind::Scale
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
        x.component_mul(&Vec3::from(self.value).add_scalar(1.0))
    }
    fn inverse(&self, y: Vec3, _c: &Conditions) -> Vec3 {
        y.component_div(&Vec3::from(self.value).add_scalar(1.0))
    }
}

impl EffectDef for Scale {
    const ID: &'static str = "scale";
    const DESCRIPTION: &'static str =
        "scale-factor error: each axis reads its input times (1 + s) (paper Eq. 1-2, S_A and S_G)";
    const GAIN: bool = true;
    fn neutral() -> Self {
        Scale {
            value: [0.0; 3],
            std_error: None,
        }
    }
    fn field_units(_triad: Triad) -> Vec<(&'static str, String)> {
        vec![("value", "1 (dimensionless; 1e-3 = 0.1 %)".to_string())]
    }
    fn validate(&self, _triad: Triad) -> Result<(), InvalidParam> {
        check_finite("value", &self.value)?;
        // |s| < 1 keeps 1 + s > 0: the axis keeps its sign and the inverse exists.
        if let Some(i) = self.value.iter().position(|s| s.abs() >= 1.0) {
            return Err(InvalidParam::new(
                format!("value[{i}]"),
                format!(
                    "scale error {} must satisfy |s| < 1; it is the deviation from nominal (1e-3 = 0.1 %), not the scale factor itself",
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
