//! One triad's diagnosis as a report section, in named parts: the verdict and residual table, the
//! worst segments, the residual charts (against time, against the correlates, the Allan
//! deviation of the noise floor, every other candidate signal folded away), the spectral lines,
//! the ranked candidates, the ambiguities and the model change.

use maud::{Markup, html};

use super::{AXIS_NAMES, Section, figures, g, g3, p, strong, table, text};
use crate::render::svg::{Chart, Figure, Look, Series, SeriesLook, Style, Ticks, axis_colour};
use crate::workbench::{Ambiguity, Candidate, HeldOut, TriadDiagnosis};

/// One triad's diagnosis: verdict, residual RMS against the noise floor per axis, the worst
/// segments, residual charts (against time and against the signal each axis correlates with
/// most), the pooled Allan deviation of the noise floor, spectral lines, the ranked candidates
/// and ambiguities, and the model change for the top claimed candidate. `signals` are the
/// workbench's explanatory signals for this triad
/// ([`Workbench::signal_values`](crate::workbench::Workbench::signal_values)), in the order of
/// `d.segments`; pass an empty slice to leave the correlate charts out.
pub fn diagnose_section(d: &TriadDiagnosis, signals: &[(String, Vec<f64>)]) -> Section {
    diagnose_section_with_base(d, None, signals)
}

/// [`diagnose_section`] with the base model's diagnosis `base` (the ladder's first step), whose
/// residuals are pictured beside the final model's: the base model's failure is the story.
pub fn diagnose_section_with_base(
    d: &TriadDiagnosis,
    base: Option<&TriadDiagnosis>,
    signals: &[(String, Vec<f64>)],
) -> Section {
    let (main, others) = figures_of(d, base, signals);
    let body = html! {
        (summary(d))
        (worst_segments(d))
        (figures(&main))
        p { "Noise floor: " (d.noise_floor.source) "." }
        @if !others.is_empty() {
            details {
                summary {
                    (format!("Residual against every other candidate signal ({})", others.len()))
                }
                (figures(&others))
            }
        }
        (constant_signals(d, signals))
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

/// Every chart of a diagnosis section: the main ones (residuals of the base model if given and
/// of the model, residual against the strongest correlates, the Allan deviation of the floor),
/// then those folded away (residual against every other candidate signal that varies).
pub fn diagnose_figures(
    d: &TriadDiagnosis,
    base: Option<&TriadDiagnosis>,
    signals: &[(String, Vec<f64>)],
) -> Vec<Figure> {
    let (mut main, others) = figures_of(d, base, signals);
    main.extend(others);
    main
}

/// The main and the folded-away charts of [`diagnose_figures`].
fn figures_of(
    d: &TriadDiagnosis,
    base: Option<&TriadDiagnosis>,
    signals: &[(String, Vec<f64>)],
) -> (Vec<Figure>, Vec<Figure>) {
    let mut main = Vec::new();
    if let Some(b) = base {
        main.push(residual_vs_time_chart(b, "base model"));
    }
    main.push(residual_vs_time_chart(
        d,
        if base.is_some() {
            "final model"
        } else {
            "model"
        },
    ));
    main.extend(correlate_charts(d, signals));
    main.push(Figure::from(allan_chart(d)));
    let others = other_signal_charts(d, signals, &main);
    (main, others)
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
                text(p(v.p_value)),
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
                p(d.p_value),
                p(d.p_value_with_drift)
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

/// The segment residual per axis in units of its noise floor (z) against the segment's mid
/// time, with the band the floor allows (|z| <= 2, 95 %): a point outside it exceeds the floor.
/// `which` names the model (`base model`, `final model`).
fn residual_vs_time_chart(d: &TriadDiagnosis, which: &str) -> Figure {
    let (lo, hi) = d
        .segments
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), s| {
            (l.min(s.start_s), h.max(s.end_s))
        });
    let (lo, hi) = if lo.is_finite() { (lo, hi) } else { (0.0, 1.0) };
    let mut series = vec![Series {
        name: "noise floor, 95 %".into(),
        points: vec![(lo, -2.0), (hi, -2.0)],
        style: Style::Band {
            upper: vec![(lo, 2.0), (hi, 2.0)],
        },
    }];
    let mut looks = vec![SeriesLook {
        colour: Some(7),
        dashed: false,
    }];
    for (a, name) in AXIS_NAMES.iter().enumerate() {
        series.push(Series {
            name: (*name).into(),
            points: d
                .segments
                .iter()
                .map(|s| (0.5 * (s.start_s + s.end_s), s.z[a]))
                .collect(),
            style: Style::Points,
        });
        looks.push(axis_colour(a));
    }
    Figure {
        chart: Chart {
            title: format!("{}, {which}: segment residual vs time", d.triad),
            x_label: "time [s]".into(),
            y_label: "residual / noise floor".into(),
            series,
            ..Chart::default()
        },
        look: Look {
            series: looks,
            ..Look::default()
        },
    }
}

/// The segment residual of the given axes (with their correlation `r`) against one signal's
/// `values` (one per segment).
fn residual_vs_signal_chart(
    d: &TriadDiagnosis,
    name: &str,
    values: &[f64],
    axes: &[(usize, f64)],
) -> Figure {
    // A discrete signal (a sign, a count) gets whole-number ticks, never 0.5.
    let integer = values.iter().all(|v| v.fract() == 0.0);
    let chart = Chart {
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
    };
    Figure {
        chart,
        look: Look {
            x_ticks: if integer { Ticks::Integer } else { Ticks::Auto },
            series: axes.iter().map(|&(a, _)| axis_colour(a)).collect(),
        },
    }
}

/// Residual against the strongest correlate, one chart per signal (axes sharing it together).
fn correlate_charts(d: &TriadDiagnosis, signals: &[(String, Vec<f64>)]) -> Vec<Figure> {
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
            (values.len() == d.segments.len() && varies(values))
                .then(|| residual_vs_signal_chart(d, name, values, &axes))
        })
        .collect()
}

/// The candidate signals that did not vary in this recording, named instead of charted: a
/// constant cannot explain a residual that varies.
fn constant_signals(d: &TriadDiagnosis, signals: &[(String, Vec<f64>)]) -> Markup {
    let constant: Vec<String> = signals
        .iter()
        .filter(|(_, v)| v.len() == d.segments.len() && !varies(v))
        .map(|(name, v)| {
            let value = v
                .iter()
                .find(|x| x.is_finite())
                .copied()
                .unwrap_or(f64::NAN);
            format!("residual vs {name} ({} throughout)", g(value))
        })
        .collect();
    html! {
        @if !constant.is_empty() {
            p {
                "Not charted, as the signal is constant in this recording (it cannot explain \
                 the residual here): " (constant.join("; ")) "."
            }
        }
    }
}

/// A signal worth a chart: its finite values are not all the same (a constant signal, e.g.
/// "input magnitude" at 0 in every still segment, would draw a degenerate chart).
fn varies(values: &[f64]) -> bool {
    let mut finite = values.iter().filter(|v| v.is_finite());
    let Some(first) = finite.next() else {
        return false;
    };
    finite.any(|v| (v - first).abs() > 1e-12 * (1.0 + first.abs()))
}

/// The pooled Allan deviation of the noise floor per axis.
fn allan_chart(d: &TriadDiagnosis) -> Chart {
    Chart {
        // The floor's source is said under the chart: in the title it ran past the view box.
        title: format!("{}: Allan deviation of the noise floor", d.triad),
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
    shown: &[Figure],
) -> Vec<Figure> {
    signals
        .iter()
        .filter(|(_, values)| values.len() == d.segments.len() && varies(values))
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
        .filter(|c| shown.iter().all(|s| s.chart.title != c.chart.title))
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

/// The ranked candidate effects, and the held-out check of the one that won in-sample.
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
        (held_out_table(d))
    }
}

fn candidate_row(c: &Candidate) -> Vec<Markup> {
    vec![
        text(c.effect.id()),
        text(c.new_params),
        text(g(c.f)),
        text(p(c.p_value)),
        text(format!("{:.1}", c.delta_aic)),
        text(c.share_of_excess_cell()),
        if c.claimed {
            strong("claimed")
        } else if c.held_out.is_some() {
            text("not confirmed on held-out data")
        } else if c.significant {
            text("significant")
        } else {
            text("no")
        },
        text(c.explanation.to_string()),
    ]
}

/// The candidates cross-validated (those that won in-sample): weighted RMS of the residuals
/// before and after adding each, in-sample and on held-out observations, and the verdict.
fn held_out_table(d: &TriadDiagnosis) -> Markup {
    let checked: Vec<(&Candidate, &HeldOut)> = d
        .candidates
        .iter()
        .filter_map(|c| c.held_out.as_ref().map(|h| (c, h)))
        .collect();
    if checked.is_empty() {
        return html! {};
    }
    let rows: Vec<Vec<Markup>> = checked
        .iter()
        .map(|(c, h)| {
            vec![
                text(c.effect.id()),
                text(h.scheme_text()),
                text(format!(
                    "{} \u{2192} {} {}",
                    g3(h.in_sample_rms_before),
                    g3(h.in_sample_rms_after),
                    h.rms_unit(c.triad)
                )),
                text(format!(
                    "{} \u{2192} {} {}",
                    g3(h.held_out_rms_before),
                    g3(h.held_out_rms_after),
                    h.rms_unit(c.triad)
                )),
                text(format!("{} of {}", h.folds_improved, h.folds)),
                if h.confirmed {
                    strong(h.verdict_text())
                } else {
                    text(h.verdict_text())
                },
            ]
        })
        .collect();
    html! {
        h3 { "Held-out check" }
        p {
            "A candidate is claimed only if it also lowers the error on observations its fit did \
             not see: the model is refitted without and with it on all but one fold and held \
             against that fold, for every fold. Claimed when the held-out weighted RMS falls in \
             a majority of the folds and over all of them. Weighted RMS (weights 1/floor\u{b2}) \
             per axis x/y/z, before \u{2192} after adding the candidate."
        }
        (table(
            &[
                "effect",
                "held out",
                "in-sample RMS",
                "held-out RMS",
                "folds lower",
                "verdict",
            ],
            &rows,
        ))
    }
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
    fn an_ambiguity_names_the_recording_that_separates_the_pair() {
        let a = Ambiguity {
            triad: Triad::Gyro,
            effects: [EffectKind::GSensitivity, EffectKind::Scale],
            correlation: 0.95,
            separating_recording: crate::workbench::Separation::of(
                EffectKind::GSensitivity,
                EffectKind::Scale,
            ),
        };
        let h = ambiguities(&[a]).into_string();
        assert_eq!(
            h,
            "<p>Ambiguous: g-sensitivity and scale explain the residual alike (pattern \
             correlation 0.95); separate them with more static orientations (each axis up and \
             down, and at 45 degrees): the g-dependent bias follows the specific force, the other \
             effect does not.</p>"
        );
    }
}
