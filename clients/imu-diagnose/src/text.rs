//! The text output of `imu-diagnose`: one triad's diagnosis (verdict, residual against the
//! floor per axis, worst segments, spectral lines, candidates with their held-out check,
//! ambiguities, model change) and the ladder's steps.

use std::io::Write;

use imu_analysis::segment::SegmentKind;
use imu_analysis::workbench::{Candidate, LadderStep, TriadDiagnosis};

/// One triad's diagnosis as text.
pub(crate) fn print_diagnosis(out: &mut impl Write, d: &TriadDiagnosis) -> std::io::Result<()> {
    let unit = d.triad.unit();
    writeln!(
        out,
        "\n== {}: {} ==",
        d.triad,
        crate::effects_text(&d.effects)
    )?;
    writeln!(out, "{}", d.verdict)?;
    print_axes(out, d)?;
    print_worst_segments(out, d)?;
    for l in &d.spectral_lines {
        writeln!(
            out,
            "  spectral line: axis {} {:.4} Hz amplitude {:.3e} {unit} ({:.1}x noise)",
            ["x", "y", "z"].get(l.axis).copied().unwrap_or("?"),
            l.frequency_hz,
            l.amplitude,
            l.ratio
        )?;
    }
    print_candidates(out, d)?;
    for a in &d.ambiguities {
        writeln!(
            out,
            "  ambiguous: {} and {} (pattern correlation {:.2}); separate them with {}",
            a.effects[0], a.effects[1], a.correlation, a.separating_recording
        )?;
    }
    if let Some(top) = d.candidates.iter().find(|c| c.claimed) {
        writeln!(
            out,
            "  model change: add to the model file\n{}",
            top.model_change
                .lines()
                .map(|l| format!("    {l}"))
                .collect::<Vec<_>>()
                .join("\n")
        )?;
    }
    Ok(())
}

/// The per-axis table: residual RMS against the noise floor, with and without drift.
fn print_axes(out: &mut impl Write, d: &TriadDiagnosis) -> std::io::Result<()> {
    let unit = d.triad.unit();
    writeln!(
        out,
        "  axis {:>13} {:>13} {:>13} {:>7} {:>10}   [{unit}]",
        "residual RMS", "noise floor", "with drift", "ratio", "p"
    )?;
    for (a, v) in d.axes.iter().enumerate() {
        writeln!(
            out,
            "  {:<4} {:>13.3e} {:>13.3e} {:>13.3e} {:>7.2} {:>10.2e}",
            ["x", "y", "z"][a],
            v.residual_rms,
            v.noise_floor_rms,
            v.noise_floor_with_drift_rms,
            v.residual_rms / v.noise_floor_rms,
            v.p_value
        )?;
    }
    Ok(())
}

fn print_worst_segments(out: &mut impl Write, d: &TriadDiagnosis) -> std::io::Result<()> {
    writeln!(out, "  worst segments:")?;
    for &i in &d.worst {
        let s = &d.segments[i];
        writeln!(
            out,
            "    #{:<4} {:<7} {:>8.1}-{:<8.1} s  residual {:>10.3e} {:>10.3e} {:>10.3e}  z {:>6.1} {:>6.1} {:>6.1}",
            s.segment,
            if s.kind == SegmentKind::Static {
                "static"
            } else {
                "plateau"
            },
            s.start_s,
            s.end_s,
            s.residual[0],
            s.residual[1],
            s.residual[2],
            s.z[0],
            s.z[1],
            s.z[2]
        )?;
    }
    Ok(())
}

fn print_candidates(out: &mut impl Write, d: &TriadDiagnosis) -> std::io::Result<()> {
    writeln!(out, "  candidates:")?;
    writeln!(
        out,
        "    {:<22} {:>3} {:>10} {:>9} {:>9} {:>6}  {:<13}  explanation",
        "effect", "new", "F", "p", "dAIC", "share", "sig/claimed"
    )?;
    for c in &d.candidates {
        let state = if c.claimed {
            "CLAIMED"
        } else if c.held_out.is_some() {
            "NOT CONFIRMED"
        } else if c.significant {
            "significant"
        } else {
            "-"
        };
        writeln!(
            out,
            "    {:<22} {:>3} {:>10.3} {:>9.2e} {:>9.1} {:>6}  {:<13}  {}",
            c.effect.id(),
            c.new_params,
            c.f,
            c.p_value,
            c.delta_aic,
            c.share_of_excess_cell(),
            state,
            c.explanation
        )?;
        print_held_out(out, c)?;
    }
    Ok(())
}

/// The held-out check of a candidate that won in-sample, under its row.
fn print_held_out(out: &mut impl Write, c: &Candidate) -> std::io::Result<()> {
    let Some(h) = &c.held_out else {
        return Ok(());
    };
    writeln!(out, "      {}", h.summary(h.rms_unit(c.triad)))
}

/// The ladder's steps, with the held-out check of each added effect.
pub(crate) fn print_ladder(out: &mut impl Write, steps: &[LadderStep]) -> std::io::Result<()> {
    writeln!(
        out,
        "{:<4} {:<26} {:<47} gyro RMS / floor x y z [rad/s], p",
        "step", "added", "accel RMS / floor x y z [m/s^2], p"
    )?;
    for (i, s) in steps.iter().enumerate() {
        let added = s
            .added
            .map_or_else(|| "base model".to_string(), |(t, k)| format!("{t} {k}"));
        let cell = |x: &imu_analysis::workbench::StepSummary| {
            let axes: Vec<String> = (0..3)
                .map(|a| format!("{:.2e}/{:.2e}", x.residual_rms[a], x.noise_floor_rms[a]))
                .collect();
            format!("{} p {:.1e}", axes.join(" "), x.p_value)
        };
        writeln!(
            out,
            "{i:<4} {added:<26} {}\n{:<31} {}",
            cell(&s.accel),
            "",
            cell(&s.gyro)
        )?;
        if let (Some((t, k)), Some(h)) = (s.added, &s.held_out) {
            writeln!(out, "{:<31} {k}: {}", "", h.summary(h.rms_unit(t)))?;
        }
        if let Some(m) = &s.gyro.moves {
            writeln!(
                out,
                "{:<31} gyro gains, {} moves: {:.2e}/{:.2e} rad p {:.1e}",
                "", m.n_moves, m.residual_rms_rad, m.expected_rms_rad, m.p_value
            )?;
        }
    }
    Ok(())
}
