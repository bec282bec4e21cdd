//! HTML report sections for the thermal, impact and dynamic analyses and the model workbench
//! (verdict, ladder, per-triad diagnosis): self-contained fragments (tables and inline SVG
//! charts, no external assets) that a workbench report embeds, plus a minimal standalone page
//! around them.

use std::fmt::Write as _;

use crate::characterize::dynamic::{DynamicReport, DynamicRun};
use crate::characterize::impact::{ImpactReport, Stats};
use crate::characterize::thermal::ThermalReport;
use crate::render::svg::{Chart, Series, Style, render_svg};
use crate::workbench::{LadderStep, StepSummary, TriadDiagnosis};

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

const AXIS_NAMES: [&str; 3] = ["x", "y", "z"];

fn yes_no(b: bool) -> &'static str {
    if b { "yes" } else { "no" }
}

/// The verdict per triad in plain words, for the top of a workbench report.
pub fn verdict_section(diagnoses: &[&TriadDiagnosis]) -> Section {
    let mut h = String::new();
    for d in diagnoses {
        let state = if d.consistent {
            "consistent with its noise floor"
        } else if d.consistent_with_drift {
            "consistent with its noise floor plus a slow bias drift"
        } else {
            "NOT consistent with its noise floor: something is missing from the model"
        };
        let _ = writeln!(
            h,
            "<p><strong>{}: {}.</strong> {}</p>",
            escape(&d.triad.to_string()),
            escape(state),
            escape(&d.verdict)
        );
        if let Some(top) = d.candidates.iter().find(|c| c.claimed) {
            let _ = writeln!(
                h,
                "<p>Add <code>{}</code> to the {} model (p = {}, &Delta;AIC = {:.1}).</p>",
                escape(top.effect.id()),
                escape(&d.triad.to_string()),
                g(top.p_value),
                top.delta_aic
            );
        }
    }
    Section {
        title: "Verdict".into(),
        html: h,
    }
}

fn step_cells(s: &StepSummary) -> Vec<String> {
    let mut v: Vec<String> = (0..3)
        .map(|a| format!("{} / {}", g(s.residual_rms[a]), g(s.noise_floor_rms[a])))
        .collect();
    v.push(g(s.p_value));
    v.push(yes_no(s.consistent_with_drift).into());
    v
}

fn ladder_chart(
    steps: &[LadderStep],
    triad: &str,
    unit: &str,
    pick: fn(&LadderStep) -> &StepSummary,
) -> Chart {
    let mut series = Vec::new();
    for (a, name) in AXIS_NAMES.iter().enumerate() {
        series.push(Series {
            name: format!("residual {name}"),
            points: steps
                .iter()
                .enumerate()
                .map(|(i, s)| (i as f64, pick(s).residual_rms[a]))
                .collect(),
            style: Style::Points,
        });
    }
    for (a, name) in AXIS_NAMES.iter().enumerate() {
        series.push(Series {
            name: format!("noise floor {name}"),
            points: steps
                .iter()
                .enumerate()
                .map(|(i, s)| (i as f64, pick(s).noise_floor_rms[a]))
                .collect(),
            style: Style::Line,
        });
    }
    Chart {
        title: format!("{triad}: residual RMS per ladder step vs the noise floor"),
        x_label: "ladder step".into(),
        y_label: format!("RMS [{unit}]"),
        log_y: true,
        series,
        ..Chart::default()
    }
}

/// The ladder: each step (effect added, residual RMS against the noise floor per axis, p) as a
/// table, and a chart per triad of the residual RMS per axis at each step with the noise floor
/// drawn as a line.
pub fn ladder_section(steps: &[LadderStep]) -> Section {
    let mut h = String::new();
    h.push_str(
        "<p>From the base model, the workbench adds the best claimed effect of a triad that is \
         not yet consistent with its noise floor, one at a time, until both are consistent or \
         nothing more is claimed. Cells: residual RMS / noise floor RMS per axis \
         (accel m/s^2, gyro rad/s).</p>\n",
    );
    let rows: Vec<Vec<String>> = steps
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let mut r = vec![
                i.to_string(),
                s.added.map_or("base model".into(), |(t, k)| {
                    escape(&format!("{t} {}", k.id()))
                }),
            ];
            r.extend(step_cells(&s.accel));
            r.extend(step_cells(&s.gyro));
            if let Some(m) = &s.gyro.moves {
                r.push(format!(
                    "{} / {} (p {})",
                    g(m.residual_rms_rad),
                    g(m.expected_rms_rad),
                    g(m.p_value)
                ));
            }
            r
        })
        .collect();
    let mut header = vec![
        "step",
        "added",
        "accel x",
        "accel y",
        "accel z",
        "accel p",
        "accel ok (drift)",
        "gyro x",
        "gyro y",
        "gyro z",
        "gyro p",
        "gyro ok (drift)",
    ];
    if steps.iter().any(|s| s.gyro.moves.is_some()) {
        // Reference-free: the gyro gains against the moves between poses.
        header.push("gyro gains: direction error / expected after the moves (rad)");
    }
    table(&mut h, &header, &rows);
    figures(
        &mut h,
        &[
            ladder_chart(steps, "accel", "m/s^2", |s| &s.accel),
            ladder_chart(steps, "gyro", "rad/s", |s| &s.gyro),
        ],
    );
    Section {
        title: "The ladder".into(),
        html: h,
    }
}

/// One triad's diagnosis: verdict, residual RMS against the noise floor per axis, the worst
/// segments, residual charts (against time and against the signal each axis correlates with
/// most), the pooled Allan deviation of the noise floor, spectral lines, the ranked candidates
/// and ambiguities, and the model change for the top claimed candidate. `signals` are the
/// workbench's explanatory signals for this triad
/// ([`Workbench::signal_values`](crate::workbench::Workbench::signal_values)), in the order of
/// `d.segments`; pass an empty slice to leave the correlate charts out.
pub fn diagnose_section(d: &TriadDiagnosis, signals: &[(String, Vec<f64>)]) -> Section {
    let triad = d.triad.to_string();
    let unit = d.triad.unit();
    let mut h = String::new();
    let _ = writeln!(h, "<p><strong>{}</strong></p>", escape(&d.verdict));
    let effects: Vec<&str> = d.effects.iter().map(|k| k.id()).collect();
    let _ = writeln!(
        h,
        "<p>Model: {}. chi2 {:.1} on {} degrees of freedom, p = {} (with drift p = {}).</p>",
        escape(&effects.join(" + ")),
        d.chi2,
        d.dof,
        g(d.p_value),
        g(d.p_value_with_drift)
    );
    let rows: Vec<Vec<String>> = d
        .axes
        .iter()
        .enumerate()
        .map(|(a, v)| {
            vec![
                AXIS_NAMES[a].into(),
                g(v.residual_rms),
                g(v.noise_floor_rms),
                g(v.noise_floor_with_drift_rms),
                g(v.residual_rms / v.noise_floor_rms),
                format!("{:.1} / {:.0}", v.chi2, v.dof),
                g(v.p_value),
            ]
        })
        .collect();
    table(
        &mut h,
        &[
            "axis",
            &format!("residual RMS [{unit}]"),
            &format!("noise floor RMS [{unit}]"),
            &format!("floor with drift [{unit}]"),
            "ratio",
            "chi2 / dof",
            "p",
        ],
        &rows,
    );

    h.push_str("<h3>Worst segments</h3>\n");
    let rows: Vec<Vec<String>> = d
        .worst
        .iter()
        .filter_map(|&i| d.segments.get(i))
        .map(|s| {
            vec![
                s.segment.to_string(),
                format!("{:?}", s.kind).to_lowercase(),
                format!("{:.1} &ndash; {:.1}", s.start_s, s.end_s),
                s.residual
                    .iter()
                    .map(|v| g(*v))
                    .collect::<Vec<_>>()
                    .join(", "),
                s.z.iter()
                    .map(|v| format!("{v:.1}"))
                    .collect::<Vec<_>>()
                    .join(", "),
            ]
        })
        .collect();
    table(
        &mut h,
        &[
            "segment",
            "kind",
            "time [s]",
            &format!("residual x, y, z [{unit}]"),
            "z x, y, z",
        ],
        &rows,
    );

    let mut charts = vec![Chart {
        title: format!("{triad}: segment residual vs time"),
        x_label: "time [s]".into(),
        y_label: format!("residual [{unit}]"),
        series: AXIS_NAMES
            .iter()
            .enumerate()
            .map(|(a, name)| Series {
                name: (*name).into(),
                points: d
                    .segments
                    .iter()
                    .map(|s| (0.5 * (s.start_s + s.end_s), s.residual[a]))
                    .collect(),
                style: Style::Points,
            })
            .collect(),
        ..Chart::default()
    }];
    // Residual against the strongest correlate, one chart per signal (axes sharing it together).
    let mut by_signal: Vec<(String, Vec<(usize, f64)>)> = Vec::new();
    for (a, st) in d.structure.iter().enumerate() {
        if let Some(c) = st.correlates.first() {
            match by_signal.iter_mut().find(|(n, _)| *n == c.signal) {
                Some((_, v)) => v.push((a, c.r)),
                None => by_signal.push((c.signal.clone(), vec![(a, c.r)])),
            }
        }
    }
    for (name, axes) in by_signal {
        let Some((_, values)) = signals.iter().find(|(n, _)| *n == name) else {
            continue;
        };
        if values.len() != d.segments.len() {
            continue;
        }
        charts.push(Chart {
            title: format!("{triad}: residual vs {name}"),
            x_label: name.clone(),
            y_label: format!("residual [{unit}]"),
            series: axes
                .iter()
                .map(|&(a, r)| Series {
                    name: format!("{} (r = {r:.2})", AXIS_NAMES[a]),
                    points: values
                        .iter()
                        .zip(&d.segments)
                        .map(|(x, s)| (*x, s.residual[a]))
                        .collect(),
                    style: Style::Points,
                })
                .collect(),
            ..Chart::default()
        });
    }
    charts.push(Chart {
        title: format!(
            "{triad}: Allan deviation of the noise floor ({})",
            d.noise_floor.source
        ),
        x_label: "tau [s]".into(),
        y_label: format!("Allan deviation [{unit}]"),
        log_x: true,
        log_y: true,
        series: AXIS_NAMES
            .iter()
            .enumerate()
            .map(|(a, name)| Series {
                name: (*name).into(),
                points: d.noise_floor.allan[a].clone(),
                style: Style::Line,
            })
            .collect(),
    });
    figures(&mut h, &charts);

    // Every other candidate explanatory signal, folded away: where the strongest correlate does
    // not tell the story, the pattern may show against another.
    let shown: Vec<String> = charts.iter().map(|c| c.title.clone()).collect();
    let others: Vec<Chart> = signals
        .iter()
        .filter(|(name, values)| {
            values.len() == d.segments.len()
                && !shown.contains(&format!("{triad}: residual vs {name}"))
        })
        .map(|(name, values)| Chart {
            title: format!("{triad}: residual vs {name}"),
            x_label: name.clone(),
            y_label: format!("residual [{unit}]"),
            series: AXIS_NAMES
                .iter()
                .enumerate()
                .map(|(a, axis)| {
                    let r = d.structure[a]
                        .correlates
                        .iter()
                        .find(|c| c.signal == *name)
                        .map_or(0.0, |c| c.r);
                    Series {
                        name: format!("{axis} (r = {r:.2})"),
                        points: values
                            .iter()
                            .zip(&d.segments)
                            .map(|(x, s)| (*x, s.residual[a]))
                            .collect(),
                        style: Style::Points,
                    }
                })
                .collect(),
            ..Chart::default()
        })
        .collect();
    if !others.is_empty() {
        let _ = writeln!(
            h,
            "<details><summary>Residual against every other candidate signal ({})</summary>",
            others.len()
        );
        figures(&mut h, &others);
        h.push_str("</details>\n");
    }

    if !d.spectral_lines.is_empty() {
        h.push_str("<h3>Spectral lines</h3>\n");
        let rows: Vec<Vec<String>> = d
            .spectral_lines
            .iter()
            .map(|l| {
                vec![
                    AXIS_NAMES.get(l.axis).copied().unwrap_or("?").into(),
                    g(l.frequency_hz),
                    g(l.amplitude),
                    format!("{:.1}", l.ratio),
                ]
            })
            .collect();
        table(
            &mut h,
            &[
                "axis",
                "frequency [Hz]",
                &format!("amplitude [{unit}]"),
                "x noise",
            ],
            &rows,
        );
    }

    h.push_str("<h3>Candidates</h3>\n");
    let rows: Vec<Vec<String>> = d
        .candidates
        .iter()
        .map(|c| {
            vec![
                escape(c.effect.id()),
                c.new_params.to_string(),
                g(c.f),
                g(c.p_value),
                format!("{:.1}", c.delta_aic),
                format!("{:.2}", c.share_of_excess),
                if c.claimed {
                    "<strong>claimed</strong>".into()
                } else if c.significant {
                    "significant".into()
                } else {
                    "no".into()
                },
                escape(&c.explanation),
            ]
        })
        .collect();
    table(
        &mut h,
        &[
            "effect",
            "new params",
            "F",
            "p",
            "\u{0394}AIC",
            "share of excess",
            "significant / claimed",
            "explanation",
        ],
        &rows,
    );
    for a in &d.ambiguities {
        let _ = writeln!(
            h,
            "<p>Ambiguous: {} and {} explain the residual alike (pattern correlation {:.2}); \
             separate them with {}.</p>",
            escape(a.effects[0].id()),
            escape(a.effects[1].id()),
            a.correlation,
            escape(&a.separating_recording)
        );
    }
    if let Some(top) = d.candidates.iter().find(|c| c.claimed) {
        let _ = writeln!(
            h,
            "<h3>Model change</h3>\n<p>Add to the model file:</p>\n<pre>{}</pre>",
            escape(&top.model_change)
        );
    }
    Section {
        title: format!("{triad} diagnosis"),
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

#[cfg(test)]
mod tests {
    use super::*;
    use imu_model::{EffectKind, Triad};

    fn summary(rms: f64, floor: f64) -> StepSummary {
        StepSummary {
            effects: vec![
                EffectKind::Bias,
                EffectKind::Scale,
                EffectKind::Misalignment,
            ],
            residual_rms: [rms; 3],
            noise_floor_rms: [floor; 3],
            noise_floor_with_drift_rms: [floor; 3],
            chi2: 10.0,
            dof: 10,
            p_value: 0.4,
            consistent: rms <= floor,
            consistent_with_drift: rms <= floor,
            moves: None,
        }
    }

    #[test]
    fn ladder_section_has_the_table_and_a_chart() {
        let steps = vec![
            LadderStep {
                added: None,
                accel: summary(1e-3, 1e-3),
                gyro: summary(5e-4, 1e-5),
            },
            LadderStep {
                added: Some((Triad::Gyro, EffectKind::GSensitivity)),
                accel: summary(1e-3, 1e-3),
                gyro: summary(1e-5, 1e-5),
            },
        ];
        let s = ladder_section(&steps);
        assert!(s.html.contains("<table"), "{}", s.html);
        assert!(s.html.contains("gyro g-sensitivity"), "{}", s.html);
        assert!(s.html.contains("base model"));
        assert!(s.html.contains("<svg"));
        let p = page("workbench", &[s]);
        assert!(p.contains("The ladder"));
        assert!(!p.contains("http://") || p.contains("http://www.w3.org/2000/svg"));
    }
}
