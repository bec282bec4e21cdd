//! A small, dependency-free SVG chart writer (lines, points, shaded bands; linear or log axes).
//!
//! Hand-rolled rather than built on plotters: plotters draws text through a font backend (system
//! fonts or `ab_glyph` with an embedded font file), and the house rule is "SVG, no system fonts".
//! Writing the `<text>` elements ourselves lets the viewer pick its own generic `sans-serif` font,
//! keeps the output deterministic (tests compare it) and costs about 300 lines.
//!
//! ```
//! use imu_analysis::render::svg::{Chart, Series, Style, render_svg};
//! let chart = Chart {
//!     title: "ADEV".into(),
//!     x_label: "tau [s]".into(),
//!     y_label: "sigma [rad/s]".into(),
//!     log_x: true,
//!     log_y: true,
//!     series: vec![Series {
//!         name: "gyro x".into(),
//!         points: vec![(0.01, 1e-3), (1.0, 1e-4), (100.0, 2e-5)],
//!         style: Style::Line,
//!     }],
//! };
//! let svg = render_svg(&chart);
//! assert!(svg.starts_with("<svg"));
//! ```

use std::fmt::Write as _;
use std::io;
use std::path::Path;

mod look;
pub use look::{Figure, Look, SeriesLook, Ticks, all_points, axis_colour, axis_ranges};

/// A chart: axes with labels, optional logarithmic scales, and the series drawn on them.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Chart {
    /// Title drawn above the plot area.
    pub title: String,
    /// Label of the horizontal axis (put the unit in it, e.g. "tau [s]").
    pub x_label: String,
    /// Label of the vertical axis (put the unit in it).
    pub y_label: String,
    /// Logarithmic (base 10) horizontal axis; non-positive x values are skipped.
    pub log_x: bool,
    /// Logarithmic (base 10) vertical axis; non-positive y values are skipped.
    pub log_y: bool,
    /// The data, drawn in order (later series on top), each with an entry in the legend.
    pub series: Vec<Series>,
}

/// One named data series.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend text.
    pub name: String,
    /// Data points `(x, y)` in axis units; for [`Style::Band`] the lower edge of the band.
    pub points: Vec<(f64, f64)>,
    /// How the points are drawn.
    pub style: Style,
}

/// How a [`Series`] is drawn.
#[derive(Debug, Clone, PartialEq)]
pub enum Style {
    /// A polyline through the points in the given order.
    Line,
    /// A marker at each point.
    Points,
    /// A shaded area between `points` (the lower edge) and `upper` (the upper edge), e.g. a
    /// confidence interval.
    Band {
        /// Upper edge of the band, `(x, y)` in axis units.
        upper: Vec<(f64, f64)>,
    },
}

const WIDTH: f64 = 800.0;
const HEIGHT: f64 = 560.0;
const LEFT: f64 = 90.0;
const RIGHT: f64 = 200.0;
const TOP: f64 = 50.0;
const BOTTOM: f64 = 70.0;
const PALETTE: [&str; 8] = [
    "#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf",
];

/// One axis: maps data values to pixels.
pub(crate) struct Axis {
    log: bool,
    lo: f64,
    hi: f64,
    px_lo: f64,
    px_hi: f64,
}

impl Axis {
    pub(crate) fn new(
        values: impl Iterator<Item = f64>,
        log: bool,
        px_lo: f64,
        px_hi: f64,
    ) -> Self {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for v in values {
            if let Some(t) = transform(v, log) {
                lo = lo.min(t);
                hi = hi.max(t);
            }
        }
        if !lo.is_finite() || !hi.is_finite() {
            (lo, hi) = (0.0, 1.0);
        }
        if hi - lo < 1e-12 * (1.0 + lo.abs()) {
            let pad = if log { 0.5 } else { 0.5 * lo.abs().max(1.0) };
            lo -= pad;
            hi += pad;
        }
        if log {
            // The data's range plus a small margin: no empty decade beyond the data.
            let pad = (LOG_MARGIN * (hi - lo)).max(MIN_LOG_MARGIN);
            lo -= pad;
            hi += pad;
        } else {
            let pad = 0.05 * (hi - lo);
            lo -= pad;
            hi += pad;
        }
        Axis {
            log,
            lo,
            hi,
            px_lo,
            px_hi,
        }
    }

    /// The axis' range in data units (what the edges of the plot area stand for).
    pub(crate) fn range(&self) -> (f64, f64) {
        if self.log {
            (10f64.powf(self.lo), 10f64.powf(self.hi))
        } else {
            (self.lo, self.hi)
        }
    }

    /// Pixel coordinate of a data value, or `None` if it cannot be drawn (e.g. <= 0 on a log axis).
    pub(crate) fn px(&self, v: f64) -> Option<f64> {
        let t = transform(v, self.log)?;
        Some(self.px_lo + (t - self.lo) / (self.hi - self.lo) * (self.px_hi - self.px_lo))
    }

    /// Tick positions (data units) and their labels.
    pub(crate) fn ticks(&self) -> Vec<(f64, String)> {
        if self.log {
            log_ticks(self.lo, self.hi)
        } else {
            let step = nice_step((self.hi - self.lo) / 6.0);
            let first = (self.lo / step).ceil() as i64;
            let last = (self.hi / step).floor() as i64;
            (first..=last)
                .map(|i| {
                    let v = i as f64 * step;
                    (v, format_number(v))
                })
                .collect()
        }
    }
}

/// Margin of a logarithmic axis beyond the data, as a share of the data's range in decades...
const LOG_MARGIN: f64 = 0.03;
/// ... and at least this many decades.
const MIN_LOG_MARGIN: f64 = 0.02;

/// Ticks of a log axis spanning `lo..=hi` decades (log10 of the data units), labelled `1e-3`,
/// `2e-3`: the decades inside the range (at most about ten, thinned evenly), and when fewer than
/// three decades fall inside, the 2 and 5 multiples too, or every multiple for a range under
/// about half a decade, so a narrow axis still has at least two labelled ticks.
pub(crate) fn log_ticks(lo: f64, hi: f64) -> Vec<(f64, String)> {
    if !(lo.is_finite() && hi.is_finite() && lo < hi) {
        return Vec::new();
    }
    let (first, last) = (lo.ceil() as i32, hi.floor() as i32);
    let decades = (last - first + 1).max(0);
    if decades >= 3 {
        let step = ((decades as f64 - 1.0) / 10.0).ceil().max(1.0) as usize;
        return (first..=last)
            .step_by(step)
            .map(|e| (10f64.powi(e), format!("1e{e}")))
            .collect();
    }
    for mantissas in [&[1u32, 2, 5][..], &[1, 2, 3, 4, 5, 6, 7, 8, 9]] {
        let ticks: Vec<(f64, String)> = (lo.floor() as i32..=hi.ceil() as i32)
            .flat_map(|e| mantissas.iter().map(move |&m| (m, e)))
            .filter_map(|(m, e)| {
                let v = f64::from(m) * 10f64.powi(e);
                (lo..=hi)
                    .contains(&v.log10())
                    .then(|| (v, format!("{m}e{e}")))
            })
            .collect();
        if ticks.len() >= 3 || mantissas.len() == 9 {
            return ticks;
        }
    }
    Vec::new()
}

fn transform(v: f64, log: bool) -> Option<f64> {
    if !v.is_finite() {
        return None;
    }
    if log {
        (v > 0.0).then(|| v.log10())
    } else {
        Some(v)
    }
}

fn nice_step(raw: f64) -> f64 {
    let mag = 10f64.powf(raw.log10().floor());
    let f = raw / mag;
    let nice = if f <= 1.0 {
        1.0
    } else if f <= 2.0 {
        2.0
    } else if f <= 5.0 {
        5.0
    } else {
        10.0
    };
    nice * mag
}

fn format_number(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        format!("{v:.1e}")
    } else {
        let s = format!("{v:.6}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

/// Escapes text for use in SVG element content and attribute values.
pub(crate) fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c if (c as u32) < 0x20 && c != '\t' && c != '\n' => {}
            c => out.push(c),
        }
    }
    out
}

fn path_data(points: impl Iterator<Item = (f64, f64)>) -> String {
    let mut d = String::new();
    for (i, (x, y)) in points.enumerate() {
        let _ = write!(d, "{}{x:.2},{y:.2}", if i == 0 { "M" } else { " L" });
    }
    d
}

/// Renders the chart as a standalone SVG document (UTF-8 text, 800 x 560 px, no fonts embedded:
/// text uses the viewer's generic `sans-serif`).
pub fn render_svg(chart: &Chart) -> String {
    let plot = Plot::new(chart);
    let mut s = String::new();
    write_header(&mut s, chart);
    plot.write_grid(&mut s);
    plot.write_tick_labels(&mut s);
    plot.write_series(&mut s, chart);
    write_frame_and_labels(&mut s, chart);
    write_legend(&mut s, chart);
    s.push_str("</svg>\n");
    s
}

/// The plot area's edges in pixels: left, right, top, bottom.
const X0: f64 = LEFT;
const X1: f64 = WIDTH - RIGHT;
const Y0: f64 = TOP;
const Y1: f64 = HEIGHT - BOTTOM;

/// The two axes of one chart, fitted to every point it draws.
struct Plot {
    xa: Axis,
    ya: Axis,
}

impl Plot {
    fn new(chart: &Chart) -> Self {
        let all_points = || {
            chart.series.iter().flat_map(|s| {
                let extra: &[(f64, f64)] = match &s.style {
                    Style::Band { upper } => upper,
                    _ => &[],
                };
                s.points.iter().chain(extra.iter()).copied()
            })
        };
        let xa = Axis::new(all_points().map(|p| p.0), chart.log_x, LEFT, WIDTH - RIGHT);
        let ya = Axis::new(all_points().map(|p| p.1), chart.log_y, HEIGHT - BOTTOM, TOP);
        Plot { xa, ya }
    }

    /// Pixel coordinates of a data point, or `None` if either coordinate cannot be drawn.
    fn to_px(&self, &(x, y): &(f64, f64)) -> Option<(f64, f64)> {
        Some((self.xa.px(x)?, self.ya.px(y)?))
    }

    fn write_grid(&self, s: &mut String) {
        s.push_str("<g class=\"grid\" stroke=\"#dddddd\" stroke-width=\"1\">\n");
        for (v, _) in &self.xa.ticks() {
            if let Some(px) = self.xa.px(*v) {
                let _ = writeln!(
                    s,
                    r#"<line x1="{px:.2}" y1="{Y0}" x2="{px:.2}" y2="{Y1}"/>"#
                );
            }
        }
        for (v, _) in &self.ya.ticks() {
            if let Some(py) = self.ya.px(*v) {
                let _ = writeln!(
                    s,
                    r#"<line x1="{X0}" y1="{py:.2}" x2="{X1}" y2="{py:.2}"/>"#
                );
            }
        }
        s.push_str("</g>\n");
    }

    fn write_tick_labels(&self, s: &mut String) {
        s.push_str("<g class=\"tick-labels\" fill=\"#333333\">\n");
        for (v, label) in &self.xa.ticks() {
            if let Some(px) = self.xa.px(*v) {
                let _ = writeln!(
                    s,
                    r#"<text x="{px:.2}" y="{:.2}" text-anchor="middle">{}</text>"#,
                    Y1 + 18.0,
                    escape(label)
                );
            }
        }
        for (v, label) in &self.ya.ticks() {
            if let Some(py) = self.ya.px(*v) {
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

    /// Every series, clipped to the plot area.
    fn write_series(&self, s: &mut String, chart: &Chart) {
        let _ = writeln!(
            s,
            r#"<clipPath id="plot-area"><rect x="{X0}" y="{Y0}" width="{}" height="{}"/></clipPath>"#,
            X1 - X0,
            Y1 - Y0
        );
        s.push_str("<g clip-path=\"url(#plot-area)\">\n");
        for (i, series) in chart.series.iter().enumerate() {
            self.write_one_series(s, series, PALETTE[i % PALETTE.len()]);
        }
        s.push_str("</g>\n");
    }

    fn write_one_series(&self, s: &mut String, series: &Series, color: &str) {
        let to_px = |p: &(f64, f64)| self.to_px(p);
        let name = escape(&series.name);
        match &series.style {
            Style::Line => {
                let d = path_data(series.points.iter().filter_map(to_px));
                let _ = writeln!(
                    s,
                    r#"<path class="series" data-name="{name}" d="{d}" fill="none" stroke="{color}" stroke-width="1.8"/>"#
                );
            }
            Style::Points => {
                let _ = writeln!(s, r#"<g class="series" data-name="{name}" fill="{color}">"#);
                for (px, py) in series.points.iter().filter_map(to_px) {
                    let _ = writeln!(s, r#"<circle cx="{px:.2}" cy="{py:.2}" r="3"/>"#);
                }
                s.push_str("</g>\n");
            }
            Style::Band { upper } => {
                let lower = series.points.iter().filter_map(to_px);
                let upper_rev = upper.iter().rev().filter_map(to_px);
                let mut d = path_data(lower.chain(upper_rev));
                if !d.is_empty() {
                    d.push_str(" Z");
                }
                let _ = writeln!(
                    s,
                    r#"<path class="series" data-name="{name}" d="{d}" fill="{color}" fill-opacity="0.2" stroke="none"/>"#
                );
            }
        }
    }
}

fn write_header(s: &mut String, chart: &Chart) {
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{HEIGHT}" viewBox="0 0 {WIDTH} {HEIGHT}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<title>{}</title>"#, escape(&chart.title));
    let _ = writeln!(
        s,
        r#"<rect x="0" y="0" width="{WIDTH}" height="{HEIGHT}" fill="white"/>"#
    );
}

/// The plot area's frame, the title and the axis labels.
fn write_frame_and_labels(s: &mut String, chart: &Chart) {
    let _ = writeln!(
        s,
        r##"<rect x="{X0}" y="{Y0}" width="{}" height="{}" fill="none" stroke="#000000"/>"##,
        X1 - X0,
        Y1 - Y0
    );
    let _ = writeln!(
        s,
        r#"<text x="{:.2}" y="28" text-anchor="middle" font-size="16">{}</text>"#,
        (X0 + X1) / 2.0,
        escape(&chart.title)
    );
    let _ = writeln!(
        s,
        r#"<text x="{:.2}" y="{:.2}" text-anchor="middle">{}</text>"#,
        (X0 + X1) / 2.0,
        HEIGHT - 25.0,
        escape(&chart.x_label)
    );
    let _ = writeln!(
        s,
        r#"<text x="20" y="{:.2}" text-anchor="middle" transform="rotate(-90 20 {:.2})">{}</text>"#,
        (Y0 + Y1) / 2.0,
        (Y0 + Y1) / 2.0,
        escape(&chart.y_label)
    );
}

fn write_legend(s: &mut String, chart: &Chart) {
    s.push_str("<g class=\"legend\">\n");
    for (i, series) in chart.series.iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
        let ly = Y0 + 10.0 + 20.0 * i as f64;
        let lx = X1 + 12.0;
        match series.style {
            Style::Line => {
                let _ = writeln!(
                    s,
                    r#"<line x1="{lx}" y1="{ly}" x2="{}" y2="{ly}" stroke="{color}" stroke-width="2"/>"#,
                    lx + 20.0
                );
            }
            Style::Points => {
                let _ = writeln!(
                    s,
                    r#"<circle cx="{}" cy="{ly}" r="3" fill="{color}"/>"#,
                    lx + 10.0
                );
            }
            Style::Band { .. } => {
                let _ = writeln!(
                    s,
                    r#"<rect x="{lx}" y="{}" width="20" height="10" fill="{color}" fill-opacity="0.2"/>"#,
                    ly - 5.0
                );
            }
        }
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

/// Renders the chart (see [`render_svg`]) and writes it to `path`.
pub fn write_svg(chart: &Chart, path: impl AsRef<Path>) -> io::Result<()> {
    std::fs::write(path, render_svg(chart))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Minimal XML well-formedness check: every tag is closed in order, attributes are quoted,
    /// and there is exactly one root element.
    fn check_well_formed(doc: &str) {
        let mut stack: Vec<String> = Vec::new();
        let mut rest = doc;
        let mut roots = 0;
        while let Some(start) = rest.find('<') {
            let text = &rest[..start];
            assert!(!text.contains('>'), "stray '>' in text: {text:?}");
            if stack.is_empty() {
                assert!(text.trim().is_empty(), "text outside root: {text:?}");
            }
            let end = rest[start..].find('>').expect("unterminated tag") + start;
            let tag = &rest[start + 1..end];
            assert!(!tag.contains('<'), "'<' inside tag {tag:?}");
            assert_eq!(
                tag.matches('"').count() % 2,
                0,
                "unbalanced quotes in {tag:?}"
            );
            if let Some(name) = tag.strip_prefix('/') {
                let open = stack.pop().expect("close without open");
                assert_eq!(open, name.trim());
            } else {
                let name = tag.split_whitespace().next().unwrap().trim_end_matches('/');
                if stack.is_empty() {
                    roots += 1;
                }
                if !tag.ends_with('/') {
                    stack.push(name.to_string());
                }
            }
            rest = &rest[end + 1..];
        }
        assert!(stack.is_empty(), "unclosed: {stack:?}");
        assert!(rest.trim().is_empty());
        assert_eq!(roots, 1);
        for (i, _) in doc.match_indices('&') {
            let ent = &doc[i..doc[i..].find(';').unwrap() + i + 1];
            assert!(
                ["&amp;", "&lt;", "&gt;", "&quot;", "&apos;"].contains(&ent),
                "bad entity {ent}"
            );
        }
    }

    fn chart() -> Chart {
        Chart {
            title: "Allan <deviation> & friends".into(),
            x_label: "tau [s]".into(),
            y_label: "sigma [rad/s]".into(),
            log_x: true,
            log_y: true,
            series: vec![
                Series {
                    name: "band \"95%\"".into(),
                    points: vec![(0.01, 0.9e-3), (1.0, 0.9e-4), (100.0, 1e-5)],
                    style: Style::Band {
                        upper: vec![(0.01, 1.1e-3), (1.0, 1.1e-4), (100.0, 3e-5)],
                    },
                },
                Series {
                    name: "gyro x".into(),
                    points: vec![(0.01, 1e-3), (1.0, 1e-4), (100.0, 2e-5), (-1.0, 5.0)],
                    style: Style::Line,
                },
                Series {
                    name: "fit N".into(),
                    points: vec![(0.01, 1e-3), (1.0, 1e-4)],
                    style: Style::Points,
                },
            ],
        }
    }

    #[test]
    fn svg_is_well_formed_and_contains_every_series() {
        let svg = render_svg(&chart());
        check_well_formed(&svg);
        assert!(svg.contains("Allan &lt;deviation&gt; &amp; friends"));
        assert!(svg.contains(r#"data-name="gyro x""#));
        assert!(svg.contains(r#"data-name="band &quot;95%&quot;""#));
        assert!(svg.contains(r#"data-name="fit N""#));
        assert_eq!(
            svg.matches("<circle").count(),
            2 + 1,
            "2 points + legend marker"
        );
        assert!(
            svg.contains(">1e-2<") && svg.contains(">1e2<"),
            "decade ticks"
        );
        assert!(svg.contains(">tau [s]<"));
        assert!(!svg.contains("NaN") && !svg.contains("inf"));
    }

    #[test]
    fn linear_and_degenerate_charts_render() {
        let mut c = chart();
        c.log_x = false;
        c.log_y = false;
        check_well_formed(&render_svg(&c));
        let empty = Chart::default();
        let svg = render_svg(&empty);
        check_well_formed(&svg);
        assert!(!svg.contains("NaN"));
        let single = Chart {
            series: vec![Series {
                name: "one".into(),
                points: vec![(1.0, 1.0)],
                style: Style::Line,
            }],
            log_y: true,
            ..Chart::default()
        };
        let svg = render_svg(&single);
        check_well_formed(&svg);
        assert!(!svg.contains("NaN"));
    }

    #[test]
    fn log_ticks_label_every_range() {
        let labels = |lo: f64, hi: f64| -> Vec<String> {
            log_ticks(lo, hi).into_iter().map(|t| t.1).collect()
        };
        assert_eq!(labels(-2.1, 2.1), ["1e-2", "1e-1", "1e0", "1e1", "1e2"]);
        assert_eq!(labels(-3.35, -2.2), ["5e-4", "1e-3", "2e-3", "5e-3"]);
        assert_eq!(
            labels(-3.25, -2.95),
            ["6e-4", "7e-4", "8e-4", "9e-4", "1e-3"]
        );
        assert!(labels(-30.0, 30.0).len() <= 11);
        assert!(labels(1.0, 1.0).is_empty());
        // The axis ends where the data do, plus the margin: no empty decade.
        let a = Axis::new([2e-3, 5e-1].into_iter(), true, 0.0, 100.0);
        let (lo, hi) = a.range();
        assert!(
            lo < 2e-3 && lo > 1.5e-3 && hi > 0.5 && hi < 0.65,
            "{lo} {hi}"
        );
    }

    #[test]
    fn write_svg_writes_the_rendered_text() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("c.svg");
        write_svg(&chart(), &p).unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), render_svg(&chart()));
    }
}
