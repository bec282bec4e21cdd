//! Constant bias (the paper's B_A, B_G): an offset added to every sample.

use crate::effect::{
    Effect, EffectDef, InvalidParam, arr3, check_finite, check_std_errors, fill, xyz_names,
};
use crate::{Conditions, EffectKind, Triad, Vec3, ParamRole};
use serde::{Deserialize, Serialize};

/// Constant bias. Forward: `y = x + b`.
///
/// TOML `[<triad>.bias]`: `value = [x, y, z]` (U), optional `std-error = [x, y, z]` (U).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct Bias {
    /// Bias per axis, in the triad's unit.
    pub value: [f64; 3],
    /// One-sigma standard error, in the triad's unit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub std_error: Option<[f64; 3]>,
}

impl Effect for Bias {
    fn kind(&self) -> EffectKind {
        EffectKind::Bias
    }
    fn param_roles(&self) -> Vec<ParamRole> {
        ParamRole::axes()
    }
    fn param_names(&self) -> Vec<String> {
        xyz_names()
    }
    fn param_units(&self, triad: Triad) -> Vec<String> {
        vec![triad.unit().to_string(); 3]
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
        x + Vec3::from(self.value)
    }
    fn inverse(&self, y: Vec3, _c: &Conditions) -> Vec3 {
        y - Vec3::from(self.value)
    }
}

impl EffectDef for Bias {
    const ID: &'static str = "bias";
    const DESCRIPTION: &'static str =
        "constant bias: an offset added to every sample (paper Eq. 1-2, B_A and B_G)";
    fn neutral() -> Self {
        Bias {
            value: [0.0; 3],
            std_error: None,
        }
    }
    fn field_units(triad: Triad) -> Vec<(&'static str, String)> {
        vec![("value", triad.unit().to_string())]
    }
    fn validate(&self, _triad: Triad) -> Result<(), InvalidParam> {
        check_finite("value", &self.value)?;
        if let Some(se) = &self.std_error {
            check_std_errors("std-error", se)?;
        }
        Ok(())
    }
}
