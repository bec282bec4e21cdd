//! The Allan-family figures of a static recording: one figure per sensor with a panel per axis
//! (shared axes), the deviation's points, its confidence band, the fitted IEEE model and each
//! fitted term drawn only over the taus where it contributes, the fitted values with their units
//! in the legend. Every figure takes its colours from [`ALLAN_PALETTE`], so a term has one
//! colour everywhere; every number is written by [`sci`].

use imu_model::{Triad, units};
use imu_stats::allan::{DevCurve, Kind};
use imu_stats::noise_terms::NoiseTerms;
use serde::Serialize;

use super::figure::{Figure, Layer, LegendLine, Panel};
use super::svg::Style;

/// The colours of the Allan figures, one per role.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AllanPalette {
    /// The deviation's points.
    pub data: &'static str,
    /// Its confidence band.
    pub band: &'static str,
    /// The fitted model (all terms together).
    pub fit: &'static str,
    /// Each IEEE term, in the order Q, N, B, K, R.
    pub terms: [&'static str; 5],
}

/// THE palette of every Allan figure (colour-blind-safe Okabe-Ito hues for the terms).
pub const ALLAN_PALETTE: AllanPalette = AllanPalette {
    data: "#1a1a1a",
    band: "#4c72b0",
    fit: "#7f7f7f",
    terms: ["#cc79a7", "#0072b2", "#009e73", "#d55e00", "#e69f00"],
};

/// The term letters, in the order of [`NoiseTerms::as_array`].
pub const TERM_NAMES: [&str; 5] = ["Q", "N", "B", "K", "R"];

/// A term is drawn where its own deviation is at least the model's divided by this.
pub const CONTRIBUTION_FACTOR: f64 = 3.0;

/// Points of each model line (log-spaced over the data's taus).
const MODEL_POINTS: usize = 160;

/// One axis of a sensor: its curve and, for the curve the terms were fitted to, the fit.
#[derive(Debug, Clone, Copy)]
pub struct AxisCurve<'a> {
    /// Axis name (`x`, `y`, `z`).
    pub axis: &'a str,
    /// The deviation.
    pub curve: &'a DevCurve,
    /// The IEEE terms fitted to `curve`, drawn over it.
    pub fit: Option<&'a NoiseTerms>,
}

/// The one number format of the noise figures and report: three significant digits in
/// scientific notation (`1.23e-4`), `0` for zero, a dash when not finite.
pub fn sci(v: f64) -> String {
    if !v.is_finite() {
        "\u{2013}".into()
    } else if v == 0.0 {
        "0".into()
    } else {
        format!("{v:.2e}")
    }
}

/// The unit of each term (Q, N, B, K, R) for rate data in `unit`.
pub fn term_units(unit: &str) -> [String; 5] {
    [
        format!("{unit}\u{b7}s"),
        format!("{unit}/\u{221a}Hz"),
        unit.to_string(),
        format!("{unit}\u{b7}\u{221a}Hz"),
        format!("{unit}/s"),
    ]
}

/// The long name of a deviation kind, for titles.
pub fn kind_title(kind: Kind) -> &'static str {
    match kind {
        Kind::Adev => "Allan deviation (ADEV)",
        Kind::Oadev => "overlapping Allan deviation (OADEV)",
        Kind::Mdev => "modified Allan deviation (MDEV)",
        Kind::Hdev => "Hadamard deviation (HDEV)",
        Kind::Ohdev => "overlapping Hadamard deviation (OHDEV)",
        Kind::Tdev => "time deviation (TDEV)",
        Kind::Totdev => "total deviation (TOTDEV)",
        Kind::Theo1 => "Theo1 deviation (THEO1, tau = 0.75 m tau0)",
        Kind::Theoh => "hybrid Theo deviation (THEOH: OADEV, then bias-removed Theo1)",
    }
}

/// The figure of one sensor (`accel`, `gyro`) whose rate data are in `unit`: a panel per axis
/// with the curve's kind, its band and, where an axis has a fit, the model and its terms.
pub fn sensor_figure(sensor: &str, unit: &str, axes: &[AxisCurve]) -> Figure {
    let kind = axes.first().map_or(Kind::Oadev, |a| a.curve.kind);
    let name = kind.name().to_uppercase();
    let y_unit = if kind == Kind::Tdev {
        format!("{unit}\u{b7}s")
    } else {
        unit.to_string()
    };
    let fitted = axes.iter().any(|a| a.fit.is_some());
    Figure {
        title: format!(
            "{sensor}: {}{}",
            kind_title(kind),
            if fitted { " and fitted IEEE terms" } else { "" }
        ),
        x_label: "tau [s]".into(),
        y_label: format!("{name}(tau) [{y_unit}]"),
        log_x: true,
        log_y: true,
        panels: axes
            .iter()
            .map(|a| axis_panel(sensor, unit, &name, a))
            .collect(),
    }
}

fn axis_panel(sensor: &str, unit: &str, name: &str, a: &AxisCurve) -> Panel {
    let c = a.curve;
    let pts = |f: &dyn Fn(&imu_stats::allan::DevPoint) -> f64| -> Vec<(f64, f64)> {
        c.points.iter().map(|p| (p.tau_s, f(p))).collect()
    };
    let band = Style::Band {
        upper: pts(&|p| p.dev_hi),
    };
    let confidence = format!("{:.1}% confidence", c.confidence * 100.0);
    let mut panel = Panel {
        title: format!("{sensor} {}", a.axis),
        layers: vec![
            Layer {
                name: confidence.clone(),
                color: ALLAN_PALETTE.band,
                points: pts(&|p| p.dev_lo),
                style: band.clone(),
                sets_range: true,
            },
            Layer {
                name: name.to_string(),
                color: ALLAN_PALETTE.data,
                points: pts(&|p| p.dev),
                style: Style::Points,
                sets_range: true,
            },
        ],
        legend: vec![
            LegendLine {
                swatch: Some((Style::Points, ALLAN_PALETTE.data)),
                text: name.to_string(),
            },
            LegendLine {
                swatch: Some((band, ALLAN_PALETTE.band)),
                text: confidence,
            },
        ],
    };
    if let Some(fit) = a.fit {
        add_fit(&mut panel, fit, unit, c);
    }
    panel
}

/// The model line, the lines of the terms where they contribute, their values in the legend.
fn add_fit(panel: &mut Panel, fit: &NoiseTerms, unit: &str, c: &DevCurve) {
    let taus = model_taus(c);
    let terms = fit.as_array();
    let present: Vec<usize> = (0..5).filter(|&k| terms[k].value > 0.0).collect();
    panel.layers.push(Layer {
        name: "fit".into(),
        color: ALLAN_PALETTE.fit,
        points: taus.iter().map(|&t| (t, fit.adev(t))).collect(),
        style: Style::Line,
        sets_range: false,
    });
    let letters: Vec<&str> = present.iter().map(|&k| TERM_NAMES[k]).collect();
    panel.legend.push(LegendLine {
        swatch: Some((Style::Line, ALLAN_PALETTE.fit)),
        text: format!("fit: {}", letters.join(" + ")),
    });
    let units = term_units(unit);
    for &k in &present {
        let points = taus
            .iter()
            .map(|&t| {
                let term = fit.term_adevs(t)[k];
                let shown = term * CONTRIBUTION_FACTOR >= fit.adev(t);
                (t, if shown { term } else { f64::NAN })
            })
            .collect();
        panel.layers.push(Layer {
            name: format!("{} term", TERM_NAMES[k]),
            color: ALLAN_PALETTE.terms[k],
            points,
            style: Style::Line,
            sets_range: false,
        });
        let t = terms[k];
        panel.legend.push(LegendLine {
            swatch: Some((Style::Line, ALLAN_PALETTE.terms[k])),
            text: format!(
                "{} {} \u{b1} {} {}{}",
                TERM_NAMES[k],
                sci(t.value),
                sci(t.sigma),
                units[k],
                if t.significant { "" } else { " (n.s.)" }
            ),
        });
    }
    let absent: Vec<&str> = (0..5)
        .filter(|k| !present.contains(k))
        .map(|k| TERM_NAMES[k])
        .collect();
    if !absent.is_empty() {
        panel.legend.push(LegendLine {
            swatch: None,
            text: format!("not supported by the curve: {}", absent.join(", ")),
        });
    }
}

/// Log-spaced taus over the curve's range, for the model lines.
fn model_taus(c: &DevCurve) -> Vec<f64> {
    let (Some(first), Some(last)) = (c.points.first(), c.points.last()) else {
        return Vec::new();
    };
    let (lo, hi) = (first.tau_s.ln(), last.tau_s.ln());
    (0..MODEL_POINTS)
        .map(|i| (lo + (hi - lo) * i as f64 / (MODEL_POINTS - 1) as f64).exp())
        .collect()
}

/// The noise of one sensor axis, as imu-noise reports it.
#[derive(Debug, Clone, Copy)]
pub struct NoiseAxis<'a> {
    /// Which sensor.
    pub triad: Triad,
    /// Axis name (`x`, `y`, `z`).
    pub axis: &'a str,
    /// The IEEE terms...
    pub fit: &'a NoiseTerms,
    /// ... fitted to this OADEV curve.
    pub fit_curve: &'a DevCurve,
    /// Every deviation asked for (an OADEV among them is drawn by the fit's figure).
    pub curves: &'a [DevCurve],
}

/// Every figure of imu-noise with its file stem: per sensor, the OADEV with the fitted terms
/// (`allan-SENSOR`), then each other kind (`dev-KIND-SENSOR`), in the order the kinds were
/// asked for.
pub fn noise_figures(axes: &[NoiseAxis]) -> Vec<(String, Figure)> {
    let mut out = Vec::new();
    for triad in [Triad::Accel, Triad::Gyro, Triad::Mag] {
        let mine: Vec<&NoiseAxis> = axes.iter().filter(|a| a.triad == triad).collect();
        let Some(first) = mine.first() else {
            continue;
        };
        let (sensor, unit) = (triad.name(), triad.unit());
        let fitted: Vec<AxisCurve> = mine
            .iter()
            .map(|a| AxisCurve {
                axis: a.axis,
                curve: a.fit_curve,
                fit: Some(a.fit),
            })
            .collect();
        out.push((
            format!("allan-{sensor}"),
            sensor_figure(sensor, unit, &fitted),
        ));
        for (k, c) in first.curves.iter().enumerate() {
            if c.kind == Kind::Oadev {
                continue;
            }
            let curves: Vec<AxisCurve> = mine
                .iter()
                .filter_map(|a| {
                    Some(AxisCurve {
                        axis: a.axis,
                        curve: a.curves.get(k)?,
                        fit: None,
                    })
                })
                .collect();
            out.push((
                format!("dev-{}-{sensor}", c.kind.name()),
                sensor_figure(sensor, unit, &curves),
            ));
        }
    }
    out
}

/// The big three terms in the units datasheets use: N, B, K in deg/sqrt(h), deg/h,
/// deg/h/sqrt(h) (gyro) or micro-g/sqrt(Hz), micro-g, micro-g*sqrt(Hz) (accel); a
/// magnetometer's stay in gauss.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DisplayTerms {
    /// White noise N.
    pub n: f64,
    /// Unit of `n`.
    pub n_unit: &'static str,
    /// Bias instability B.
    pub b: f64,
    /// Unit of `b`.
    pub b_unit: &'static str,
    /// Rate random walk K.
    pub k: f64,
    /// Unit of `k`.
    pub k_unit: &'static str,
}

impl DisplayTerms {
    /// `t` (in the triad's SI unit) in display units.
    pub fn of(triad: Triad, t: &NoiseTerms) -> Self {
        let (n, b, k) = (t.n_u_per_sqrt_hz.value, t.b_u.value, t.k_u_sqrt_hz.value);
        match triad {
            Triad::Gyro => {
                // rad/s/sqrt(Hz) = rad/sqrt(s) -> deg/sqrt(h): x 180/pi x 60.
                let deg_h = units::RAD_TO_DEG * units::SECONDS_PER_HOUR;
                Self {
                    n: n / units::DEG_PER_SQRT_HOUR_TO_RAD_PER_SQRT_S,
                    n_unit: "deg/sqrt(h)",
                    b: b * deg_h,
                    b_unit: "deg/h",
                    k: k * deg_h * 60.0,
                    k_unit: "deg/h/sqrt(h)",
                }
            }
            Triad::Accel => Self {
                n: n / units::MICRO_G_TO_M_S2,
                n_unit: "micro-g/sqrt(Hz)",
                b: b / units::MICRO_G_TO_M_S2,
                b_unit: "micro-g",
                k: k / units::MICRO_G_TO_M_S2,
                k_unit: "micro-g*sqrt(Hz)",
            },
            Triad::Mag => Self {
                n,
                n_unit: "gauss/sqrt(Hz)",
                b,
                b_unit: "gauss",
                k,
                k_unit: "gauss*sqrt(Hz)",
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use imu_stats::allan::DevPoint;
    use imu_stats::noise_terms::Term;

    use super::*;
    use crate::render::figure::render_figure;
    use crate::render::lint::{check_svg, panel_ranges};

    fn term(value: f64) -> Term {
        Term {
            value,
            sigma: 0.05 * value,
            significant: value > 0.0,
        }
    }

    /// White noise N = 1e-3 and random walk K = 2e-5 (crossing at sqrt(3) N / K = 87 s), the
    /// curve exactly the model's, octave taus 0.05..3277 s.
    fn fixture() -> (NoiseTerms, DevCurve) {
        let fit = NoiseTerms {
            q_u_s: term(0.0),
            n_u_per_sqrt_hz: term(1e-3),
            b_u: term(0.0),
            k_u_sqrt_hz: term(2e-5),
            r_u_per_s: term(0.0),
            chi2_per_dof: 1.0,
            n_points: 17,
            n_theo1_points: 0,
        };
        let points = (0..17)
            .map(|i| {
                let m = 1usize << i;
                let tau_s = 0.05 * m as f64;
                let dev = fit.adev(tau_s);
                DevPoint {
                    m,
                    tau_s,
                    dev,
                    n_terms: 1000,
                    edf: 100.0,
                    dev_lo: 0.9 * dev,
                    dev_hi: 1.1 * dev,
                }
            })
            .collect();
        let curve = DevCurve {
            kind: Kind::Oadev,
            tau0_s: 0.05,
            confidence: 0.683,
            points,
        };
        (fit, curve)
    }

    /// The taus a term's line is drawn at, read back from the figure's model.
    fn drawn_taus(panel: &Panel, name: &str) -> Vec<f64> {
        let layer = panel.layers.iter().find(|l| l.name == name).unwrap();
        layer
            .points
            .iter()
            .filter(|p| p.1.is_finite())
            .map(|p| p.0)
            .collect()
    }

    #[test]
    fn terms_are_drawn_only_where_they_contribute() {
        let (fit, curve) = fixture();
        let axes: Vec<AxisCurve> = ["x", "y", "z"]
            .map(|axis| AxisCurve {
                axis,
                curve: &curve,
                fit: Some(&fit),
            })
            .to_vec();
        let fig = sensor_figure("gyro", "rad/s", &axes);
        assert_eq!(fig.panels.len(), 3);
        let n = drawn_taus(&fig.panels[0], "N term");
        let k = drawn_taus(&fig.panels[0], "K term");
        // A term is a third of the model where its variance is 1/9 of the sum: N up to
        // sqrt(8) x 86.6 s = 245 s, K from 86.6 s / sqrt(8) = 30.6 s (a model step is 7 %).
        let (n_max, k_min) = (n.iter().copied().fold(0.0, f64::max), k[0]);
        assert!(
            n[0] <= 0.051 && (228.0..245.0).contains(&n_max),
            "N {n_max}"
        );
        assert!((30.6..33.0).contains(&k_min), "K from {k_min}");
        assert!(k.last().unwrap() > &3000.0);
        assert!(fig.panels[0].layers.iter().all(|l| l.name != "B term"));
        let legend: Vec<&str> = fig.panels[0]
            .legend
            .iter()
            .map(|l| l.text.as_str())
            .collect();
        assert!(
            legend.contains(&"N 1.00e-3 \u{b1} 5.00e-5 rad/s/\u{221a}Hz"),
            "{legend:?}"
        );
        assert!(
            legend.contains(&"not supported by the curve: Q, B, R"),
            "{legend:?}"
        );

        let svg = render_figure(&fig);
        assert_eq!(check_svg(&svg), Vec::<String>::new());
        let r = panel_ranges(&svg)[0];
        // The data: taus 0.05..3277 s, the bounds' extremes.
        let lo = curve.points.iter().map(|p| p.dev_lo).fold(1.0, f64::min);
        let hi = curve.points.iter().map(|p| p.dev_hi).fold(0.0, f64::max);
        assert!(r[0] < 0.05 && r[0] > 0.05 / 1.5 && r[1] > 3276.0 && r[1] < 3277.0 * 1.5);
        assert!(
            r[2] < lo && r[2] > lo / 1.5 && r[3] > hi && r[3] < hi * 1.5,
            "{r:?}"
        );
    }

    #[test]
    fn one_number_format() {
        assert_eq!(sci(1.234_56e-4), "1.23e-4");
        assert_eq!(sci(0.0), "0");
        assert_eq!(sci(f64::NAN), "\u{2013}");
        assert_eq!(sci(12345.0), "1.23e4");
    }
}
