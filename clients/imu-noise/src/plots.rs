//! The figures (`imu_analysis::render::allan`: per sensor, a panel per axis): as SVG files
//! (`--plot DIR`: `allan-SENSOR.svg`, the OADEV with the fitted terms, and `dev-KIND-SENSOR.svg`
//! for each other kind) and in the HTML report (`--report FILE`).

use std::path::Path;

use anyhow::{Context, Result};
use imu_analysis::ImuSeries;
use imu_analysis::render::allan::{NoiseAxis, noise_figures};
use imu_analysis::render::figure::render_figure;
use imu_analysis::render::html::{noise_sections, page};
use imu_stats::allan::DevCurve;

use crate::AxisReport;

/// The deviations of each axis as curves, in the order of `reports`.
fn curves(reports: &[AxisReport]) -> Vec<Vec<DevCurve>> {
    reports
        .iter()
        .map(|r| {
            r.deviations
                .iter()
                .map(|k| DevCurve {
                    kind: k.kind,
                    tau0_s: r.curve.tau0_s,
                    confidence: k.confidence,
                    points: k.points.iter().map(|p| p.point).collect(),
                })
                .collect()
        })
        .collect()
}

fn noise_axes<'a>(reports: &'a [AxisReport], curves: &'a [Vec<DevCurve>]) -> Vec<NoiseAxis<'a>> {
    reports
        .iter()
        .zip(curves)
        .map(|(r, c)| NoiseAxis {
            triad: r.sensor,
            axis: r.axis,
            fit: &r.fit,
            fit_curve: &r.curve,
            curves: c,
        })
        .collect()
}

/// Every figure into `dir` (created if missing).
pub fn write_figures(dir: &Path, reports: &[AxisReport]) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let curves = curves(reports);
    for (stem, fig) in noise_figures(&noise_axes(reports, &curves)) {
        let path = dir.join(format!("{stem}.svg"));
        std::fs::write(&path, render_figure(&fig))
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

/// The HTML report of `series` (read from `shown`) to `path`.
pub fn write_report(
    path: &Path,
    shown: &str,
    series: &ImuSeries,
    reports: &[AxisReport],
) -> Result<()> {
    let rate_hz = reports.first().map_or(f64::NAN, |r| r.sample_rate_hz);
    let mut facts = vec![
        ("recording".to_string(), shown.to_string()),
        ("samples".to_string(), series.len().to_string()),
        ("sample rate".to_string(), format!("{rate_hz:.3} Hz")),
        (
            "duration".to_string(),
            format!("{:.1} s", series.len() as f64 / rate_hz),
        ),
    ];
    if let Some(first) = reports.first().and_then(|r| r.deviations.first()) {
        facts.push((
            "confidence bounds".to_string(),
            format!(
                "{:.1} %, {:?} EDF",
                first.confidence * 100.0,
                first.edf_method
            ),
        ));
    }
    if let Some(w) = series.motion_warning() {
        facts.push(("warning".to_string(), w));
    }
    let curves = curves(reports);
    let sections = noise_sections(&facts, &noise_axes(reports, &curves));
    std::fs::write(path, page(&format!("imu-noise: {shown}"), &sections))
        .with_context(|| format!("writing {}", path.display()))
}
