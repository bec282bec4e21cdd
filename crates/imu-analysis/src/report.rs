//! HTML report sections for the thermal, impact and dynamic analyses: self-contained fragments
//! (tables and inline SVG charts, no external assets) that a workbench report embeds, plus a
//! minimal standalone page around them.

use std::fmt::Write as _;

use crate::dynamic::{DynamicReport, DynamicRun};
use crate::impact::{ImpactReport, Stats};
use crate::plot::{Chart, render_svg};
use crate::thermal::ThermalReport;

/// One titled HTML fragment.
#[derive(Debug, Clone, PartialEq)]
pub struct Section {
    /// Heading text (plain, not HTML).
    pub title: String,
    /// Body: self-contained HTML (inline SVG, no scripts, no external references).
    pub html: String,
}

/// Escapes text for HTML content and attribute values.
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            _ => out.push(c),
        }
    }
    out
}

/// A chart as inline SVG (the XML declaration dropped so it can sit inside HTML).
pub fn inline_svg(chart: &Chart) -> String {
    let svg = render_svg(chart);
    match svg.find("<svg") {
        Some(i) => svg[i..].to_string(),
        None => svg,
    }
}

fn g(v: f64) -> String {
    if !v.is_finite() {
        "&ndash;".into()
    } else if v == 0.0 || (1e-3..1e5).contains(&v.abs()) {
        format!("{v:.4}")
    } else {
        format!("{v:.3e}")
    }
}

fn table(out: &mut String, head: &[&str], rows: &[Vec<String>]) {
    out.push_str("<table class=\"imu\"><thead><tr>");
    for h in head {
        let _ = write!(out, "<th>{}</th>", escape(h));
    }
    out.push_str("</tr></thead><tbody>");
    for r in rows {
        out.push_str("<tr>");
        for c in r {
            let _ = write!(out, "<td>{c}</td>");
        }
        out.push_str("</tr>");
    }
    out.push_str("</tbody></table>\n");
}

fn figures(out: &mut String, charts: &[Chart]) {
    for c in charts {
        let _ = writeln!(out, "<figure>{}</figure>", inline_svg(c));
    }
}

/// The thermal section: recommendation, warm-up fit, per-axis coefficients, charts.
pub fn thermal_section(r: &ThermalReport, charts: &[Chart]) -> Section {
    let mut h = String::new();
    let _ = writeln!(h, "<p><strong>{}</strong></p>", escape(&r.recommendation));
    let _ = writeln!(
        h,
        "<p>{} samples, {} temperature readings over {:.0} s, {:.1} to {:.1} deg C, {} bins of {} s.</p>",
        r.n_samples,
        r.n_temp_readings,
        r.duration_s,
        r.temp_range_c[0],
        r.temp_range_c[1],
        r.bins.len(),
        r.bin_s
    );
    if let Some(w) = &r.warmup {
        let _ = writeln!(
            h,
            "<p>Warm-up: tau = {:.0} &plusmn; {:.0} s, from {:.2} to {:.2} deg C (fit RMS {:.3} K).</p>",
            w.tau_s, w.tau_std_s, w.start_c, w.final_c, w.residual_rms_c
        );
    }
    let rows: Vec<Vec<String>> = r
        .axes
        .iter()
        .map(|a| {
            vec![
                escape(&format!("{} {}", a.sensor, a.axis)),
                g(a.mean),
                format!(
                    "{} &plusmn; {}",
                    g(a.bias_coeff_per_k),
                    g(a.bias_coeff_std_per_k)
                ),
                g(a.linear.t_stats[1]),
                g(a.linear.p_values[1]),
                format!(
                    "{} ({})",
                    g(a.quadratic.coefficients[2]),
                    if a.quadratic_significant {
                        "significant"
                    } else {
                        "n.s."
                    }
                ),
                a.scale_coeff_per_k
                    .map_or("&ndash;".into(), |s| format!("{:.1} ppm/K", s * 1e6)),
                g(a.predicted_change),
                g(a.bin_noise),
                if a.model_warranted {
                    "<strong>yes</strong>".into()
                } else {
                    "no".into()
                },
            ]
        })
        .collect();
    table(
        &mut h,
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
        &rows,
    );
    let _ = writeln!(
        h,
        "<p>Units: accel m/s^2, gyro rad/s. {}</p>",
        escape(&r.confounding.note)
    );
    figures(&mut h, charts);
    Section {
        title: "Thermal test (warm-up)".into(),
        html: h,
    }
}

fn stats_cell(s: &Stats) -> String {
    format!(
        "{} &plusmn; {} [{}, {}]",
        g(s.mean),
        g(s.std),
        g(s.min),
        g(s.max)
    )
}

/// The impact section: event count, per-axis summary, pooled couplings, charts.
pub fn impact_section(r: &ImpactReport, charts: &[Chart]) -> Section {
    let mut h = String::new();
    let axis = r.struck_axis.map_or("-", |a| ["x", "y", "z"][a]);
    let _ = writeln!(
        h,
        "<p>{} impacts detected (threshold {} m/s^2 on |accel magnitude - {} m/s^2|), struck axis {axis}.</p>",
        r.events.len(),
        g(r.threshold_m_s2),
        g(r.baseline_m_s2)
    );
    let s = &r.summary;
    let rows: Vec<Vec<String>> = (0..3)
        .map(|i| {
            vec![
                ["x", "y", "z"][i].into(),
                stats_cell(&s.accel_peak_m_s2[i]),
                stats_cell(&s.accel_peak_ratio[i]),
                format!(
                    "{} &plusmn; {}",
                    g(r.pooled_accel_coupling[i].value),
                    g(r.pooled_accel_coupling[i].std_error)
                ),
                stats_cell(&s.accel_settling_s[i]),
                stats_cell(&s.gyro_peak_rad_s[i]),
                format!(
                    "{} &plusmn; {}",
                    g(r.pooled_gyro_coupling_rad_s_per_m_s2[i].value),
                    g(r.pooled_gyro_coupling_rad_s_per_m_s2[i].std_error)
                ),
                stats_cell(&s.gyro_settling_s[i]),
            ]
        })
        .collect();
    table(
        &mut h,
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
    );
    h.push_str(
        "<p>Cells: mean &plusmn; std [min, max] across events. Coupling: least-squares slope of \
         each axis's response on the struck axis's response.</p>\n",
    );
    figures(&mut h, charts);
    Section {
        title: "Impact test".into(),
        html: h,
    }
}

/// The dynamic section: drift of the integrated angle, raw versus calibrated, charts.
pub fn dynamic_section(r: &DynamicReport, charts: &[Chart]) -> Section {
    let mut h = String::new();
    let _ = writeln!(h, "<p>{}</p>", escape(&r.summary));
    let runs: Vec<(&str, &DynamicRun)> = [("raw", &r.raw), ("calibrated", &r.corrected)]
        .into_iter()
        .filter_map(|(n, x)| x.as_ref().map(|x| (n, x)))
        .collect();
    let rows: Vec<Vec<String>> = runs
        .iter()
        .map(|(n, x)| {
            vec![
                (*n).into(),
                format!("{:.2}", x.reference_delay_s * 1e3),
                g(x.rate_correlation),
                format!("{} &plusmn; {}", g(x.growth_deg_s), g(x.growth_std_deg_s)),
                g(x.growth_deg_h),
                g(x.final_error_deg),
                g(x.max_abs_error_deg),
                g(x.duration_s),
            ]
        })
        .collect();
    table(
        &mut h,
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
    );
    figures(&mut h, charts);
    Section {
        title: "Dynamic test (integrated angle vs table)".into(),
        html: h,
    }
}

/// A standalone HTML page holding `sections` (inline CSS only).
pub fn page(title: &str, sections: &[Section]) -> String {
    let mut h = String::new();
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title>\n\
         <style>body{{font-family:sans-serif;max-width:1100px;margin:auto}}\
         table.imu{{border-collapse:collapse;font-size:0.85em}}\
         table.imu td,table.imu th{{border:1px solid #bbb;padding:2px 6px}}\
         figure{{margin:1em 0}}svg{{max-width:100%;height:auto}}</style></head><body>\n<h1>{}</h1>\n",
        escape(title),
        escape(title)
    );
    for s in sections {
        let _ = write!(
            h,
            "<section><h2>{}</h2>\n{}</section>\n",
            escape(&s.title),
            s.html
        );
    }
    h.push_str("</body></html>\n");
    h
}
