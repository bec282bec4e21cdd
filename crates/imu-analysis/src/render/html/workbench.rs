//! The workbench sections around the per-triad diagnoses: the verdict per triad in plain words
//! and the ladder (effects added one at a time, residual RMS against the noise floor per step).

use maud::{Markup, html};

use super::{AXIS_NAMES, Section, figures, g, g3, p, table, text, yes_no};
use crate::render::svg::{Chart, Figure, Look, Series, Style, Ticks, axis_colour};
use crate::workbench::{LadderStep, StepSummary, TriadDiagnosis, VerdictState};

/// The verdict per triad in plain words, for the top of a workbench report.
pub fn verdict_section(diagnoses: &[&TriadDiagnosis]) -> Section {
    let body = html! {
        @for d in diagnoses {
            p {
                strong { (d.triad) ": " (verdict_heading(d)) "." }
                " " (d.verdict)
            }
            @if let Some(top) = d.candidates.iter().find(|c| c.claimed) {
                p {
                    "Add " code { (top.effect.id()) } " to the " (d.triad) " model "
                    (format!("(p = {}, \u{394}AIC = {:.1}", p(top.p_value), top.delta_aic))
                    @if let Some(h) = &top.held_out {
                        (format!(
                            "; held-out weighted RMS {} \u{2192} {} {}, {}",
                            g3(h.held_out_rms_before),
                            g3(h.held_out_rms_after),
                            h.rms_unit(d.triad),
                            h.verdict_text()
                        ))
                    }
                    ")."
                }
            }
        }
    };
    Section::new("Verdict", body)
}

/// The verdict's state in words, with the test that decided it: the heading says what the
/// verdict below it says (both follow [`VerdictState`]).
pub fn verdict_heading(d: &TriadDiagnosis) -> String {
    let not = format!("NOT consistent with its noise floor (p = {})", p(d.p_value));
    match d.state {
        VerdictState::Consistent => {
            format!("consistent with its noise floor (p = {})", p(d.p_value))
        }
        VerdictState::PeriodicComponent => format!(
            "consistent with its noise floor in the chi-square test (p = {}), but a periodic \
             component remains",
            p(d.p_value)
        ),
        VerdictState::BiasWander => format!(
            "{not}; a slow bias wander between segments explains the excess (p = {} with it)",
            p(d.p_value_with_drift)
        ),
        VerdictState::MissingEffect => format!("{not}: an effect is missing from the model"),
        VerdictState::NotConfirmed => {
            format!("{not}: the best candidate is not confirmed on held-out data (not claimed)")
        }
        VerdictState::Ambiguous => {
            format!("{not}: two effects explain the excess and this recording cannot tell which")
        }
        VerdictState::Unexplained => format!("{not}: no library effect explains the excess"),
        VerdictState::GainsInconsistent => {
            "NOT consistent: the gyro gains do not match the rotations over the moves".into()
        }
    }
}

/// The ladder: each step (effect added, residual RMS against the noise floor per axis, p) as a
/// table, and a chart per triad of the residual RMS per axis at each step with the noise floor
/// drawn as a line.
pub fn ladder_section(steps: &[LadderStep]) -> Section {
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
    let moves = steps.iter().any(|s| s.gyro.moves.is_some());
    if moves {
        // Reference-free: the gyro gains against the moves between poses.
        header.push("gyro gains: direction error / expected after the moves (rad)");
    }
    let held_out = steps.iter().any(|s| s.held_out.is_some());
    if held_out {
        header.push("added effect: held-out weighted RMS before \u{2192} after");
    }
    let rows: Vec<Vec<Markup>> = steps
        .iter()
        .enumerate()
        .map(|(i, s)| ladder_row(i, s, moves, held_out))
        .collect();
    let body = html! {
        p {
            "From the base model, the workbench adds the best claimed effect of a triad that is \
             not yet consistent with its noise floor, one at a time, until both are consistent \
             or nothing more is claimed. Cells: residual RMS / noise floor RMS per axis \
             (accel m/s^2, gyro rad/s)."
        }
        (table(&header, &rows))
        (figures(&ladder_figures(steps)))
    };
    Section::new("The ladder", body)
}

/// Step `i` of the ladder as a table row; `moves` and `held_out` say whether the table has
/// those columns.
fn ladder_row(i: usize, s: &LadderStep, moves: bool, held_out: bool) -> Vec<Markup> {
    let added = s
        .added
        .map_or("base model".into(), |(t, k)| format!("{t} {}", k.id()));
    let mut r = vec![text(i), text(added)];
    r.extend(step_cells(&s.accel));
    r.extend(step_cells(&s.gyro));
    if moves {
        r.push(text(s.gyro.moves.as_ref().map_or(String::new(), |m| {
            format!(
                "{} / {} (p {})",
                g(m.residual_rms_rad),
                g(m.expected_rms_rad),
                p(m.p_value)
            )
        })));
    }
    if held_out {
        let cell = match (&s.held_out, s.added) {
            (Some(h), Some((t, _))) => format!(
                "{} \u{2192} {} {} ({}, lower in {} of {} folds; in-sample {} \u{2192} {})",
                g3(h.held_out_rms_before),
                g3(h.held_out_rms_after),
                h.rms_unit(t),
                h.scheme_text(),
                h.folds_improved,
                h.folds,
                g3(h.in_sample_rms_before),
                g3(h.in_sample_rms_after)
            ),
            _ => String::new(),
        };
        r.push(text(cell));
    }
    r
}

fn step_cells(s: &StepSummary) -> Vec<Markup> {
    let mut v: Vec<Markup> = (0..3)
        .map(|a| {
            text(format!(
                "{} / {}",
                g(s.residual_rms[a]),
                g(s.noise_floor_rms[a])
            ))
        })
        .collect();
    v.push(text(p(s.p_value)));
    v.push(text(yes_no(s.consistent_with_drift)));
    v
}

/// The ladder's charts: residual RMS against the noise floor per step, for each triad whose
/// residual changed along the ladder (a triad nothing was added to would draw flat lines: the
/// table says it).
pub fn ladder_figures(steps: &[LadderStep]) -> Vec<Figure> {
    let changes = |pick: fn(&LadderStep) -> &StepSummary| {
        steps
            .windows(2)
            .any(|w| (0..3).any(|a| pick(&w[0]).residual_rms[a] != pick(&w[1]).residual_rms[a]))
    };
    let mut out = Vec::new();
    if changes(|s| &s.accel) {
        out.push(ladder_chart(steps, "accel", "m/s^2", |s| &s.accel));
    }
    if changes(|s| &s.gyro) {
        out.push(ladder_chart(steps, "gyro", "rad/s", |s| &s.gyro));
    }
    out
}

/// The residual RMS per axis at each ladder step (points) against its noise floor (a line of
/// the same colour): integer steps on the x axis, one colour per axis.
fn ladder_chart(
    steps: &[LadderStep],
    triad: &str,
    unit: &str,
    pick: fn(&LadderStep) -> &StepSummary,
) -> Figure {
    let per_axis =
        |a: usize, label: &str, style: Style, value: fn(&StepSummary, usize) -> f64| Series {
            name: format!("{} {label}", AXIS_NAMES[a]),
            points: steps
                .iter()
                .enumerate()
                .map(|(i, s)| (i as f64, value(pick(s), a)))
                .collect(),
            style,
        };
    let mut series = Vec::new();
    let mut looks = Vec::new();
    for a in 0..3 {
        series.push(per_axis(a, "residual", Style::Points, |s, a| {
            s.residual_rms[a]
        }));
        series.push(per_axis(a, "noise floor", Style::Line, |s, a| {
            s.noise_floor_rms[a]
        }));
        looks.extend([axis_colour(a), axis_colour(a)]);
    }
    Figure {
        chart: Chart {
            title: format!("{triad}: residual RMS per ladder step"),
            x_label: "ladder step (0 = base model)".into(),
            y_label: format!("RMS [{unit}]"),
            log_y: true,
            series,
            ..Chart::default()
        },
        look: Look {
            x_ticks: Ticks::Integer,
            series: looks,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::super::page;
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
                held_out: None,
                accel: summary(1e-3, 1e-3),
                gyro: summary(5e-4, 1e-5),
            },
            LadderStep {
                added: Some((Triad::Gyro, EffectKind::GSensitivity)),
                held_out: None,
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
        // Without a held-out check there is no such column.
        assert!(!p.contains("held-out"), "{p}");
    }

    #[test]
    fn the_ladder_shows_the_held_out_check_of_each_added_effect() {
        use crate::workbench::{FoldScheme, HeldOut, HeldOutUnit};
        let h = HeldOut {
            scheme: FoldScheme::KFold,
            folds: 5,
            unit: HeldOutUnit::Segments,
            n_observations: 24,
            in_sample_rms_before: [1.0e-3, 8.0e-4, 2.4e-3],
            in_sample_rms_after: [2.8e-4, 3.1e-4, 2.5e-4],
            held_out_rms_before: [1.1e-3, 8.3e-4, 2.2e-3],
            held_out_rms_after: [3.1e-4, 3.6e-4, 2.9e-4],
            folds_improved: 5,
            folds_failed: 0,
            confirmed: true,
        };
        let steps = vec![
            LadderStep {
                added: None,
                held_out: None,
                accel: summary(1e-3, 1e-3),
                gyro: summary(5e-4, 1e-5),
            },
            LadderStep {
                added: Some((Triad::Gyro, EffectKind::GSensitivity)),
                held_out: Some(h),
                accel: summary(1e-3, 1e-3),
                gyro: summary(1e-5, 1e-5),
            },
        ];
        let s = ladder_section(&steps);
        assert!(s.html.contains("held-out weighted RMS"), "{}", s.html);
        assert!(
            s.html.contains(
                "1.100e-3/8.300e-4/2.200e-3 \u{2192} 3.100e-4/3.600e-4/2.900e-4 rad/s (5-fold over \
                 segments, lower in 5 of 5 folds; in-sample 1.000e-3/8.000e-4/2.400e-3 \u{2192} \
                 2.800e-4/3.100e-4/2.500e-4)"
            ),
            "{}",
            s.html
        );
    }
}
