//! The thermal verdict of one axis, and the report's recommendation, decided by the test that
//! accounts for coloured noise and by nothing else: "warranted" only when that test resolves
//! the coefficient and the change it predicts matters; otherwise the words say the effect is
//! not resolvable in this recording, how large it could be, and what recording would resolve it.

use serde::Serialize;

use super::{AxisThermal, ThermalOptions};
use crate::characterize::units::DisplayUnit;
use crate::render::number::p_value;

/// What one recording says about one axis's temperature dependence.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum ThermalVerdict {
    /// The temperature changed by less than 1 K between bins: nothing to test.
    NoTemperatureRange,
    /// The coloured-noise test resolves the coefficient (p below the significance level) and
    /// the change it predicts over the range exceeds the relevance threshold.
    Warranted,
    /// Resolved by the test, but the change it predicts over the range is below the relevance
    /// threshold (a real but negligible dependence).
    ResolvedButNegligible,
    /// Not resolvable in this recording: the test does not separate the coefficient from the
    /// bias drift.
    NotResolvable {
        /// Upper bound on |linear coefficient| at `1 - significance_p` confidence, output
        /// unit per K.
        bound_per_k: f64,
        /// The smallest |coefficient| this recording would resolve (the test's critical value
        /// times the standard error), output unit per K.
        detectable_per_k: f64,
        /// Upper bound on the change over the observed range, output unit.
        change_bound: f64,
    },
}

impl ThermalVerdict {
    /// The verdict from the linear and quadratic tests of `a` over `range_k` K.
    pub(super) fn decide(a: &AxisThermal, range_k: f64, options: &ThermalOptions) -> Self {
        if range_k < 1.0 {
            return Self::NoTemperatureRange;
        }
        if a.significant {
            return if a.relevant {
                Self::Warranted
            } else {
                Self::ResolvedButNegligible
            };
        }
        let t_crit = imu_stats::distributions::student_t_two_sided_quantile(
            options.significance_p,
            a.linear.dof_effective,
        );
        let detectable_per_k = t_crit * a.bias_coeff_std_per_k;
        let bound_per_k = a.bias_coeff_per_k.abs() + detectable_per_k;
        Self::NotResolvable {
            bound_per_k,
            detectable_per_k,
            change_bound: bound_per_k * range_k,
        }
    }

    /// A short word for tables: `warranted`, `negligible`, `not resolvable`, `no range`.
    pub fn word(&self) -> &'static str {
        match self {
            Self::NoTemperatureRange => "no range",
            Self::Warranted => "warranted",
            Self::ResolvedButNegligible => "negligible",
            Self::NotResolvable { .. } => "not resolvable",
        }
    }
}

/// `sensor axis` of an axis, e.g. `gyro x`.
fn name(a: &AxisThermal) -> String {
    format!("{} {}", a.sensor, a.axis)
}

/// Whether a thermal model is warranted, as data: the per-axis verdicts it is made of, the
/// temperature range and the test's settings. Programs read [`Recommendation::codes`] (or the
/// axes' [`ThermalVerdict`]s); the sentence is its `Display`. In JSON: `recommendation` (the
/// sentence) and `recommendation_codes`.
#[derive(Clone, Debug, PartialEq)]
pub struct Recommendation {
    /// The axes and their verdicts.
    pub axes: Vec<AxisThermal>,
    /// Temperature range between the bins, K.
    pub range_k: f64,
    /// Lowest and highest temperature, deg C.
    pub temp_range_c: [f64; 2],
    /// The test's settings.
    pub options: ThermalOptions,
}

impl Recommendation {
    /// Stable codes: `range_too_small` alone, else `model_warranted` or `no_model_warranted`,
    /// then `resolved_but_negligible` and `not_resolvable` when some axis is so.
    pub fn codes(&self) -> Vec<&'static str> {
        if self.range_k < 1.0 {
            return vec!["range_too_small"];
        }
        let any = |f: fn(&ThermalVerdict) -> bool| self.axes.iter().any(|a| f(&a.verdict));
        let mut v = vec![if any(|v| matches!(v, ThermalVerdict::Warranted)) {
            "model_warranted"
        } else {
            "no_model_warranted"
        }];
        if any(|v| matches!(v, ThermalVerdict::ResolvedButNegligible)) {
            v.push("resolved_but_negligible");
        }
        if any(|v| matches!(v, ThermalVerdict::NotResolvable { .. })) {
            v.push("not_resolvable");
        }
        v
    }
}

impl std::fmt::Display for Recommendation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&recommendation(
            &self.axes,
            self.range_k,
            self.temp_range_c,
            &self.options,
        ))
    }
}

/// `{"recommendation": sentence, "recommendation_codes": [code...]}`: use with
/// `#[serde(flatten)]`.
impl Serialize for Recommendation {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let mut s = serializer.serialize_struct("Recommendation", 2)?;
        s.serialize_field("recommendation", &self.to_string())?;
        s.serialize_field("recommendation_codes", &self.codes())?;
        s.end()
    }
}

/// The plain-language recommendation over `axes`, the temperature range `[tmin, tmax]` deg C
/// (`range_k` K between the bins): [`Recommendation`]'s words. Every sentence follows the
/// per-axis verdicts.
fn recommendation(
    axes: &[AxisThermal],
    range_k: f64,
    [tmin, tmax]: [f64; 2],
    options: &ThermalOptions,
) -> String {
    if range_k < 1.0 {
        return format!(
            "The temperature varied by only {range_k:.2} K; the data cannot support or rule \
             out a thermal model. Record through a temperature change of several K (a warm-up \
             from cold, or a temperature cycle)."
        );
    }
    let level = 100.0 * (1.0 - options.significance_p);
    let pick = |f: fn(&ThermalVerdict) -> bool| -> Vec<&AxisThermal> {
        axes.iter().filter(|a| f(&a.verdict)).collect()
    };
    let warranted = pick(|v| matches!(v, ThermalVerdict::Warranted));
    let negligible = pick(|v| matches!(v, ThermalVerdict::ResolvedButNegligible));
    let unresolved = pick(|v| matches!(v, ThermalVerdict::NotResolvable { .. }));
    let mut s = if warranted.is_empty() {
        format!("No thermal error model is warranted between {tmin:.1} and {tmax:.1} deg C.")
    } else {
        let list: Vec<String> = warranted.iter().map(|a| warranted_clause(a)).collect();
        format!(
            "A thermal error model IS warranted between {tmin:.1} and {tmax:.1} deg C for {}: \
             the test that accounts for the bias drift (coloured noise) resolves the \
             coefficient at p < {} and the change it predicts exceeds {} x the scatter of a \
             {} s mean.",
            list.join(", "),
            options.significance_p,
            options.relevance_factor,
            options.bin_s
        )
    };
    if !negligible.is_empty() {
        let list: Vec<String> = negligible.iter().map(|a| name(a)).collect();
        s.push_str(&format!(
            " Resolved but negligible (change over the range below {} x the scatter of a {} s \
             mean): {}.",
            options.relevance_factor,
            options.bin_s,
            list.join(", ")
        ));
    }
    if !unresolved.is_empty() {
        let list: Vec<String> = unresolved.iter().map(|a| unresolved_clause(a)).collect();
        s.push_str(&format!(
            " Not resolvable in this recording (the coefficient is not separated from the bias \
             drift), with {level:.0} % upper bounds: {}. To resolve smaller coefficients, \
             record a temperature cycle (heating and cooling, so temperature does not follow \
             time) or a wider temperature range; a longer warm-up alone adds drift as well as \
             data.",
            list.join("; ")
        ));
    }
    s
}

/// `gyro x (+0.41 deg/h/K, p 3.2e-3)`.
fn warranted_clause(a: &AxisThermal) -> String {
    let u = DisplayUnit::of_sensor(&a.sensor);
    let (p, which) = if a.linear.p_values[1] <= a.quadratic.p_values[2] {
        (a.linear.p_values[1], "")
    } else {
        (a.quadratic.p_values[2], "quadratic term ")
    };
    format!(
        "{} ({} {}/K, {which}p {})",
        name(a),
        u.format(a.bias_coeff_per_k),
        u.label(),
        p_value(p)
    )
}

/// `gyro x: |coefficient| < 1.1 deg/h/K (up to 17 deg/h over the range; this recording
/// resolves coefficients above 0.8 deg/h/K)`.
fn unresolved_clause(a: &AxisThermal) -> String {
    let ThermalVerdict::NotResolvable {
        bound_per_k,
        detectable_per_k,
        change_bound,
    } = a.verdict
    else {
        return name(a);
    };
    let u = DisplayUnit::of_sensor(&a.sensor);
    format!(
        "{}: |coefficient| < {} {l}/K (up to {} {l} over the range; this recording resolves \
         coefficients above {} {l}/K)",
        name(a),
        u.format(bound_per_k),
        u.format(change_bound),
        u.format(detectable_per_k),
        l = u.label()
    )
}
