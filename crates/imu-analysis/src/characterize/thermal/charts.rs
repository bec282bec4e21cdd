//! The thermal charts (the paper's Figures 4-6): temperature versus time with the warm-up fit,
//! and the binned outputs versus time and versus temperature.

use super::{ThermalReport, ThermalVerdict};
use crate::characterize::units::DisplayUnit;
use crate::render::number::number;
use crate::render::svg::{Chart, Figure, Look, Series, Style, axis_colour};

/// Charts like the paper's Figures 4-6: temperature versus time with the warm-up fit, and the
/// binned outputs (offset from their mean, in mg and deg/h) versus time and versus
/// temperature, the latter with each axis's fitted slope drawn as a line of the axis's colour.
pub fn charts(report: &ThermalReport) -> Vec<Figure> {
    let mut out = vec![Figure::from(temperature_chart(report))];
    for (sensor, quantity, k0) in [("accel", "specific force", 0usize), ("gyro", "rate", 3)] {
        let unit = DisplayUnit::of_sensor(sensor);
        let y_label = format!("{quantity} - mean [{}]", unit.label());
        for by_time in [true, false] {
            let mut series: Vec<Series> = (0..3)
                .map(|i| bin_mean_series(report, sensor, k0 + i, i, unit.per_si(), by_time))
                .collect();
            let mut looks: Vec<_> = (0..3).map(axis_colour).collect();
            if !by_time {
                series.extend((0..3).map(|i| slope_series(report, k0 + i, unit)));
                looks.extend((0..3).map(axis_colour));
            }
            let versus = if by_time { "time" } else { "temperature" };
            out.push(Figure {
                chart: Chart {
                    title: format!("{sensor} {} s means vs {versus}", report.bin_s),
                    x_label: if by_time {
                        "time [min]"
                    } else {
                        "temperature [deg C]"
                    }
                    .into(),
                    y_label: y_label.clone(),
                    series,
                    ..Chart::default()
                },
                look: Look {
                    series: looks,
                    ..Look::default()
                },
            });
        }
    }
    out
}

/// Report axis `k`'s fitted linear slope as a line across the bins' temperatures, offset so it
/// runs through the axis's mean; named with its slope in `unit` per K and its verdict.
fn slope_series(report: &ThermalReport, k: usize, unit: DisplayUnit) -> Series {
    let a = &report.axes[k];
    let (lo, hi) = report
        .bins
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), b| {
            (l.min(b.temp_c), h.max(b.temp_c))
        });
    let fit = |t: f64| {
        let c = &a.linear.coefficients;
        (c[0] + c[1] * (t - report.temp_ref_c) - a.mean) * unit.per_si()
    };
    let word = match a.verdict {
        ThermalVerdict::Warranted | ThermalVerdict::NoTemperatureRange => "",
        ThermalVerdict::ResolvedButNegligible => " (small)",
        ThermalVerdict::NotResolvable { .. } => " (n.s.)",
    };
    Series {
        name: format!(
            "{}: {}/K{word}",
            a.axis,
            number(a.bias_coeff_per_k * unit.per_si())
        ),
        points: vec![(lo, fit(lo)), (hi, fit(hi))],
        style: Style::Line,
    }
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
