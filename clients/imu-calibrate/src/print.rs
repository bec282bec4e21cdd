//! The text output: parameter tables, fitted against true values, the reference-free summary.

use super::*;

/// Fitted vs true for every parameter (an effect absent from the truth has truth 0).
pub(super) fn compare(
    triad: Triad,
    names: &[String],
    units: &[String],
    params: &[f64],
    std_errors: &[Option<f64>],
    truth: &TriadModel,
) -> Vec<TruthRow> {
    let truth_names = truth.param_names(triad);
    let values = truth.params();
    (0..params.len())
        .map(|i| {
            let t = truth_names
                .iter()
                .position(|n| *n == names[i])
                .map_or(0.0, |k| values[k]);
            let se = std_errors[i];
            TruthRow {
                triad,
                name: names[i].clone(),
                unit: units[i].clone(),
                fitted: params[i],
                truth: t,
                std_error: se,
                error_in_se: se.map(|s| (params[i] - t) / s),
            }
        })
        .collect()
}

pub(super) fn truth_rows(fit: &FitResult, truth: &TriadModel) -> Vec<TruthRow> {
    compare(
        fit.triad,
        &fit.names,
        &fit.units,
        &fit.params,
        &fit.std_errors,
        truth,
    )
}

/// The parameter table: name, value, standard error (`missing` where there is none), unit.
pub(super) fn print_params(
    out: &mut impl Write,
    names: &[String],
    params: &[f64],
    std_errors: &[Option<f64>],
    units: &[String],
    missing: &str,
) -> std::io::Result<()> {
    writeln!(
        out,
        "  {:<36} {:>13} {:>11}  unit",
        "parameter", "value", "std error"
    )?;
    for i in 0..params.len() {
        let se = std_errors[i].map_or_else(|| missing.to_string(), |s| format!("{s:.3e}"));
        writeln!(
            out,
            "  {:<36} {:>13.5e} {:>11}  {}",
            names[i], params[i], se, units[i]
        )?;
    }
    Ok(())
}

pub(super) fn print_fit(out: &mut impl Write, fit: &FitResult) -> std::io::Result<()> {
    writeln!(
        out,
        "\n{} ({} segments, {} free parameters, reduced chi2 {:.2}, {} iterations{})",
        fit.triad,
        fit.residuals.len(),
        fit.free.len(),
        fit.reduced_chi2,
        fit.iterations,
        if fit.converged { "" } else { ", NOT converged" }
    )?;
    print_params(
        out,
        &fit.names,
        &fit.params,
        &fit.std_errors,
        &fit.units,
        "not fitted",
    )?;
    let unit = fit.triad.unit();
    writeln!(
        out,
        "  residual RMS x {:.3e}  y {:.3e}  z {:.3e}  {unit}",
        fit.residual_rms[0], fit.residual_rms[1], fit.residual_rms[2]
    )?;
    for w in &fit.warnings {
        writeln!(out, "  warning: {w}")?;
    }
    Ok(())
}

pub(super) fn print_tables(
    out: &mut impl Write,
    fit: &CalibrationFit,
    truth: Option<&[TruthRow]>,
) -> std::io::Result<()> {
    let several = fit.recordings.len() > 1;
    for (k, r) in fit.recordings.iter().enumerate() {
        let s = &r.segmentation;
        let indent = if several {
            writeln!(out, "recording {}: {}", k + 1, r.origin)?;
            writeln!(out, "  reference: {}", r.reference)?;
            "  "
        } else {
            ""
        };
        writeln!(
            out,
            "{indent}segments: {} static, {} rate plateaus (window {} samples; thresholds: accel std {:.3e} m/s^2, gyro std {:.3e} rad/s)",
            s.count(SegmentKind::Static),
            s.count(SegmentKind::Plateau),
            s.window_samples,
            s.accel_std_threshold_m_s2,
            s.gyro_std_threshold_rad_s
        )?;
        if several {
            writeln!(
                out,
                "{indent}points: {} accel, {} gyro",
                r.accel_points.len(),
                r.gyro_points.len()
            )?;
        }
    }
    for n in &fit.notes {
        writeln!(out, "note: {n}")?;
    }
    print_fit(out, &fit.accel)?;
    print_fit(out, &fit.gyro)?;
    if let Some(rows) = truth {
        writeln!(out, "\nfitted vs truth")?;
        print_truth(out, rows)?;
    }
    Ok(())
}

pub(super) fn print_truth(out: &mut impl Write, rows: &[TruthRow]) -> std::io::Result<()> {
    {
        writeln!(
            out,
            "  {:<5} {:<36} {:>13} {:>13} {:>8}  unit",
            "triad", "parameter", "fitted", "truth", "err/SE"
        )?;
        for r in rows {
            let z = r
                .error_in_se
                .map_or_else(|| "-".to_string(), |z| format!("{z:.2}"));
            writeln!(
                out,
                "  {:<5} {:<36} {:>13.5e} {:>13.5e} {:>8}  {}",
                r.triad.to_string(),
                r.name,
                r.fitted,
                r.truth,
                z,
                r.unit
            )?;
        }
    }
    Ok(())
}

/// One reference-free triad fit (parameters, standard errors, residuals, warnings).
pub(super) fn print_triad_fit(out: &mut impl Write, fit: &TriadFit) -> std::io::Result<()> {
    writeln!(
        out,
        "\n{} ({} residuals, {} free parameters, reduced chi2 {:.2}, smallest normalised eigenvalue {:.1e}, {} iterations{})",
        fit.triad,
        fit.n_residuals,
        fit.free.len(),
        fit.reduced_chi2,
        fit.min_eigenvalue,
        fit.iterations,
        if fit.converged { "" } else { ", NOT converged" }
    )?;
    print_params(
        out,
        &fit.names,
        &fit.params,
        &fit.std_errors,
        &fit.units,
        "held",
    )?;
    writeln!(
        out,
        "  residual RMS {:.3e} {} ({})",
        fit.residual_rms, fit.residual_unit, fit.residual
    )?;
    for u in &fit.unobservable {
        writeln!(out, "  held: {}: {}", u.name, u.reason)?;
    }
    for w in &fit.warnings {
        writeln!(out, "  warning: {w}")?;
    }
    Ok(())
}

pub(super) fn print_reference_free(
    out: &mut impl Write,
    fit: &ReferenceFreeFit,
    truth: Option<&[TruthRow]>,
) -> std::io::Result<()> {
    let s = &fit.segmentation;
    writeln!(
        out,
        "reference-free: {} still poses, {} moves (window {} samples; thresholds: accel std {:.3e} m/s^2, gyro std {:.3e} rad/s); g = {:.6} m/s^2",
        fit.poses.len(),
        fit.moves.len(),
        s.window_samples,
        s.accel_std_threshold_m_s2,
        s.gyro_std_threshold_rad_s,
        fit.gravity_m_s2
    )?;
    for n in &fit.notes {
        writeln!(out, "note: {n}")?;
    }
    print_triad_fit(out, &fit.accel)?;
    print_triad_fit(out, &fit.gyro)?;
    if let Some(rows) = truth {
        writeln!(
            out,
            "\nfitted vs truth (truth re-expressed in the body frame the accelerometer defines)"
        )?;
        print_truth(out, rows)?;
    }
    Ok(())
}
