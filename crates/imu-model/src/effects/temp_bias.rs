//! Temperature-dependent bias: the offset drifts with sensor temperature.

use crate::effect::{
    Effect, EffectDef, InvalidParam, check_finite, check_poly_std_errors, poly_no_constant,
    unit_per_kelvin_pow,
};
use crate::effects::temp_scale::{default_t0_c, poly_names, rows_from, set_rows};
use crate::{Conditions, EffectKind, Triad, Vec3, ParamRole};
use serde::{Deserialize, Serialize};

/// Temperature-dependent bias. Forward: `y = x + sum_k c_k (T - T0)^k`, k = 1..n, per axis.
///
/// TOML `[<triad>.temp-bias]`: `t0-c = 25.0` (degC, default 25),
/// `coefficients = [[c1x, c1y, c1z], ...]` (row k in U/K^k), optional `std-error` of the same
/// shape. The constant part of the bias belongs to `bias`; this effect is zero at T0.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct TempBias {
    /// Reference temperature T0, degC.
    #[serde(default = "default_t0_c")]
    pub t0_c: f64,
    /// Row k-1 holds the per-axis coefficients of (T - T0)^k, U/K^k.
    pub coefficients: Vec<[f64; 3]>,
    /// One-sigma standard errors, same shape as `coefficients`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub std_error: Option<Vec<[f64; 3]>>,
}

impl TempBias {
    /// Neutral model of polynomial degree `degree` (all coefficients 0), for fitting.
    pub fn with_degree(degree: usize) -> Self {
        TempBias {
            t0_c: default_t0_c(),
            coefficients: vec![[0.0; 3]; degree],
            std_error: None,
        }
    }

    /// The additive bias at `temp_c`, in the triad's unit.
    pub fn offset(&self, temp_c: f64) -> Vec3 {
        poly_no_constant(&self.coefficients, temp_c - self.t0_c)
    }
}

impl Effect for TempBias {
    fn kind(&self) -> EffectKind {
        EffectKind::TempBias
    }
    fn param_roles(&self) -> Vec<ParamRole> {
        (1..=self.coefficients.len())
            .flat_map(|power| (0..3).map(move |axis| ParamRole::Power { power, axis }))
            .collect()
    }
    fn param_names(&self) -> Vec<String> {
        poly_names(self.coefficients.len())
    }
    fn param_units(&self, triad: Triad) -> Vec<String> {
        (1..=self.coefficients.len())
            .flat_map(|k| std::iter::repeat_n(unit_per_kelvin_pow(triad, k), 3))
            .collect()
    }
    fn params(&self) -> Vec<f64> {
        self.coefficients.as_flattened().to_vec()
    }
    fn set_params(&mut self, p: &[f64]) {
        set_rows(&mut self.coefficients, p);
    }
    fn std_errors(&self) -> Option<Vec<f64>> {
        self.std_error.as_ref().map(|s| s.as_flattened().to_vec())
    }
    fn set_std_errors(&mut self, se: Option<Vec<f64>>) {
        self.std_error = se.map(|s| rows_from(self.coefficients.len(), &s));
    }
    fn forward(&self, x: Vec3, c: &Conditions) -> Vec3 {
        x + self.offset(c.temp_c)
    }
    fn inverse(&self, y: Vec3, c: &Conditions) -> Vec3 {
        y - self.offset(c.temp_c)
    }
}

impl EffectDef for TempBias {
    const ID: &'static str = "temp-bias";
    const DESCRIPTION: &'static str = "temperature-dependent bias: additive offset polynomial in (T - T0) without constant term";
    fn neutral() -> Self {
        TempBias::with_degree(1)
    }
    fn field_units(triad: Triad) -> Vec<(&'static str, String)> {
        vec![
            ("t0-c", "degC".to_string()),
            (
                "coefficients",
                format!("row k in {}/K^k", crate::effect::paren(triad.unit())),
            ),
        ]
    }
    fn validate(&self, _triad: Triad) -> Result<(), InvalidParam> {
        check_finite("t0-c", &[self.t0_c])?;
        for (k, row) in self.coefficients.iter().enumerate() {
            check_finite(&format!("coefficients[{k}]"), row)?;
        }
        check_poly_std_errors(&self.coefficients, &self.std_error)
    }
}
