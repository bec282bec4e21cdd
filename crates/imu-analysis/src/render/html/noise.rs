//! The imu-noise report: what was read, the fitted IEEE terms of every axis (SI and datasheet
//! units) and the Allan-family figures of [`crate::render::allan::noise_figures`], the same
//! figures `imu-noise --plot` writes. Every number is written by [`sci`].

use maud::{Markup, PreEscaped, html};

use super::{Section, table, text};
use crate::render::allan::{DisplayTerms, NoiseAxis, TERM_NAMES, noise_figures, sci, term_units};
use crate::render::figure::render_figure;

/// What the report says about its input, as label and value pairs (files, rate, duration...).
pub type Facts = [(String, String)];

/// The sections of the imu-noise report: the input, the terms, one per figure.
pub fn noise_sections(facts: &Facts, axes: &[NoiseAxis]) -> Vec<Section> {
    let figures: Vec<String> = noise_figures(axes)
        .iter()
        .map(|(_, fig)| render_figure(fig))
        .collect();
    // Raw markup from our own SVG writer (`render::figure`), which escapes every text it writes.
    let figures = html! { @for svg in &figures { figure { (PreEscaped(svg.as_str())) } } };
    vec![
        Section::new("Input", facts_table(facts)),
        Section::new("Fitted IEEE noise terms", terms_tables(axes)),
        Section::new("Figures", figures),
    ]
}

fn facts_table(facts: &Facts) -> Markup {
    html! {
        table.imu { tbody { @for (k, v) in facts { tr { th { (k) } td { (v) } } } } }
    }
}

/// A datasheet-unit value, or "not supported" for a term the fit left out.
fn shown(v: f64, unit: &str) -> Markup {
    if v > 0.0 {
        text(format!("{} {unit}", sci(v)))
    } else {
        text("not supported")
    }
}

/// Two tables: every term with its standard error in SI units, and N, B, K in datasheet units.
fn terms_tables(axes: &[NoiseAxis]) -> Markup {
    let si_rows: Vec<Vec<Markup>> = axes
        .iter()
        .map(|a| {
            let units = term_units(a.triad.unit());
            let mut row = vec![text(a.triad.name()), text(a.axis)];
            for (t, u) in a.fit.as_array().iter().zip(&units) {
                row.push(text(if t.value > 0.0 {
                    format!("{} \u{b1} {} {u}", sci(t.value), sci(t.sigma))
                } else {
                    "not supported".to_string()
                }));
            }
            row.push(text(format!("{:.2}", a.fit.chi2_per_dof)));
            row
        })
        .collect();
    let mut head = vec!["sensor", "axis"];
    head.extend(TERM_NAMES);
    head.push("chi\u{b2}/dof");
    let display_rows: Vec<Vec<Markup>> = axes
        .iter()
        .map(|a| {
            let d = DisplayTerms::of(a.triad, a.fit);
            vec![
                text(a.triad.name()),
                text(a.axis),
                shown(d.n, d.n_unit),
                shown(d.b, d.b_unit),
                shown(d.k, d.k_unit),
            ]
        })
        .collect();
    html! {
        p {
            "Weighted non-negative least squares on the Allan variance, \u{b1} one standard error; "
            "a term the curve does not support at 3 sigma is left out (\u{201c}not supported\u{201d}). "
            "Q quantization, N white noise (angle/velocity random walk), B bias instability, "
            "K rate random walk, R rate ramp."
        }
        (table(&head, &si_rows))
        p { "The same N, B and K in datasheet units:" }
        (table(&["sensor", "axis", "N", "B", "K"], &display_rows))
    }
}
