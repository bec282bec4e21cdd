//! The thermal charts (the paper's Figures 4-6): temperature versus time with the warm-up fit,
//! and the binned outputs versus time and versus temperature.

use super::{G0, ThermalReport};
use crate::render::svg::{Chart, Series, Style};

/// Charts like the paper's Figures 4-6: temperature versus time with the warm-up fit, and the
/// binned outputs (offset from their mean) versus time and versus temperature.
pub fn charts(report: &ThermalReport) -> Vec<Chart> {
    let mut out = vec![temperature_chart(report)];
    for (sensor, unit_label, k0, scale) in [
        ("accel", "specific force - mean [mg]", 0usize, 1e3 / G0),
        ("gyro", "rate - mean [deg/h]", 3, 3600.0_f64.to_degrees()),
    ] {
        for (versus, x_label) in [
            ("time", "time [min]"),
            ("temperature", "temperature [deg C]"),
        ] {
            let series = (0..3)
                .map(|i| bin_mean_series(report, sensor, k0 + i, i, scale, versus == "time"))
                .collect();
            out.push(Chart {
                title: format!("{sensor} {}-s means vs {versus}", report.bin_s),
                x_label: x_label.into(),
                y_label: unit_label.into(),
                series,
                ..Chart::default()
            });
        }
    }
    out
}

/// The bins' mean temperature over time, with the warm-up fit if any.
fn temperature_chart(report: &ThermalReport) -> Chart {
    let mut temp_series = vec![Series {
        name: "bin mean temperature".into(),
        points: report
            .bins
            .iter()
            .map(|b| (b.t_s / 60.0, b.temp_c))
            .collect(),
        style: Style::Points,
    }];
    if let Some(w) = &report.warmup {
        let t_end = report.duration_s.max(1.0);
        temp_series.push(Series {
            name: format!("fit, tau = {:.0} s", w.tau_s),
            points: (0..=200)
                .map(|k| {
                    let t = t_end * f64::from(k) / 200.0;
                    (
                        t / 60.0,
                        w.final_c - (w.final_c - w.start_c) * (-t / w.tau_s).exp(),
                    )
                })
                .collect(),
            style: Style::Line,
        });
    }
    Chart {
        title: "Internal temperature".into(),
        x_label: "time [min]".into(),
        y_label: "temperature [deg C]".into(),
        series: temp_series,
        ..Chart::default()
    }
}

/// Axis `i` of `sensor` (report axis `k`): its bin means minus their mean, times `scale`,
/// against time in minutes (a line) or temperature (points).
fn bin_mean_series(
    report: &ThermalReport,
    sensor: &str,
    k: usize,
    i: usize,
    scale: f64,
    by_time: bool,
) -> Series {
    let ax = &report.axes[k];
    Series {
        name: format!("{sensor} {}", ax.axis),
        points: report
            .bins
            .iter()
            .map(|b| {
                let v = if sensor == "accel" {
                    b.accel_m_s2[i]
                } else {
                    b.gyro_rad_s[i]
                };
                let x = if by_time { b.t_s / 60.0 } else { b.temp_c };
                (x, (v - ax.mean) * scale)
            })
            .collect(),
        style: if by_time { Style::Line } else { Style::Points },
    }
}
