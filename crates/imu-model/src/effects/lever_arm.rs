//! Lever arm: the accelerometer proof masses sit away from the IMU reference point, so they
//! also feel centripetal and tangential acceleration when the body rotates.

use crate::effect::{
    AXES, Effect, EffectDef, InvalidParam, arr3, check_finite, check_std_errors, fill, xyz_names,
};
use crate::{Conditions, EffectKind, Triad, Vec3, ParamRole};
use serde::{Deserialize, Serialize};

/// Accelerometer lever arm. Forward: `f_meas = f + w x (w x r) + a x r` with `w` the true
/// angular rate, `a` the true angular acceleration (from [`Conditions`]) and `r` the offset of
/// the accelerometer from the reference point.
///
/// TOML `[accel.lever-arm]`: `offset-m = [x, y, z]` (m), optional `std-error = [x, y, z]` (m).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct LeverArm {
    /// Offset of the accelerometer triad from the IMU reference point, sensor frame, metres.
    pub offset_m: [f64; 3],
    /// One-sigma standard error of `offset_m`, metres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub std_error: Option<[f64; 3]>,
}

impl LeverArm {
    /// The additive term `w x (w x r) + a x r` for the given conditions, m/s^2.
    pub fn term_m_s2(&self, c: &Conditions) -> Vec3 {
        let r = Vec3::from(self.offset_m);
        let w = c.angular_rate_rad_s;
        w.cross(&w.cross(&r)) + c.angular_accel_rad_s2.cross(&r)
    }
}

impl Effect for LeverArm {
    fn kind(&self) -> EffectKind {
        EffectKind::LeverArm
    }
    fn param_roles(&self) -> Vec<ParamRole> {
        ParamRole::axes()
    }
    fn param_names(&self) -> Vec<String> {
        xyz_names()
    }
    fn param_units(&self, _triad: Triad) -> Vec<String> {
        vec!["m".to_string(); 3]
    }
    fn params(&self) -> Vec<f64> {
        self.offset_m.to_vec()
    }
    fn set_params(&mut self, p: &[f64]) {
        fill(&mut self.offset_m, p);
    }
    fn std_errors(&self) -> Option<Vec<f64>> {
        self.std_error.map(|s| s.to_vec())
    }
    fn set_std_errors(&mut self, se: Option<Vec<f64>>) {
        self.std_error = se.map(|s| arr3(&s));
    }
    fn forward(&self, x: Vec3, c: &Conditions) -> Vec3 {
        x + self.term_m_s2(c)
    }
    fn inverse(&self, y: Vec3, c: &Conditions) -> Vec3 {
        y - self.term_m_s2(c)
    }
}

impl EffectDef for LeverArm {
    const ID: &'static str = "lever-arm";
    const DESCRIPTION: &'static str = "accelerometer lever arm: centripetal w x (w x r) and tangential a x r acceleration of a proof mass offset r from the reference point";
    fn applies_to(triad: Triad) -> bool {
        triad == Triad::Accel
    }
    fn neutral() -> Self {
        LeverArm {
            offset_m: [0.0; 3],
            std_error: None,
        }
    }
    fn field_units(_triad: Triad) -> Vec<(&'static str, String)> {
        vec![("offset-m", "m".to_string())]
    }
    fn validate(&self, _triad: Triad) -> Result<(), InvalidParam> {
        check_finite("offset-m", &self.offset_m)?;
        // A lever arm of metres means the wrong unit (mm or cm) was typed.
        if let Some(i) = self.offset_m.iter().position(|v| v.abs() > 1.0) {
            return Err(InvalidParam::new(
                format!("offset-m[{i}]"),
                format!(
                    "{} m on axis {} is larger than 1 m; the offset is in metres (write 0.012 for 12 mm)",
                    self.offset_m[i], AXES[i]
                ),
            ));
        }
        if let Some(se) = &self.std_error {
            check_std_errors("std-error", se)?;
        }
        Ok(())
    }
}
