//! The characterisation sections: thermal (warm-up fit and per-axis coefficients), impact (per-axis
//! peaks, couplings and settling) and dynamic (drift of the integrated angle, raw vs calibrated).

use maud::{Markup, html};

use super::{AXIS_NAMES, Section, figures, g, pm, strong, table, text};
use crate::characterize::dynamic::{DynamicReport, DynamicRun};
use crate::characterize::impact::{ImpactReport, Stats};
use crate::characterize::thermal::{AxisThermal, ThermalReport};
use crate::render::svg::Chart;

/// The thermal section: recommendation, warm-up fit, per-axis coefficients, charts.
pub fn thermal_section(r: &ThermalReport, charts: &[Chart]) -> Section {
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
                    "Warm-up: tau = {:.0} \u{b1} {:.0} s, from {:.2} to {:.2} deg C \
                     (fit RMS {:.3} K).",
                    w.tau_s, w.tau_std_s, w.start_c, w.final_c, w.residual_rms_c
                ))
            }
        }
        (table(
            &[
                "axis",
                "mean",
                "bias coeff / K",
                "t",
                "p",
                "quadratic / K^2",
                "as scale coeff",
                "change over range",
                "bin scatter",
                "model?",
            ],
            &r.axes.iter().map(thermal_row).collect::<Vec<_>>(),
        ))
        p { "Units: accel m/s^2, gyro rad/s. " (r.confounding.note) }
        (figures(charts))
    };
    Section::new("Thermal test (warm-up)", body)
}

fn thermal_row(a: &AxisThermal) -> Vec<Markup> {
    let quadratic = if a.quadratic_significant {
        "significant"
    } else {
        "n.s."
    };
    vec![
        text(format!("{} {}", a.sensor, a.axis)),
        text(g(a.mean)),
        text(pm(a.bias_coeff_per_k, a.bias_coeff_std_per_k)),
        text(g(a.linear.t_stats[1])),
        text(g(a.linear.p_values[1])),
        text(format!("{} ({quadratic})", g(a.quadratic.coefficients[2]))),
        text(
            a.scale_coeff_per_k
                .map_or("\u{2013}".into(), |s| format!("{:.1} ppm/K", s * 1e6)),
        ),
        text(g(a.predicted_change)),
        text(g(a.bin_noise)),
        if a.model_warranted {
            strong("yes")
        } else {
            text("no")
        },
    ]
}

fn stats_cell(s: &Stats) -> Markup {
    text(format!(
        "{} [{}, {}]",
        pm(s.mean, s.std),
        g(s.min),
        g(s.max)
    ))
}

/// The impact section: event count, per-axis summary, pooled couplings, charts.
pub fn impact_section(r: &ImpactReport, charts: &[Chart]) -> Section {
    let axis = r.struck_axis.map_or("-", |a| AXIS_NAMES[a]);
    let s = &r.summary;
    let rows: Vec<Vec<Markup>> = (0..3)
        .map(|i| {
            let accel = &r.pooled_accel_coupling[i];
            let gyro = &r.pooled_gyro_coupling_rad_s_per_m_s2[i];
            vec![
                text(AXIS_NAMES[i]),
                stats_cell(&s.accel_peak_m_s2[i]),
                stats_cell(&s.accel_peak_ratio[i]),
                text(pm(accel.value, accel.std_error)),
                stats_cell(&s.accel_settling_s[i]),
                stats_cell(&s.gyro_peak_rad_s[i]),
                text(pm(gyro.value, gyro.std_error)),
                stats_cell(&s.gyro_settling_s[i]),
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
                "gyro peak [rad/s]",
                "gyro coupling [(rad/s)/(m/s^2)]",
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
pub fn dynamic_section(r: &DynamicReport, charts: &[Chart]) -> Section {
    let runs: Vec<(&str, &DynamicRun)> = [("raw", &r.raw), ("calibrated", &r.corrected)]
        .into_iter()
        .filter_map(|(n, x)| x.as_ref().map(|x| (n, x)))
        .collect();
    let rows: Vec<Vec<Markup>> = runs
        .iter()
        .map(|(n, x)| {
            vec![
                text(n),
                text(format!("{:.2}", x.reference_delay_s * 1e3)),
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
