//! The text output: the fitted IEEE terms, the slope read-offs and one block per deviation kind
//! with its confidence bounds.

use std::io::Write;

use imu_analysis::render::number::number;
use imu_model::Triad;

use crate::AxisReport;

fn opt(v: Option<f64>) -> String {
    v.map_or_else(|| "-".into(), |v| format!("{v:.3e}"))
}

fn print_terms(reports: &[AxisReport], w: &mut impl Write) -> std::io::Result<()> {
    writeln!(
        w,
        "Fitted IEEE terms (weighted NNLS on the Allan variance; +- 1 sigma); U = m/s^2 (accel), rad/s (gyro)"
    )?;
    writeln!(
        w,
        "{:<7}{:<3}{:>24}{:>24}{:>24}{:>12}{:>12}  display units",
        "sensor", "ax", "N [U/sqrt(Hz)]", "B [U]", "K [U*sqrt(Hz)]", "Q [U*s]", "R [U/s]"
    )?;
    for r in reports {
        let t = &r.fit;
        let pm = |x: &imu_stats::noise_terms::Term| format!("{:.3e}+-{:.1e}", x.value, x.sigma);
        writeln!(
            w,
            "{:<7}{:<3}{:>24}{:>24}{:>24}{:>12.2e}{:>12.2e}  N {} {}, B {} {}, K {} {}",
            r.sensor.name(),
            r.axis,
            pm(&t.n_u_per_sqrt_hz),
            pm(&t.b_u),
            pm(&t.k_u_sqrt_hz),
            t.q_u_s.value,
            t.r_u_per_s.value,
            number(r.display.n),
            r.display.n_unit,
            number(r.display.b),
            r.display.b_unit,
            number(r.display.k),
            r.display.k_unit,
        )?;
    }
    // With --kind theo1/theoh the fit also takes Theo1 points beyond the OADEV's last tau.
    let theo: Vec<String> = reports
        .iter()
        .filter(|r| r.fit.n_theo1_points > 0)
        .map(|r| format!("{} {} {}", r.sensor.name(), r.axis, r.fit.n_theo1_points))
        .collect();
    if !theo.is_empty() {
        writeln!(
            w,
            "Fit extended by Theo1 points beyond the OADEV's longest tau (each modelled by its \
             own expectation per term): {}",
            theo.join(", ")
        )?;
    }
    writeln!(
        w,
        "\nDiscrete per-sample values and classic slope read-offs (N at tau=1 on the -1/2 line, B = min ADEV/0.664, K at tau=3 on the +1/2 line):"
    )?;
    writeln!(
        w,
        "{:<7}{:<3}{:>10}{:>20}{:>22}{:>16}{:>16}{:>16}",
        "sensor",
        "ax",
        "rate [Hz]",
        "white/sample [U]",
        "RW step/sample [U]",
        "N read [U/rtHz]",
        "B read [U]",
        "K read [U*rtHz]"
    )?;
    for r in reports {
        writeln!(
            w,
            "{:<7}{:<3}{:>10.2}{:>20.3e}{:>22.3e}{:>16}{:>16}{:>16}",
            r.sensor.name(),
            r.axis,
            r.sample_rate_hz,
            r.white_per_sample_u,
            r.random_walk_step_per_sample_u,
            opt(r.slope_readoffs.n_u_per_sqrt_hz),
            opt(r.slope_readoffs.b_u),
            opt(r.slope_readoffs.k_u_sqrt_hz),
        )?;
    }
    Ok(())
}

/// The whole table: terms, read-offs, then each deviation kind.
pub fn print(reports: &[AxisReport], w: &mut impl Write) -> std::io::Result<()> {
    print_terms(reports, w)?;
    let n_kinds = reports.first().map_or(0, |r| r.deviations.len());
    for k in 0..n_kinds {
        for sensor in [Triad::Accel, Triad::Gyro] {
            let axes: Vec<&AxisReport> = reports.iter().filter(|r| r.sensor == sensor).collect();
            print_deviation_block(&axes, k, w)?;
        }
    }
    Ok(())
}

/// One kind for the three axes of one sensor: a row per tau, `dev [lo, hi] alpha` per axis.
fn print_deviation_block(
    axes: &[&AxisReport],
    k: usize,
    w: &mut impl Write,
) -> std::io::Result<()> {
    let Some(first) = axes.first().map(|a| &a.deviations[k]) else {
        return Ok(());
    };
    writeln!(
        w,
        "\n{} of {} [{}], {:.1} % confidence bounds ({:?} EDF), alpha = identified noise exponent:",
        first.kind.name().to_uppercase(),
        axes[0].sensor,
        first.unit,
        first.confidence * 100.0,
        first.edf_method,
    )?;
    write!(w, "{:>12}", "tau [s]")?;
    for a in axes {
        write!(w, "{:>36}", format!("{} [lo, hi] alpha", a.axis))?;
    }
    writeln!(w)?;
    for (i, p) in first.points.iter().enumerate() {
        write!(w, "{:>12.4e}", p.point.tau_s)?;
        for a in axes {
            match a.deviations[k].points.get(i) {
                Some(q) => write!(
                    w,
                    "{:>36}",
                    format!(
                        "{:.4e} [{:.3e}, {:.3e}] {:+}",
                        q.point.dev, q.point.dev_lo, q.point.dev_hi, q.alpha
                    )
                )?,
                None => write!(w, "{:>36}", "-")?,
            }
        }
        writeln!(w)?;
    }
    Ok(())
}
