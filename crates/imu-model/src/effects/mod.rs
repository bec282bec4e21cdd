//! The effect registry: one line per effect, in canonical application order.
//!
//! `register_effects!` generates, from that list, the `EffectKind` enum, the `TriadModel`
//! struct (one optional field per effect, named after the module), and the plumbing that maps
//! between them. Adding an effect is therefore: write `src/effects/<name>.rs` implementing
//! [`Effect`] and [`EffectDef`], and add `<name>::<Type>` to the list at the right place in the
//! order (see the crate docs for the checklist).

use crate::effect::{Effect, EffectDef, InvalidParam};
use crate::{NoiseModel, Triad};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

macro_rules! register_effects {
    ($( $module:ident :: $Type:ident ),+ $(,)?) => {
        $( pub mod $module; pub use $module::$Type; )+

        /// Identifies an effect; the variants are in canonical application order.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub enum EffectKind {
            $(
                #[doc = concat!("See [`", stringify!($Type), "`].")]
                $Type,
            )+
        }

        impl EffectKind {
            /// Every effect, in canonical application order (forward applies them in this order,
            /// inverse undoes them in reverse).
            pub const ALL: [EffectKind; [$(stringify!($Type)),+].len()] = [$(EffectKind::$Type),+];

            /// Kebab-case id used in TOML, JSON and on the command line (e.g. `"g-sensitivity"`).
            pub fn id(&self) -> &'static str {
                match self { $(EffectKind::$Type => <$Type as EffectDef>::ID,)+ }
            }

            /// One line in physical terms.
            pub fn description(&self) -> &'static str {
                match self { $(EffectKind::$Type => <$Type as EffectDef>::DESCRIPTION,)+ }
            }

            /// Whether the effect is a gain (scales with the input; see [`EffectDef::GAIN`]).
            pub fn is_gain(&self) -> bool {
                match self { $(EffectKind::$Type => <$Type as EffectDef>::GAIN,)+ }
            }

            /// Whether the effect exists for `triad` (g-sensitivity: gyro only; lever-arm: accel only).
            pub fn applies_to(&self, triad: Triad) -> bool {
                match self { $(EffectKind::$Type => <$Type as EffectDef>::applies_to(triad),)+ }
            }

            /// `(field, unit)` pairs describing the effect's TOML table for `triad`.
            pub fn field_units(&self, triad: Triad) -> Vec<(&'static str, String)> {
                match self { $(EffectKind::$Type => <$Type as EffectDef>::field_units(triad),)+ }
            }

            /// A boxed effect with neutral parameters (forward is the identity).
            pub fn neutral(&self) -> Box<dyn Effect> {
                match self { $(EffectKind::$Type => Box::new(<$Type as EffectDef>::neutral()),)+ }
            }

            /// Module/field name (snake case), used only by the registry consistency test.
            #[cfg(test)]
            pub(crate) fn module_name(&self) -> &'static str {
                match self { $(EffectKind::$Type => stringify!($module),)+ }
            }
        }

        /// The error model of one triad: every effect is optional; absent means "no such error".
        ///
        /// In TOML each present effect is a table `[<triad>.<effect-id>]`; `noise` is
        /// `[<triad>.noise]` and `residual-rms = [x, y, z]` sits directly in `[<triad>]`.
        #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
        #[serde(deny_unknown_fields, rename_all = "kebab-case")]
        pub struct TriadModel {
            $(
                #[doc = concat!("Optional [`", stringify!($Type), "`] stage.")]
                #[serde(default, skip_serializing_if = "Option::is_none")]
                pub $module: Option<$Type>,
            )+
            /// Stochastic noise description (not inverted; used by the simulator and noise tools).
            #[serde(default, skip_serializing_if = "Option::is_none")]
            pub noise: Option<NoiseModel>,
            /// RMS of the fit residuals per axis, in the triad's unit (informational, from the fit).
            #[serde(default, skip_serializing_if = "Option::is_none")]
            pub residual_rms: Option<[f64; 3]>,
        }

        impl TriadModel {
            /// The present effects, in canonical order.
            pub fn effects(&self) -> Vec<&dyn Effect> {
                let mut v: Vec<&dyn Effect> = Vec::new();
                $( if let Some(e) = &self.$module { v.push(e); } )+
                v
            }

            /// Every effect slot in canonical order (`None` where absent). Allocation-free, so the
            /// daemon's per-sample inverse never touches the heap.
            pub fn effect_slots(&self) -> [Option<&dyn Effect>; EffectKind::ALL.len()] {
                [$( self.$module.as_ref().map(|e| e as &dyn Effect), )+]
            }

            /// The present effects, mutable, in canonical order.
            pub fn effects_mut(&mut self) -> Vec<&mut dyn Effect> {
                let mut v: Vec<&mut dyn Effect> = Vec::new();
                $( if let Some(e) = &mut self.$module { v.push(e); } )+
                v
            }

            /// The effect of kind `k`, if present.
            pub fn get(&self, k: EffectKind) -> Option<&dyn Effect> {
                match k { $(EffectKind::$Type => self.$module.as_ref().map(|e| e as &dyn Effect),)+ }
            }

            /// The effect of kind `k`, mutable, if present.
            pub fn get_mut(&mut self, k: EffectKind) -> Option<&mut dyn Effect> {
                match k { $(EffectKind::$Type => self.$module.as_mut().map(|e| e as &mut dyn Effect),)+ }
            }

            /// Whether the effect is present.
            pub fn has(&self, k: EffectKind) -> bool {
                match k { $(EffectKind::$Type => self.$module.is_some(),)+ }
            }

            /// Add the effect with neutral parameters (no change to the output) if absent; an
            /// already present effect keeps its parameters. Does not check
            /// [`EffectKind::applies_to`]: validation reports a misplaced effect.
            pub fn add(&mut self, k: EffectKind) {
                match k {
                    $(EffectKind::$Type => {
                        if self.$module.is_none() {
                            self.$module = Some(<$Type as EffectDef>::neutral());
                        }
                    })+
                }
            }

            /// Remove the effect (no-op if absent).
            pub fn remove(&mut self, k: EffectKind) {
                match k { $(EffectKind::$Type => self.$module = None,)+ }
            }

            /// Validate every present effect for `triad`; keys are relative to the triad table.
            pub(crate) fn validate_effects(&self, triad: Triad) -> Result<(), InvalidParam> {
                $(
                    if let Some(e) = &self.$module {
                        let id = <$Type as EffectDef>::ID;
                        if !<$Type as EffectDef>::applies_to(triad) {
                            let valid: Vec<&str> = Triad::ALL
                                .iter()
                                .filter(|t| <$Type as EffectDef>::applies_to(**t))
                                .map(|t| t.name())
                                .collect();
                            return Err(InvalidParam::new(
                                id,
                                format!(
                                    "effect `{id}` does not apply to {triad} (it applies to: {}); remove [{triad}.{id}]",
                                    valid.join(", ")
                                ),
                            ));
                        }
                        e.validate(triad).map_err(|err| err.within(id))?;
                    }
                )+
                Ok(())
            }
        }
    };
}

// The canonical application order (forward: top to bottom; inverse: bottom to top).
// Why this order is in the crate docs ("Canonical order").
register_effects! {
    lever_arm::LeverArm,
    misalignment::Misalignment,
    scale::Scale,
    asymmetric_scale::AsymmetricScale,
    temp_scale::TempScale,
    scale_nonlinearity::ScaleNonlinearity,
    bias::Bias,
    temp_bias::TempBias,
    warmup::Warmup,
    g_sensitivity::GSensitivity,
}

impl fmt::Display for EffectKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.id())
    }
}

impl FromStr for EffectKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        EffectKind::ALL
            .into_iter()
            .find(|k| k.id() == s)
            .ok_or_else(|| format!("unknown effect `{s}`; valid effects: {}", valid_ids()))
    }
}

/// Comma-separated list of all effect ids in canonical order.
pub(crate) fn valid_ids() -> String {
    EffectKind::ALL
        .iter()
        .map(|k| k.id())
        .collect::<Vec<_>>()
        .join(", ")
}

impl Serialize for EffectKind {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.id())
    }
}

impl<'de> Deserialize<'de> for EffectKind {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_are_kebab_case_module_names_and_unique() {
        let mut seen = std::collections::HashSet::new();
        for k in EffectKind::ALL {
            assert_eq!(k.id(), k.module_name().replace('_', "-"), "{k:?}");
            assert!(seen.insert(k.id()), "duplicate id {}", k.id());
            assert_eq!(k.id().parse::<EffectKind>(), Ok(k));
            assert_eq!(k.neutral().kind(), k);
            assert!(!k.description().is_empty());
        }
    }

    #[test]
    fn canonical_order_and_ids_match_the_documented_list() {
        let ids: Vec<&str> = EffectKind::ALL.iter().map(|k| k.id()).collect();
        assert_eq!(
            ids,
            [
                "lever-arm",
                "misalignment",
                "scale",
                "asymmetric-scale",
                "temp-scale",
                "scale-nonlinearity",
                "bias",
                "temp-bias",
                "warmup",
                "g-sensitivity"
            ]
        );
    }

    #[test]
    fn applicability_per_triad() {
        for k in EffectKind::ALL {
            let expected = match k {
                EffectKind::GSensitivity => [false, true, false],
                EffectKind::LeverArm => [true, false, false],
                _ => [true, true, true],
            };
            let got = Triad::ALL.map(|t| k.applies_to(t));
            assert_eq!(got, expected, "{k}");
        }
    }

    #[test]
    fn unknown_id_error_lists_valid_ids() {
        let err = "biass".parse::<EffectKind>().unwrap_err();
        assert!(err.contains("`biass`"), "{err}");
        assert!(err.contains("lever-arm, misalignment, scale"), "{err}");
        assert!(err.contains("g-sensitivity"), "{err}");
    }

    #[test]
    fn effect_kind_serializes_as_its_id() {
        #[derive(Serialize, Deserialize, PartialEq, Debug)]
        struct W {
            k: EffectKind,
        }
        let text = toml::to_string(&W {
            k: EffectKind::GSensitivity,
        })
        .unwrap();
        assert_eq!(text.trim(), "k = \"g-sensitivity\"");
        let back: W = toml::from_str(&text).unwrap();
        assert_eq!(back.k, EffectKind::GSensitivity);
        assert!(toml::from_str::<W>("k = \"gsens\"").is_err());
    }
}
