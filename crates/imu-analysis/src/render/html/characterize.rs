//! The characterisation sections: thermal (warm-up fit and per-axis coefficients), impact (per-axis
//! peaks, couplings and settling) and dynamic (drift of the integrated angle, raw vs calibrated).

use maud::{Markup, html};

use super::{AXIS_NAMES, Section, figures, g, p, pm, strong, table, text};
use crate::characterize::dynamic::{DynamicReport, DynamicRun};
use crate::characterize::impact::{ImpactReport, Stats};
use crate::characterize::thermal::{AxisThermal, ThermalReport, ThermalVerdict};
use crate::characterize::units::DisplayUnit;
use crate::render::svg::Figure;

/// The thermal section: recommendation, warm-up fit, per-axis coefficients (accelerometers in
/// mg, gyros in deg/h, as in the charts) with the verdict of each axis, charts.
pub fn thermal_section(r: &ThermalReport, charts: &[Figure]) -> Section {
    let body = html! {
        p { strong { (r.recommendation) } }
        p {
            (format!(
                "{} samples, {} temperature readings over {:.0} s, {:.1} to {:.1} deg C, \
                 {} bins of {} s.",
                r.n_samples,
                r.n_temp_readings,
                r.duration_s,
                r.temp_range_c[0],
                r.temp_range_c[1],
                r.bins.len(),
                r.bin_s
            ))
        }
        @if let Some(w) = &r.warmup {
            p {
                (format!(
                    "Warm-up: tau = {} \u{b1} {} s, from {} to {} deg C (fit RMS {} K).",
                    g(w.tau_s), g(w.tau_std_s), g(w.start_c), g(w.final_c), g(w.residual_rms_c)
                ))
            }
        }
        @for sensor in ["accel", "gyro"] {
            (thermal_table(r, sensor))
        }
        p {
            "p: the test of the coefficient that accounts for the bias drift (coloured noise). \
             99 % bound: how large the coefficient could be when the test does not resolve it. "
            (r.confounding.note)
        }
        (figures(charts))
    };
    Section::new("Thermal test (warm-up)", body)
}

/// The coefficients of one sensor's axes, in the sensor's display unit.
fn thermal_table(r: &ThermalReport, sensor: &str) -> Markup {
    let u = DisplayUnit::of_sensor(sensor).label();
    let rows: Vec<Vec<Markup>> = r
        .axes
        .iter()
        .filter(|a| a.sensor == sensor)
        .map(thermal_row)
        .collect();
    table(
        &[
            &format!("{sensor} axis"),
            &format!("mean [{u}]"),
            &format!("coefficient [{u}/K]"),
            "t",
            "p",
            &format!("quadratic [{u}/K^2] (p)"),
            "as scale [ppm/K]",
            &format!("change over range [{u}]"),
            &format!("bin scatter [{u}]"),
            "verdict",
            &format!("99 % bound [{u}/K]"),
        ],
        &rows,
    )
}

fn thermal_row(a: &AxisThermal) -> Vec<Markup> {
    let unit = DisplayUnit::of_sensor(&a.sensor);
    let d = |v: f64| g(v * unit.per_si());
    let bound = match a.verdict {
        ThermalVerdict::NotResolvable { bound_per_k, .. } => d(bound_per_k),
        _ => "\u{2013}".into(),
    };
    vec![
        text(&a.axis),
        text(d(a.mean)),
        text(format!(
            "{} \u{b1} {}",
            d(a.bias_coeff_per_k),
            d(a.bias_coeff_std_per_k)
        )),
        text(format!("{:+.2}", a.linear.t_stats[1])),
        text(p(a.linear.p_values[1])),
        text(format!(
            "{} ({})",
            d(a.quadratic.coefficients[2]),
            p(a.quadratic.p_values[2])
        )),
        text(
            a.scale_coeff_per_k
                .map_or("\u{2013}".into(), |s| format!("{:.1}", s * 1e6)),
        ),
        text(d(a.predicted_change)),
        text(d(a.bin_noise)),
        if a.model_warranted {
            strong(a.verdict.word())
        } else {
            text(a.verdict.word())
        },
        text(bound),
    ]
}

/// `mean ± std [min, max]`, each times `scale` (a unit conversion).
fn stats_cell(s: &Stats, scale: f64) -> Markup {
    text(format!(
        "{} [{}, {}]",
        pm(s.mean * scale, s.std * scale),
        g(s.min * scale),
        g(s.max * scale)
    ))
}

/// The impact section: event count, per-axis summary, pooled couplings, charts (accelerometers
/// in m/s^2 and gyros in deg/s, as in the charts).
pub fn impact_section(r: &ImpactReport, charts: &[Figure]) -> Section {
    let axis = r.struck_axis.map_or("-", |a| AXIS_NAMES[a]);
    let s = &r.summary;
    let rows: Vec<Vec<Markup>> = (0..3)
        .map(|i| {
            let accel = &r.pooled_accel_coupling[i];
            let gyro = &r.pooled_gyro_coupling_rad_s_per_m_s2[i];
            let deg = 1f64.to_degrees();
            vec![
                text(AXIS_NAMES[i]),
                stats_cell(&s.accel_peak_m_s2[i], 1.0),
                stats_cell(&s.accel_peak_ratio[i], 1.0),
                text(pm(accel.value, accel.std_error)),
                stats_cell(&s.accel_settling_s[i], 1.0),
                stats_cell(&s.gyro_peak_rad_s[i], deg),
                text(pm(gyro.value * deg, gyro.std_error * deg)),
                stats_cell(&s.gyro_settling_s[i], 1.0),
            ]
        })
        .collect();
    let body = html! {
        p {
            (format!(
                "{} impacts detected (threshold {} m/s^2 on |accel magnitude - {} m/s^2|), \
                 struck axis {axis}.",
                r.events.len(),
                g(r.threshold_m_s2),
                g(r.baseline_m_s2)
            ))
        }
        (table(
            &[
                "axis",
                "accel peak [m/s^2]",
                "accel peak ratio",
                "accel coupling (pooled)",
                "accel settling [s]",
                "gyro peak [deg/s]",
                "gyro coupling [(deg/s)/(m/s^2)]",
                "gyro settling [s]",
            ],
            &rows,
        ))
        p {
            "Cells: mean \u{b1} std [min, max] across events. Coupling: least-squares slope of \
             each axis's response on the struck axis's response."
        }
        (figures(charts))
    };
    Section::new("Impact test", body)
}

/// The dynamic section: drift of the integrated angle, raw versus calibrated, charts.
pub fn dynamic_section(r: &DynamicReport, charts: &[Figure]) -> Section {
    let runs: Vec<(&str, &DynamicRun)> = [("raw", &r.raw), ("calibrated", &r.corrected)]
        .into_iter()
        .filter_map(|(n, x)| x.as_ref().map(|x| (n, x)))
        .collect();
    let rows: Vec<Vec<Markup>> = runs
        .iter()
        .map(|(n, x)| {
            vec![
                text(n),
                text(g(x.reference_delay_s * 1e3)),
                text(g(x.rate_correlation)),
                text(pm(x.growth_deg_s, x.growth_std_deg_s)),
                text(g(x.growth_deg_h)),
                text(g(x.final_error_deg)),
                text(g(x.max_abs_error_deg)),
                text(g(x.duration_s)),
            ]
        })
        .collect();
    let body = html! {
        p { (r.summary) }
        (table(
            &[
                "stream",
                "timing offset [ms]",
                "rate corr.",
                "growth [deg/s]",
                "growth [deg/h]",
                "final error [deg]",
                "max |error| [deg]",
                "span [s]",
            ],
            &rows,
        ))
        (figures(charts))
    };
    Section::new("Dynamic test (integrated angle vs table)", body)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_from_the_report_is_escaped() {
        let r = DynamicReport {
            reference: "table".into(),
            raw: None,
            corrected: None,
            growth_reduction_factor: None,
            calibration: crate::characterize::dynamic::CalibrationEffect::NotCompared,
            summary: "<script>alert(1)</script> & more".into(),
        };
        let s = dynamic_section(&r, &[]);
        assert!(
            s.html
                .contains("<p>&lt;script&gt;alert(1)&lt;/script&gt; &amp; more</p>"),
            "{}",
            s.html
        );
        assert!(!s.html.contains("<script>"), "{}", s.html);
        assert!(s.html.contains("<th>max |error| [deg]</th>"), "{}", s.html);
    }
}
