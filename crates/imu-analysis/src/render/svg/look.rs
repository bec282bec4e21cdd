//! A chart with a look: per-series colours (the same colour for the same axis everywhere),
//! dashed lines (a raw line stays visible under a calibrated one), and integer ticks on the
//! horizontal axis (a ladder's steps). A [`Figure`] is a [`Chart`] plus its [`Look`]; the
//! default look renders exactly as [`render_svg`](super::render_svg).

use std::fmt::Write as _;

use super::{
    Chart, PALETTE, Plot, Series, Style, X0, X1, Y0, Y1, escape, write_frame_and_labels,
    write_header,
};

/// Where the ticks of the horizontal axis go.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Ticks {
    /// "Nice" steps of 1, 2 or 5 times a power of ten (or decades on a log axis).
    #[default]
    Auto,
    /// Whole numbers only (a count or a step index): never a tick at 0.2.
    Integer,
}

/// How one series is drawn beyond its [`Style`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SeriesLook {
    /// Index into the palette; `None`: the series' own index, as `render_svg` does.
    pub colour: Option<usize>,
    /// Draw a line dashed.
    pub dashed: bool,
}

/// The look of a chart: tick rule of the x axis and per-series looks (missing ones default).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Look {
    /// Ticks of the horizontal axis.
    pub x_ticks: Ticks,
    /// Per series, in the chart's order.
    pub series: Vec<SeriesLook>,
}

/// The palette index of axis `x`, `y`, `z` (0, 1, 2): blue, red, green on every chart.
pub fn axis_colour(axis: usize) -> SeriesLook {
    SeriesLook {
        colour: Some(axis),
        dashed: false,
    }
}

/// A chart and its look.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Figure {
    /// What is drawn.
    pub chart: Chart,
    /// How.
    pub look: Look,
}

impl From<Chart> for Figure {
    fn from(chart: Chart) -> Self {
        Self {
            chart,
            look: Look::default(),
        }
    }
}

impl Figure {
    /// Renders the figure as a standalone SVG document (800 x 560 px, as `render_svg`).
    pub fn to_svg(&self) -> String {
        let chart = &self.chart;
        let plot = Plot::new(chart);
        let mut s = String::new();
        write_header(&mut s, chart);
        let x_ticks = match self.look.x_ticks {
            Ticks::Auto => plot.xa.ticks(),
            Ticks::Integer => integer_ticks(plot.xa.lo, plot.xa.hi, plot.xa.log),
        };
        write_grid_and_labels(&mut s, &plot, &x_ticks);
        let _ = writeln!(
            s,
            r#"<clipPath id="plot-area"><rect x="{X0}" y="{Y0}" width="{}" height="{}"/></clipPath>"#,
            X1 - X0,
            Y1 - Y0
        );
        s.push_str("<g clip-path=\"url(#plot-area)\">\n");
        for (i, series) in chart.series.iter().enumerate() {
            let look = self.series_look(i);
            if look.dashed {
                s.push_str("<g stroke-dasharray=\"7 4\">\n");
            }
            plot.write_one_series(&mut s, series, self.colour(i));
            if look.dashed {
                s.push_str("</g>\n");
            }
        }
        s.push_str("</g>\n");
        write_frame_and_labels(&mut s, chart);
        self.write_legend(&mut s);
        s.push_str("</svg>\n");
        s
    }

    fn series_look(&self, i: usize) -> SeriesLook {
        self.look.series.get(i).copied().unwrap_or_default()
    }

    fn colour(&self, i: usize) -> &'static str {
        let k = self.series_look(i).colour.unwrap_or(i);
        PALETTE[k % PALETTE.len()]
    }

    /// The legend (as `render_svg`'s, with each series' colour and dash).
    fn write_legend(&self, s: &mut String) {
        s.push_str("<g class=\"legend\">\n");
        for (i, series) in self.chart.series.iter().enumerate() {
            let (color, ly, lx) = (self.colour(i), Y0 + 10.0 + 20.0 * i as f64, X1 + 12.0);
            let dash = if self.series_look(i).dashed {
                r#" stroke-dasharray="7 4""#
            } else {
                ""
            };
            let _ = match series.style {
                Style::Line => writeln!(
                    s,
                    r#"<line x1="{lx}" y1="{ly}" x2="{}" y2="{ly}" stroke="{color}" stroke-width="2"{dash}/>"#,
                    lx + 20.0
                ),
                Style::Points => writeln!(
                    s,
                    r#"<circle cx="{}" cy="{ly}" r="3" fill="{color}"/>"#,
                    lx + 10.0
                ),
                Style::Band { .. } => writeln!(
                    s,
                    r#"<rect x="{lx}" y="{}" width="20" height="10" fill="{color}" fill-opacity="0.2"/>"#,
                    ly - 5.0
                ),
            };
            let _ = writeln!(
                s,
                r#"<text x="{}" y="{}">{}</text>"#,
                lx + 26.0,
                ly + 4.0,
                escape(&series.name)
            );
        }
        s.push_str("</g>\n");
    }
}

/// Whole-number ticks between `lo` and `hi` (axis units; on a log axis, whole decades as
/// usual), at most about ten of them.
fn integer_ticks(lo: f64, hi: f64, log: bool) -> Vec<(f64, String)> {
    if log {
        return (lo.ceil() as i64..=hi.floor() as i64)
            .map(|e| (10f64.powi(e as i32), format!("1e{e}")))
            .collect();
    }
    let step = ((hi - lo) / 10.0).ceil().max(1.0) as i64;
    let first = (lo / step as f64).ceil() as i64;
    let last = (hi / step as f64).floor() as i64;
    (first..=last)
        .map(|k| ((k * step) as f64, (k * step).to_string()))
        .collect()
}

/// The grid lines and tick labels, with `x_ticks` on the horizontal axis.
fn write_grid_and_labels(s: &mut String, plot: &Plot, x_ticks: &[(f64, String)]) {
    let y_ticks = plot.ya.ticks();
    s.push_str("<g class=\"grid\" stroke=\"#dddddd\" stroke-width=\"1\">\n");
    for px in x_ticks.iter().filter_map(|(v, _)| plot.xa.px(*v)) {
        let _ = writeln!(
            s,
            r#"<line x1="{px:.2}" y1="{Y0}" x2="{px:.2}" y2="{Y1}"/>"#
        );
    }
    for py in y_ticks.iter().filter_map(|(v, _)| plot.ya.px(*v)) {
        let _ = writeln!(
            s,
            r#"<line x1="{X0}" y1="{py:.2}" x2="{X1}" y2="{py:.2}"/>"#
        );
    }
    s.push_str("</g>\n<g class=\"tick-labels\" fill=\"#333333\">\n");
    for (v, label) in x_ticks {
        if let Some(px) = plot.xa.px(*v) {
            let _ = writeln!(
                s,
                r#"<text x="{px:.2}" y="{:.2}" text-anchor="middle">{}</text>"#,
                Y1 + 18.0,
                escape(label)
            );
        }
    }
    for (v, label) in &y_ticks {
        if let Some(py) = plot.ya.px(*v) {
            let _ = writeln!(
                s,
                r#"<text x="{:.2}" y="{:.2}" text-anchor="end">{}</text>"#,
                X0 - 6.0,
                py + 4.0,
                escape(label)
            );
        }
    }
    s.push_str("</g>\n");
}

/// The ranges the axes of `chart` are drawn over, `[(x_lo, x_hi), (y_lo, y_hi)]` in data units
/// (powers of ten on a log axis), for checks that a chart shows its data and not much else.
pub fn axis_ranges(chart: &Chart) -> [(f64, f64); 2] {
    let plot = Plot::new(chart);
    let range = |a: &super::Axis| {
        if a.log {
            (10f64.powf(a.lo), 10f64.powf(a.hi))
        } else {
            (a.lo, a.hi)
        }
    };
    [range(&plot.xa), range(&plot.ya)]
}

/// A series' points, for checks: every `(x, y)` of a line, point or band series.
pub fn all_points(series: &Series) -> impl Iterator<Item = (f64, f64)> + '_ {
    let extra: &[(f64, f64)] = match &series.style {
        Style::Band { upper } => upper,
        _ => &[],
    };
    series.points.iter().chain(extra).copied()
}

#[cfg(test)]
mod tests {
    use super::super::render_svg;
    use super::*;

    fn ladder() -> Chart {
        Chart {
            title: "ladder".into(),
            x_label: "step".into(),
            y_label: "rms".into(),
            series: vec![
                Series {
                    name: "x".into(),
                    points: vec![(0.0, 1.0), (1.0, 0.5)],
                    style: Style::Points,
                },
                Series {
                    name: "floor x".into(),
                    points: vec![(0.0, 0.4), (1.0, 0.4)],
                    style: Style::Line,
                },
            ],
            ..Chart::default()
        }
    }

    #[test]
    fn the_default_look_is_render_svg() {
        let c = ladder();
        assert_eq!(Figure::from(c.clone()).to_svg(), render_svg(&c));
    }

    #[test]
    fn integer_ticks_colours_and_dashes() {
        let c = ladder();
        assert!(
            render_svg(&c).contains(">0.2<"),
            "the auto rule ticks at 0.2"
        );
        let f = Figure {
            chart: c,
            look: Look {
                x_ticks: Ticks::Integer,
                series: vec![
                    axis_colour(0),
                    SeriesLook {
                        colour: Some(0),
                        dashed: true,
                    },
                ],
            },
        };
        let svg = f.to_svg();
        assert!(!svg.contains(">0.2<") && svg.contains(">0<") && svg.contains(">1<"));
        assert_eq!(
            svg.matches(PALETTE[0]).count(),
            4,
            "both series and legends blue"
        );
        assert!(!svg.contains(PALETTE[1]));
        assert_eq!(svg.matches("stroke-dasharray").count(), 2, "{svg}");
    }
}
