//! Temperature-dependent scale factor: the scale error drifts with sensor temperature.

use crate::effect::{
    AXES, Effect, EffectDef, InvalidParam, check_finite, check_poly_std_errors, fill, pow,
    poly_no_constant,
};
use crate::{Conditions, EffectKind, Triad, Vec3, ParamRole};
use serde::{Deserialize, Serialize};

/// Temperature range (degC) over which validation requires a positive, sane scale.
pub const VALID_TEMP_RANGE_C: (f64, f64) = (-40.0, 85.0);

pub(crate) fn default_t0_c() -> f64 {
    crate::units::REFERENCE_TEMP_C
}

/// Temperature-dependent scale. Forward: `y_i = x_i (1 + sum_k c_{k,i} (T - T0)^k)`, k = 1..n.
///
/// TOML `[<triad>.temp-scale]`: `t0-c = 25.0` (degC, default 25),
/// `coefficients = [[c1x, c1y, c1z], [c2x, c2y, c2z], ...]` (row k in 1/K^k),
/// optional `std-error` of the same shape as `coefficients`.
/// The polynomial degree is the number of rows; `t0-c` is a fixed reference, not a parameter.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct TempScale {
    /// Reference temperature T0, degC.
    #[serde(default = "default_t0_c")]
    pub t0_c: f64,
    /// Row k-1 holds the per-axis coefficients of (T - T0)^k, 1/K^k.
    pub coefficients: Vec<[f64; 3]>,
    /// One-sigma standard errors, same shape as `coefficients`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub std_error: Option<Vec<[f64; 3]>>,
}

impl TempScale {
    /// Neutral model of polynomial degree `degree` (all coefficients 0), for fitting.
    pub fn with_degree(degree: usize) -> Self {
        TempScale {
            t0_c: default_t0_c(),
            coefficients: vec![[0.0; 3]; degree],
            std_error: None,
        }
    }

    /// The per-axis factor `1 + poly(T - T0)` at `temp_c`.
    pub fn factor(&self, temp_c: f64) -> Vec3 {
        poly_no_constant(&self.coefficients, temp_c - self.t0_c).add_scalar(1.0)
    }
}

pub(crate) fn poly_names(n: usize) -> Vec<String> {
    (1..=n)
        .flat_map(|k| AXES.iter().map(move |a| format!("c{k}.{a}")))
        .collect()
}

pub(crate) fn set_rows(rows: &mut [[f64; 3]], p: &[f64]) {
    fill(rows.as_flattened_mut(), p);
}

pub(crate) fn rows_from(rows: usize, p: &[f64]) -> Vec<[f64; 3]> {
    let mut v = vec![[0.0; 3]; rows];
    set_rows(&mut v, p);
    v
}

impl Effect for TempScale {
    fn kind(&self) -> EffectKind {
        EffectKind::TempScale
    }
    fn param_roles(&self) -> Vec<ParamRole> {
        (1..=self.coefficients.len())
            .flat_map(|power| (0..3).map(move |axis| ParamRole::Power { power, axis }))
            .collect()
    }
    fn param_names(&self) -> Vec<String> {
        poly_names(self.coefficients.len())
    }
    fn param_units(&self, _triad: Triad) -> Vec<String> {
        (1..=self.coefficients.len())
            .flat_map(|k| std::iter::repeat_n(format!("1/{}", pow("K", k)), 3))
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
        x.component_mul(&self.factor(c.temp_c))
    }
    fn inverse(&self, y: Vec3, c: &Conditions) -> Vec3 {
        y.component_div(&self.factor(c.temp_c))
    }
}

impl EffectDef for TempScale {
    const ID: &'static str = "temp-scale";
    const DESCRIPTION: &'static str = "temperature-dependent scale factor: scale error is a polynomial in (T - T0) without constant term";
    const GAIN: bool = true;
    fn neutral() -> Self {
        TempScale::with_degree(1)
    }
    fn field_units(_triad: Triad) -> Vec<(&'static str, String)> {
        vec![
            ("t0-c", "degC".to_string()),
            ("coefficients", "row k in 1/K^k".to_string()),
        ]
    }
    fn validate(&self, _triad: Triad) -> Result<(), InvalidParam> {
        check_finite("t0-c", &[self.t0_c])?;
        for (k, row) in self.coefficients.iter().enumerate() {
            check_finite(&format!("coefficients[{k}]"), row)?;
        }
        check_poly_std_errors(&self.coefficients, &self.std_error)?;
        // The inverse divides by the factor: require it to stay well away from 0 (and from
        // sign flips) everywhere a sensor can operate.
        let (lo, hi) = VALID_TEMP_RANGE_C;
        let mut t = lo;
        while t <= hi {
            let f = self.factor(t);
            if let Some(i) = (0..3).find(|&i| !(f[i] > 0.5 && f[i] < 2.0)) {
                return Err(InvalidParam::new(
                    "coefficients",
                    format!(
                        "the scale factor on axis {} reaches {:.4} at {t} degC; it must stay within (0.5, 2) over {lo}..{hi} degC (row k is in 1/K^k: check the units)",
                        AXES[i], f[i]
                    ),
                ));
            }
            t += 1.0;
        }
        Ok(())
    }
}
