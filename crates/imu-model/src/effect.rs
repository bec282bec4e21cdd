//! The `Effect` trait every physical error effect implements, and helpers shared by the effect files.

use crate::{Conditions, EffectKind, Triad, Vec3};
use serde::Serialize;
use serde::de::DeserializeOwned;
use std::fmt::Debug;

/// One deterministic error stage of a triad's model: `forward` maps the stage's input to its
/// output (towards the measurement), `inverse` undoes it exactly.
///
/// Parameters are exposed as a flat `f64` vector so that fitting tools can treat any subset of
/// effects uniformly; `param_names`, `param_units` and `std_errors` are parallel to `params`.
pub trait Effect: Debug + Send + Sync {
    /// Which effect this is.
    fn kind(&self) -> EffectKind;
    /// Parameter names, parallel to [`Effect::params`] (e.g. `["x", "y", "z"]`).
    fn param_names(&self) -> Vec<String>;
    /// What each parameter acts on, parallel to [`Effect::params`].
    fn param_roles(&self) -> Vec<crate::ParamRole>;
    /// Parameter units for the given triad, parallel to [`Effect::params`].
    fn param_units(&self, triad: Triad) -> Vec<String>;
    /// The current parameter vector.
    fn params(&self) -> Vec<f64>;
    /// Replace the parameters. `p` must have the length of [`Effect::params`]: this is checked
    /// with `debug_assert!`; in release builds surplus values are ignored and missing ones leave
    /// the corresponding parameters unchanged (no panic on the daemon's path).
    fn set_params(&mut self, p: &[f64]);
    /// One-sigma standard errors parallel to [`Effect::params`], if known (from a fit).
    fn std_errors(&self) -> Option<Vec<f64>>;
    /// Replace the standard errors (same length rule as [`Effect::set_params`]).
    fn set_std_errors(&mut self, se: Option<Vec<f64>>);
    /// Apply this stage only: stage input `x` -> stage output.
    fn forward(&self, x: Vec3, c: &Conditions) -> Vec3;
    /// Exact inverse of [`Effect::forward`] for the same conditions.
    fn inverse(&self, y: Vec3, c: &Conditions) -> Vec3;
    /// [`Effect::inverse`] of every value of `ys` in place, all at the same conditions `c`.
    /// The result is bit-for-bit that of `inverse` on each value; an effect whose inverse
    /// prepares something from its parameters alone (a matrix factorisation) overrides this to
    /// prepare it once for the batch.
    fn inverse_batch(&self, ys: &mut [Vec3], c: &Conditions) {
        for y in ys {
            *y = self.inverse(*y, c);
        }
    }
    /// Number of parameters.
    fn n_params(&self) -> usize {
        self.params().len()
    }
}

/// A validation failure inside one effect or triad table: `key` is relative to that table
/// (e.g. `"cubic"` or `"coefficients[1]"`), the caller prefixes the path.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct InvalidParam {
    /// Key path relative to the table being validated.
    pub key: String,
    /// What is wrong and what to do.
    pub message: String,
}

impl InvalidParam {
    /// Build an `InvalidParam`.
    pub fn new(key: impl Into<String>, message: impl Into<String>) -> Self {
        InvalidParam {
            key: key.into(),
            message: message.into(),
        }
    }

    /// Prefix the key with a parent table name (`"bias"` + `"value"` -> `"bias.value"`).
    pub fn within(mut self, parent: &str) -> Self {
        self.key = if self.key.is_empty() {
            parent.to_string()
        } else {
            format!("{parent}.{}", self.key)
        };
        self
    }
}

/// Static facts about an effect type, used by the registry in `effects/mod.rs`. Implemented
/// next to [`Effect`] in each effect's own file.
pub trait EffectDef:
    Effect + Clone + PartialEq + Serialize + DeserializeOwned + Sized + 'static
{
    /// Kebab-case id used in TOML, JSON and on the command line; equals the module name with
    /// `_` replaced by `-` (a test checks this).
    const ID: &'static str;
    /// One line in physical terms.
    const DESCRIPTION: &'static str;
    /// A gain: the effect scales with the input (zero input shows nothing of it), so only a
    /// large input (rate plateaus, moves between poses, gravity in several directions) excites
    /// it. Offsets (bias, g-sensitivity, temperature bias, warm-up, lever arm) are not gains.
    const GAIN: bool = false;
    /// Whether the effect exists for this triad (default: all triads).
    fn applies_to(triad: Triad) -> bool {
        let _ = triad;
        true
    }
    /// Parameters that make `forward` the identity (what `TriadModel::add` inserts).
    fn neutral() -> Self;
    /// `(field, unit)` pairs for the file's `# units:` comment.
    fn field_units(triad: Triad) -> Vec<(&'static str, String)>;
    /// Check values after parsing (finite, shapes, invertibility domain).
    fn validate(&self, triad: Triad) -> Result<(), InvalidParam>;
}

// ---- helpers shared by effect files -------------------------------------------------------

/// Axis suffixes.
pub(crate) const AXES: [&str; 3] = ["x", "y", "z"];

/// `["x","y","z"]` as owned strings.
pub(crate) fn xyz_names() -> Vec<String> {
    AXES.iter().map(|s| s.to_string()).collect()
}

/// `prefix.x, prefix.y, prefix.z`.
pub(crate) fn prefixed_xyz(prefix: &str) -> Vec<String> {
    AXES.iter().map(|a| format!("{prefix}.{a}")).collect()
}

/// Wrap a compound unit in parentheses so that it can be divided or raised to a power.
pub(crate) fn paren(unit: &str) -> String {
    if unit.contains('/') || unit.contains('*') {
        format!("({unit})")
    } else {
        unit.to_string()
    }
}

/// `unit^k` ("K", "K^2", ...).
pub(crate) fn pow(unit: &str, k: usize) -> String {
    if k == 1 {
        paren(unit)
    } else {
        format!("{}^{k}", paren(unit))
    }
}

/// `1/U^k` for triad unit U.
pub(crate) fn per_unit_pow(triad: Triad, k: usize) -> String {
    format!("1/{}", pow(triad.unit(), k))
}

/// `U/K^k` for triad unit U.
pub(crate) fn unit_per_kelvin_pow(triad: Triad, k: usize) -> String {
    format!("{}/{}", paren(triad.unit()), pow("K", k))
}

/// Copy `src` into `dst` without panicking on a length mismatch (debug builds assert).
pub(crate) fn fill(dst: &mut [f64], src: &[f64]) {
    debug_assert_eq!(dst.len(), src.len(), "parameter vector length mismatch");
    for (d, s) in dst.iter_mut().zip(src) {
        *d = *s;
    }
}

/// A `[f64; 3]` from a slice (missing values are 0).
pub(crate) fn arr3(src: &[f64]) -> [f64; 3] {
    let mut a = [0.0; 3];
    fill(&mut a, src);
    a
}

/// Check every value is finite.
pub(crate) fn check_finite(key: &str, values: &[f64]) -> Result<(), InvalidParam> {
    match values.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) if values.len() > 1 => Err(InvalidParam::new(
            format!("{key}[{i}]"),
            format!("value {} is not a finite number", values[i]),
        )),
        Some(i) => Err(InvalidParam::new(
            key,
            format!("value {} is not a finite number", values[i]),
        )),
    }
}

/// Check standard errors are finite and non-negative.
pub(crate) fn check_std_errors(key: &str, values: &[f64]) -> Result<(), InvalidParam> {
    check_finite(key, values)?;
    match values.iter().position(|v| *v < 0.0) {
        None => Ok(()),
        Some(i) => Err(InvalidParam::new(
            format!("{key}[{i}]"),
            format!(
                "standard error {} is negative; a standard error is >= 0",
                values[i]
            ),
        )),
    }
}

/// Evaluate the per-axis polynomial `sum_{k=1..n} c_k dt^k` (no constant term) by Horner's rule.
pub(crate) fn poly_no_constant(coefficients: &[[f64; 3]], dt: f64) -> Vec3 {
    let mut p = Vec3::zeros();
    for c in coefficients.iter().rev() {
        p = (p + Vec3::from(*c)) * dt;
    }
    p
}

/// Check the shape of a std-error polynomial table against its coefficients.
pub(crate) fn check_poly_std_errors(
    coefficients: &[[f64; 3]],
    se: &Option<Vec<[f64; 3]>>,
) -> Result<(), InvalidParam> {
    if let Some(se) = se {
        if se.len() != coefficients.len() {
            return Err(InvalidParam::new(
                "std-error",
                format!(
                    "has {} rows but `coefficients` has {}; give one [x, y, z] row per coefficient row",
                    se.len(),
                    coefficients.len()
                ),
            ));
        }
        check_std_errors("std-error", se.as_flattened())?;
    }
    Ok(())
}
