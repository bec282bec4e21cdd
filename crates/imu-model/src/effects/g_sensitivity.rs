//! Gyro g-sensitivity (the paper's B_g): a MEMS gyro's proof mass also responds to linear
//! acceleration, so the rate output carries a bias proportional to the specific force.

use crate::effect::{
    AXES, Effect, EffectDef, InvalidParam, check_finite, check_std_errors, fill,
};
use crate::{Conditions, EffectKind, Mat3, Triad, Vec3, ParamRole};
use serde::{Deserialize, Serialize};

/// Gyro g-dependent bias. Forward: `w_meas = w + G f` with `f` the TRUE specific force at the
/// reference point ([`Conditions::specific_force_m_s2`]).
///
/// TOML `[gyro.g-sensitivity]`: `matrix = [[xx, xy, xz], [yx, yy, yz], [zx, zy, zz]]`
/// ((rad/s)/(m/s^2); row = gyro axis, column = specific-force axis), optional `std-error` of the
/// same shape.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct GSensitivity {
    /// G, row-major, (rad/s)/(m/s^2).
    pub matrix: [[f64; 3]; 3],
    /// One-sigma standard errors, same shape.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub std_error: Option<[[f64; 3]; 3]>,
}

impl GSensitivity {
    /// G as a matrix.
    pub fn g_matrix(&self) -> Mat3 {
        Mat3::from_fn(|r, c| self.matrix[r][c])
    }
}

fn rows(p: &[f64]) -> [[f64; 3]; 3] {
    let mut m = [[0.0; 3]; 3];
    fill(m.as_flattened_mut(), p);
    m
}

impl Effect for GSensitivity {
    fn kind(&self) -> EffectKind {
        EffectKind::GSensitivity
    }
    fn param_roles(&self) -> Vec<ParamRole> {
        (0..3)
            .flat_map(|row| (0..3).map(move |col| ParamRole::Coupling { row, col }))
            .collect()
    }
    fn param_names(&self) -> Vec<String> {
        AXES.iter()
            .flat_map(|r| AXES.iter().map(move |c| format!("{r}{c}")))
            .collect()
    }
    fn param_units(&self, triad: Triad) -> Vec<String> {
        vec![format!("({})/(m/s^2)", triad.unit()); 9]
    }
    fn params(&self) -> Vec<f64> {
        self.matrix.as_flattened().to_vec()
    }
    fn set_params(&mut self, p: &[f64]) {
        fill(self.matrix.as_flattened_mut(), p);
    }
    fn std_errors(&self) -> Option<Vec<f64>> {
        self.std_error.map(|s| s.as_flattened().to_vec())
    }
    fn set_std_errors(&mut self, se: Option<Vec<f64>>) {
        self.std_error = se.map(|s| rows(&s));
    }
    fn forward(&self, x: Vec3, c: &Conditions) -> Vec3 {
        x + self.g_matrix() * c.specific_force_m_s2
    }
    fn inverse(&self, y: Vec3, c: &Conditions) -> Vec3 {
        y - self.g_matrix() * c.specific_force_m_s2
    }
}

impl EffectDef for GSensitivity {
    const ID: &'static str = "g-sensitivity";
    const DESCRIPTION: &'static str = "gyro g-dependent bias: rate error proportional to the specific force (paper Eq. 2-4, B_g)";
    fn applies_to(triad: Triad) -> bool {
        triad == Triad::Gyro
    }
    fn neutral() -> Self {
        GSensitivity {
            matrix: [[0.0; 3]; 3],
            std_error: None,
        }
    }
    fn field_units(_triad: Triad) -> Vec<(&'static str, String)> {
        vec![(
            "matrix",
            "(rad/s)/(m/s^2), row = gyro axis, column = specific-force axis".to_string(),
        )]
    }
    fn validate(&self, _triad: Triad) -> Result<(), InvalidParam> {
        for (r, row) in self.matrix.iter().enumerate() {
            check_finite(&format!("matrix[{r}]"), row)?;
        }
        if let Some(se) = &self.std_error {
            check_std_errors("std-error", se.as_flattened())?;
        }
        Ok(())
    }
}
