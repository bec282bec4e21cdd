//! SVG plots: the OADEV with its confidence band, the fitted model and each fitted term
//! (`adev-SENSOR-AXIS.svg`), and every other requested deviation kind with its band
//! (`dev-KIND-SENSOR-AXIS.svg`).

use std::path::Path;

use anyhow::{Context, Result};
use imu_analysis::render::svg::{Chart, Series, Style, write_svg};
use imu_stats::allan::{self, Kind};

use crate::{AxisReport, KindReport};

/// Every plot of one axis.
pub fn write_axis(dir: &Path, r: &AxisReport) -> Result<()> {
    plot_fit(dir, r)?;
    for k in r.deviations.iter().filter(|k| k.kind != Kind::Oadev) {
        plot_kind(dir, r, k)?;
    }
    Ok(())
}

/// One non-OADEV kind: points and the confidence band.
fn plot_kind(dir: &Path, r: &AxisReport, k: &KindReport) -> Result<()> {
    let pts = |f: &dyn Fn(&allan::DevPoint) -> f64| -> Vec<(f64, f64)> {
        k.points
            .iter()
            .map(|p| (p.point.tau_s, f(&p.point)))
            .collect()
    };
    let name = k.kind.name().to_uppercase();
    let chart = Chart {
        title: format!("{} {}: {name}", r.sensor, r.axis),
        x_label: "tau [s]".into(),
        y_label: format!("{name}(tau) [{}]", k.unit),
        log_x: true,
        log_y: true,
        series: vec![
            Series {
                name: format!("{:.0}% confidence", k.confidence * 100.0),
                points: pts(&|p| p.dev_lo),
                style: Style::Band {
                    upper: pts(&|p| p.dev_hi),
                },
            },
            Series {
                name: name.clone(),
                points: pts(&|p| p.dev),
                style: Style::Points,
            },
        ],
    };
    let path = dir.join(format!("dev-{}-{}-{}.svg", k.kind.name(), r.sensor, r.axis));
    write_svg(&chart, &path).with_context(|| format!("writing {}", path.display()))
}

fn plot_fit(dir: &Path, r: &AxisReport) -> Result<()> {
    let c = &r.curve;
    let pts = |f: &dyn Fn(&allan::DevPoint) -> f64| -> Vec<(f64, f64)> {
        c.points.iter().map(|p| (p.tau_s, f(p))).collect()
    };
    let mut series = vec![
        Series {
            name: format!("{:.0}% confidence", c.confidence * 100.0),
            points: pts(&|p| p.dev_lo),
            style: Style::Band {
                upper: pts(&|p| p.dev_hi),
            },
        },
        Series {
            name: "OADEV".into(),
            points: pts(&|p| p.dev),
            style: Style::Points,
        },
        Series {
            name: "fit".into(),
            points: pts(&|p| r.fit.adev(p.tau_s)),
            style: Style::Line,
        },
    ];
    for (k, name) in ["Q", "N", "B", "K", "R"].iter().enumerate() {
        let line: Vec<(f64, f64)> = c
            .points
            .iter()
            .map(|p| (p.tau_s, r.fit.term_adevs(p.tau_s)[k]))
            .collect();
        if line.iter().any(|p| p.1 > 0.0) {
            series.push(Series {
                name: format!("{name} term"),
                points: line,
                style: Style::Line,
            });
        }
    }
    let chart = Chart {
        title: format!("{} {}: overlapping Allan deviation", r.sensor, r.axis),
        x_label: "tau [s]".into(),
        y_label: format!("sigma(tau) [{}]", r.unit),
        log_x: true,
        log_y: true,
        series,
    };
    let path = dir.join(format!("adev-{}-{}.svg", r.sensor, r.axis));
    write_svg(&chart, &path).with_context(|| format!("writing {}", path.display()))
}
