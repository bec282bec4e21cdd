//! One triad's diagnosis as a report section, in named parts: the verdict and residual table, the
//! worst segments, the residual charts (against time, against the correlates, the Allan
//! deviation of the noise floor, every other candidate signal folded away), the spectral lines,
//! the ranked candidates, the ambiguities and the model change.

use maud::{Markup, html};

use super::{AXIS_NAMES, Section, figures, g, strong, table, text};
use crate::render::svg::{Chart, Series, Style};
use crate::workbench::{Ambiguity, Candidate, TriadDiagnosis};

/// One triad's diagnosis: verdict, residual RMS against the noise floor per axis, the worst
/// segments, residual charts (against time and against the signal each axis correlates with
/// most), the pooled Allan deviation of the noise floor, spectral lines, the ranked candidates
/// and ambiguities, and the model change for the top claimed candidate. `signals` are the
/// workbench's explanatory signals for this triad
/// ([`Workbench::signal_values`](crate::workbench::Workbench::signal_values)), in the order of
/// `d.segments`; pass an empty slice to leave the correlate charts out.
pub fn diagnose_section(d: &TriadDiagnosis, signals: &[(String, Vec<f64>)]) -> Section {
    let mut charts = vec![residual_vs_time_chart(d)];
    charts.extend(correlate_charts(d, signals));
    charts.push(allan_chart(d));
    let others = other_signal_charts(d, signals, &charts);
    let body = html! {
        (summary(d))
        (worst_segments(d))
        (figures(&charts))
        @if !others.is_empty() {
            details {
                summary {
                    (format!("Residual against every other candidate signal ({})", others.len()))
                }
                (figures(&others))
            }
        }
        (spectral_lines(d))
        (candidates(d))
        (ambiguities(&d.ambiguities))
        @if let Some(top) = d.candidates.iter().find(|c| c.claimed) {
            h3 { "Model change" }
            p { "Add to the model file:" }
            pre { (top.model_change) }
        }
    };
    Section::new(format!("{} diagnosis", d.triad), body)
}

/// The verdict, the model with its chi-square test, and the residual RMS against the noise
/// floor per axis.
fn summary(d: &TriadDiagnosis) -> Markup {
    let unit = d.triad.unit();
    let effects: Vec<&str> = d.effects.iter().map(|k| k.id()).collect();
    let rows: Vec<Vec<Markup>> = d
        .axes
        .iter()
        .zip(AXIS_NAMES)
        .map(|(v, name)| {
            vec![
                text(name),
                text(g(v.residual_rms)),
                text(g(v.noise_floor_rms)),
                text(g(v.noise_floor_with_drift_rms)),
                text(g(v.residual_rms / v.noise_floor_rms)),
                text(format!("{:.1} / {:.0}", v.chi2, v.dof)),
                text(g(v.p_value)),
            ]
        })
        .collect();
    html! {
        p { strong { (d.verdict) } }
        p {
            "Model: " (effects.join(" + "))
            (format!(
                ". chi2 {:.1} on {} degrees of freedom, p = {} (with drift p = {}).",
                d.chi2,
                d.dof,
                g(d.p_value),
                g(d.p_value_with_drift)
            ))
        }
        (table(
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
        ))
    }
}

/// The segments with the largest residuals.
fn worst_segments(d: &TriadDiagnosis) -> Markup {
    let unit = d.triad.unit();
    let rows: Vec<Vec<Markup>> = d
        .worst
        .iter()
        .filter_map(|&i| d.segments.get(i))
        .map(|s| {
            let residual: Vec<String> = s.residual.iter().map(|v| g(*v)).collect();
            let z: Vec<String> = s.z.iter().map(|v| format!("{v:.1}")).collect();
            vec![
                text(s.segment),
                text(format!("{:?}", s.kind).to_lowercase()),
                text(format!("{:.1} \u{2013} {:.1}", s.start_s, s.end_s)),
                text(residual.join(", ")),
                text(z.join(", ")),
            ]
        })
        .collect();
    html! {
        h3 { "Worst segments" }
        (table(
            &[
                "segment",
                "kind",
                "time [s]",
                &format!("residual x, y, z [{unit}]"),
                "z x, y, z",
            ],
            &rows,
        ))
    }
}

/// The segment residual per axis against the segment's mid time.
fn residual_vs_time_chart(d: &TriadDiagnosis) -> Chart {
    Chart {
        title: format!("{}: segment residual vs time", d.triad),
        x_label: "time [s]".into(),
        y_label: format!("residual [{}]", d.triad.unit()),
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
    }
}

/// The segment residual of the given axes (with their correlation `r`) against one signal's
/// `values` (one per segment).
fn residual_vs_signal_chart(
    d: &TriadDiagnosis,
    name: &str,
    values: &[f64],
    axes: &[(usize, f64)],
) -> Chart {
    Chart {
        title: format!("{}: residual vs {name}", d.triad),
        x_label: name.into(),
        y_label: format!("residual [{}]", d.triad.unit()),
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
    }
}

/// Residual against the strongest correlate, one chart per signal (axes sharing it together).
fn correlate_charts(d: &TriadDiagnosis, signals: &[(String, Vec<f64>)]) -> Vec<Chart> {
    let mut by_signal: Vec<(&str, Vec<(usize, f64)>)> = Vec::new();
    for (a, st) in d.structure.iter().enumerate() {
        if let Some(c) = st.correlates.first() {
            match by_signal.iter_mut().find(|(n, _)| *n == c.signal) {
                Some((_, v)) => v.push((a, c.r)),
                None => by_signal.push((&c.signal, vec![(a, c.r)])),
            }
        }
    }
    by_signal
        .into_iter()
        .filter_map(|(name, axes)| {
            let (_, values) = signals.iter().find(|(n, _)| n == name)?;
            (values.len() == d.segments.len())
                .then(|| residual_vs_signal_chart(d, name, values, &axes))
        })
        .collect()
}

/// The pooled Allan deviation of the noise floor per axis.
fn allan_chart(d: &TriadDiagnosis) -> Chart {
    Chart {
        title: format!(
            "{}: Allan deviation of the noise floor ({})",
            d.triad, d.noise_floor.source
        ),
        x_label: "tau [s]".into(),
        y_label: format!("Allan deviation [{}]", d.triad.unit()),
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
    }
}

/// Every other candidate explanatory signal (not among the `shown` charts), all three axes each:
/// where the strongest correlate does not tell the story, the pattern may show against another.
fn other_signal_charts(
    d: &TriadDiagnosis,
    signals: &[(String, Vec<f64>)],
    shown: &[Chart],
) -> Vec<Chart> {
    signals
        .iter()
        .filter(|(_, values)| values.len() == d.segments.len())
        .map(|(name, values)| {
            let axes: Vec<(usize, f64)> = (0..3)
                .map(|a| {
                    let r = d.structure[a]
                        .correlates
                        .iter()
                        .find(|c| c.signal == *name)
                        .map_or(0.0, |c| c.r);
                    (a, r)
                })
                .collect();
            residual_vs_signal_chart(d, name, values, &axes)
        })
        .filter(|c| shown.iter().all(|s| s.title != c.title))
        .collect()
}

/// Spectral lines in the noise floor, if any.
fn spectral_lines(d: &TriadDiagnosis) -> Markup {
    let rows: Vec<Vec<Markup>> = d
        .spectral_lines
        .iter()
        .map(|l| {
            vec![
                text(AXIS_NAMES.get(l.axis).copied().unwrap_or("?")),
                text(g(l.frequency_hz)),
                text(g(l.amplitude)),
                text(format!("{:.1}", l.ratio)),
            ]
        })
        .collect();
    html! {
        @if !rows.is_empty() {
            h3 { "Spectral lines" }
            (table(
                &[
                    "axis",
                    "frequency [Hz]",
                    &format!("amplitude [{}]", d.triad.unit()),
                    "x noise",
                ],
                &rows,
            ))
        }
    }
}

/// The ranked candidate effects.
fn candidates(d: &TriadDiagnosis) -> Markup {
    let rows: Vec<Vec<Markup>> = d.candidates.iter().map(candidate_row).collect();
    html! {
        h3 { "Candidates" }
        (table(
            &[
                "effect",
                "new params",
                "F",
                "p",
                "\u{394}AIC",
                "share of excess",
                "significant / claimed",
                "explanation",
            ],
            &rows,
        ))
    }
}

fn candidate_row(c: &Candidate) -> Vec<Markup> {
    vec![
        text(c.effect.id()),
        text(c.new_params),
        text(g(c.f)),
        text(g(c.p_value)),
        text(format!("{:.1}", c.delta_aic)),
        text(c.share_of_excess_cell()),
        if c.claimed {
            strong("claimed")
        } else if c.significant {
            text("significant")
        } else {
            text("no")
        },
        text(&c.explanation),
    ]
}

/// Pairs of effects that explain the residual alike, and the recording that separates them.
fn ambiguities(ambiguities: &[Ambiguity]) -> Markup {
    html! {
        @for a in ambiguities {
            p {
                "Ambiguous: " (a.effects[0].id()) " and " (a.effects[1].id())
                (format!(
                    " explain the residual alike (pattern correlation {:.2}); separate them with ",
                    a.correlation
                ))
                (a.separating_recording) "."
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use imu_model::{EffectKind, Triad};

    #[test]
    fn the_separating_recording_is_escaped() {
        let a = Ambiguity {
            triad: Triad::Gyro,
            effects: [EffectKind::GSensitivity, EffectKind::Scale],
            correlation: 0.95,
            separating_recording: "<script>alert(1)</script> & a turn".into(),
        };
        let h = ambiguities(&[a]).into_string();
        assert_eq!(
            h,
            "<p>Ambiguous: g-sensitivity and scale explain the residual alike (pattern \
             correlation 0.95); separate them with &lt;script&gt;alert(1)&lt;/script&gt; &amp; \
             a turn.</p>"
        );
    }
}
