//! Warm-up transient: after power-on the bias settles exponentially while the die heats up.

use crate::effect::{
    Effect, EffectDef, InvalidParam, check_finite, check_std_errors, fill, prefixed_xyz,
};
use crate::{Conditions, EffectKind, Triad, Vec3, ParamRole};
use serde::{Deserialize, Serialize};

/// Warm-up bias transient. Forward: `y = x + A exp(-t / tau)`, `t` = time since power-on.
///
/// TOML `[<triad>.warmup]`: `amplitude = [x, y, z]` (U, the extra bias at power-on),
/// `tau-s = 300.0` (s, shared time constant), optional
/// `std-error = { amplitude = [x, y, z], tau-s = ... }`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct Warmup {
    /// Extra bias at power-on per axis, in the triad's unit.
    pub amplitude: [f64; 3],
    /// Time constant of the exponential decay, seconds (> 0).
    pub tau_s: f64,
    /// One-sigma standard errors.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub std_error: Option<WarmupStdError>,
}

/// Standard errors of a [`Warmup`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct WarmupStdError {
    /// Of `amplitude`, in the triad's unit.
    pub amplitude: [f64; 3],
    /// Of `tau-s`, seconds.
    pub tau_s: f64,
}

/// Default time constant of an added (neutral) warm-up, seconds; a starting point for fits.
pub const DEFAULT_TAU_S: f64 = 300.0;

impl Warmup {
    /// The additive transient at `time_since_power_on_s`.
    pub fn offset(&self, time_since_power_on_s: f64) -> Vec3 {
        // Before power-on there is no transient to model; clamping avoids exp overflow on
        // nonsense negative times.
        let t = time_since_power_on_s.max(0.0);
        Vec3::from(self.amplitude) * (-t / self.tau_s).exp()
    }
}

impl Effect for Warmup {
    fn kind(&self) -> EffectKind {
        EffectKind::Warmup
    }
    fn param_roles(&self) -> Vec<ParamRole> {
        let mut v = ParamRole::axes();
        v.push(ParamRole::Scalar);
        v
    }
    fn param_names(&self) -> Vec<String> {
        let mut v = prefixed_xyz("amplitude");
        v.push("tau_s".to_string());
        v
    }
    fn param_units(&self, triad: Triad) -> Vec<String> {
        let mut v = vec![triad.unit().to_string(); 3];
        v.push("s".to_string());
        v
    }
    fn params(&self) -> Vec<f64> {
        let mut v = self.amplitude.to_vec();
        v.push(self.tau_s);
        v
    }
    fn set_params(&mut self, p: &[f64]) {
        let mut a = self.params();
        fill(&mut a, p);
        self.amplitude = [a[0], a[1], a[2]];
        self.tau_s = a[3];
    }
    fn std_errors(&self) -> Option<Vec<f64>> {
        self.std_error.map(|s| {
            let mut v = s.amplitude.to_vec();
            v.push(s.tau_s);
            v
        })
    }
    fn set_std_errors(&mut self, se: Option<Vec<f64>>) {
        self.std_error = se.map(|s| {
            let mut a = [0.0; 4];
            fill(&mut a, &s);
            WarmupStdError {
                amplitude: [a[0], a[1], a[2]],
                tau_s: a[3],
            }
        });
    }
    fn forward(&self, x: Vec3, c: &Conditions) -> Vec3 {
        x + self.offset(c.time_since_power_on_s)
    }
    fn inverse(&self, y: Vec3, c: &Conditions) -> Vec3 {
        y - self.offset(c.time_since_power_on_s)
    }
}

impl EffectDef for Warmup {
    const ID: &'static str = "warmup";
    const DESCRIPTION: &'static str = "warm-up transient: extra bias A exp(-t/tau) decaying after power-on while the sensor heats up";
    fn neutral() -> Self {
        Warmup {
            amplitude: [0.0; 3],
            tau_s: DEFAULT_TAU_S,
            std_error: None,
        }
    }
    fn field_units(triad: Triad) -> Vec<(&'static str, String)> {
        vec![
            ("amplitude", triad.unit().to_string()),
            ("tau-s", "s".to_string()),
        ]
    }
    fn validate(&self, _triad: Triad) -> Result<(), InvalidParam> {
        check_finite("amplitude", &self.amplitude)?;
        check_finite("tau-s", &[self.tau_s])?;
        if self.tau_s <= 0.0 {
            return Err(InvalidParam::new(
                "tau-s",
                format!(
                    "time constant {} s must be > 0 (seconds)",
                    self.tau_s
                ),
            ));
        }
        if let Some(se) = &self.std_error {
            check_std_errors("std-error.amplitude", &se.amplitude)?;
            check_std_errors("std-error.tau-s", &[se.tau_s])?;
        }
        Ok(())
    }
}
