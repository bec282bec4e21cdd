//! The workbench sections around the per-triad diagnoses: the verdict per triad in plain words
//! and the ladder (effects added one at a time, residual RMS against the noise floor per step).

use maud::{Markup, html};

use super::{AXIS_NAMES, Section, figures, g, table, text, yes_no};
use crate::render::svg::{Chart, Series, Style};
use crate::workbench::{LadderStep, StepSummary, TriadDiagnosis};

/// The verdict per triad in plain words, for the top of a workbench report.
pub fn verdict_section(diagnoses: &[&TriadDiagnosis]) -> Section {
    let body = html! {
        @for d in diagnoses {
            p {
                strong { (d.triad) ": " (state(d)) "." }
                " " (d.verdict)
            }
            @if let Some(top) = d.candidates.iter().find(|c| c.claimed) {
                p {
                    "Add " code { (top.effect.id()) } " to the " (d.triad) " model "
                    (format!("(p = {}, \u{394}AIC = {:.1}).", g(top.p_value), top.delta_aic))
                }
            }
        }
    };
    Section::new("Verdict", body)
}

/// Whether a triad is consistent with its noise floor, in words.
fn state(d: &TriadDiagnosis) -> &'static str {
    if d.consistent {
        "consistent with its noise floor"
    } else if d.consistent_with_drift {
        "consistent with its noise floor plus a slow bias drift"
    } else {
        "NOT consistent with its noise floor: something is missing from the model"
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
    if steps.iter().any(|s| s.gyro.moves.is_some()) {
        // Reference-free: the gyro gains against the moves between poses.
        header.push("gyro gains: direction error / expected after the moves (rad)");
    }
    let rows: Vec<Vec<Markup>> = steps.iter().enumerate().map(ladder_row).collect();
    let body = html! {
        p {
            "From the base model, the workbench adds the best claimed effect of a triad that is \
             not yet consistent with its noise floor, one at a time, until both are consistent \
             or nothing more is claimed. Cells: residual RMS / noise floor RMS per axis \
             (accel m/s^2, gyro rad/s)."
        }
        (table(&header, &rows))
        (figures(&[
            ladder_chart(steps, "accel", "m/s^2", |s| &s.accel),
            ladder_chart(steps, "gyro", "rad/s", |s| &s.gyro),
        ]))
    };
    Section::new("The ladder", body)
}

/// Step `i` of the ladder as a table row.
fn ladder_row((i, s): (usize, &LadderStep)) -> Vec<Markup> {
    let added = s
        .added
        .map_or("base model".into(), |(t, k)| format!("{t} {}", k.id()));
    let mut r = vec![text(i), text(added)];
    r.extend(step_cells(&s.accel));
    r.extend(step_cells(&s.gyro));
    if let Some(m) = &s.gyro.moves {
        r.push(text(format!(
            "{} / {} (p {})",
            g(m.residual_rms_rad),
            g(m.expected_rms_rad),
            g(m.p_value)
        )));
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
    v.push(text(g(s.p_value)));
    v.push(text(yes_no(s.consistent_with_drift)));
    v
}

fn ladder_chart(
    steps: &[LadderStep],
    triad: &str,
    unit: &str,
    pick: fn(&LadderStep) -> &StepSummary,
) -> Chart {
    let per_axis = |label: &str, style: Style, value: fn(&StepSummary, usize) -> f64| {
        AXIS_NAMES
            .iter()
            .enumerate()
            .map(move |(a, name)| Series {
                name: format!("{label} {name}"),
                points: steps
                    .iter()
                    .enumerate()
                    .map(|(i, s)| (i as f64, value(pick(s), a)))
                    .collect(),
                style: style.clone(),
            })
            .collect::<Vec<_>>()
    };
    let mut series = per_axis("residual", Style::Points, |s, a| s.residual_rms[a]);
    series.extend(per_axis("noise floor", Style::Line, |s, a| {
        s.noise_floor_rms[a]
    }));
    Chart {
        title: format!("{triad}: residual RMS per ladder step vs the noise floor"),
        x_label: "ladder step".into(),
        y_label: format!("RMS [{unit}]"),
        log_y: true,
        series,
        ..Chart::default()
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
