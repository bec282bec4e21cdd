//! Small multiples: a figure of panels side by side that share both axes' ranges (so the
//! panels compare at a glance), each series in a colour the caller chooses (so one quantity has
//! one colour in every figure) and a legend of free text lines under each panel (room for
//! fitted values with their units). Built on the axes and escaping of [`super::svg`]; the same
//! no-fonts SVG.
//!
//! The axes span what the series marked `sets_range` hold plus a small margin; other series
//! (model lines) are clipped to that. Every panel's `<g class="panel">` carries its axis ranges
//! in data units (`data-x-lo`, `data-x-hi`, `data-y-lo`, `data-y-hi`), so a test can check them.

use std::fmt::Write as _;

use super::svg::{Axis, Style, escape, log_ticks};

/// A figure: a title over panels laid out left to right.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Figure {
    /// Title above the panels.
    pub title: String,
    /// Horizontal axis label under each panel (with the unit).
    pub x_label: String,
    /// Vertical axis label, left of the first panel (with the unit).
    pub y_label: String,
    /// Logarithmic horizontal axis (non-positive x skipped).
    pub log_x: bool,
    /// Logarithmic vertical axis (non-positive y skipped).
    pub log_y: bool,
    /// The panels, left to right.
    pub panels: Vec<Panel>,
}

/// One panel: a small title, its layers and legend lines.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Panel {
    /// Title above the panel (e.g. the axis name).
    pub title: String,
    /// Drawn in order, later on top.
    pub layers: Vec<Layer>,
    /// Legend lines under the panel, each with a swatch of a layer's style, or plain text.
    pub legend: Vec<LegendLine>,
}

/// One series of a panel.
#[derive(Debug, Clone, PartialEq)]
pub struct Layer {
    /// The series' name (its `data-name`).
    pub name: String,
    /// CSS colour.
    pub color: &'static str,
    /// `(x, y)` in data units; for [`Style::Line`] a non-finite y breaks the line.
    pub points: Vec<(f64, f64)>,
    /// How it is drawn.
    pub style: Style,
    /// Whether the axes' ranges are fitted to this series (data: yes; model lines: no).
    pub sets_range: bool,
}

/// One line of a panel's legend.
#[derive(Debug, Clone, PartialEq)]
pub struct LegendLine {
    /// A swatch drawn like this style in this colour, or none (plain text, grey).
    pub swatch: Option<(Style, &'static str)>,
    /// The text.
    pub text: String,
}

/// Legend text size, px (the estimate of its width is what the layout is made for).
pub const LEGEND_FONT_PX: f64 = 11.0;
const PANEL_W: f64 = 300.0;
const PLOT_H: f64 = 280.0;
const GAP: f64 = 24.0;
const LEFT: f64 = 84.0;
const RIGHT: f64 = 16.0;
const PLOT_TOP: f64 = 66.0;
const LEGEND_ROW: f64 = 17.0;
/// From the plot's bottom edge to the first legend row's baseline.
const LEGEND_TOP: f64 = 62.0;

/// The figure's size in px: width, height.
pub fn figure_size(fig: &Figure) -> (f64, f64) {
    let n = fig.panels.len().max(1) as f64;
    let rows = fig.panels.iter().map(|p| p.legend.len()).max().unwrap_or(0) as f64;
    (
        LEFT + n * PANEL_W + (n - 1.0) * GAP + RIGHT,
        PLOT_TOP + PLOT_H + LEGEND_TOP + rows * LEGEND_ROW,
    )
}

/// Renders the figure as a standalone SVG document.
pub fn render_figure(fig: &Figure) -> String {
    let (w, h) = figure_size(fig);
    let ranged = |x: bool| {
        fig.panels
            .iter()
            .flat_map(|p| p.layers.iter().filter(|l| l.sets_range))
            .flat_map(|l| {
                let upper: &[(f64, f64)] = match &l.style {
                    Style::Band { upper } => upper,
                    _ => &[],
                };
                l.points
                    .iter()
                    .chain(upper)
                    .map(move |p| if x { p.0 } else { p.1 })
            })
            .collect::<Vec<f64>>()
    };
    let (xs, ys) = (ranged(true), ranged(false));
    let id = slug(&fig.title);
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, "<title>{}</title>", escape(&fig.title));
    let _ = writeln!(
        s,
        r#"<rect x="0" y="0" width="{w}" height="{h}" fill="white"/>"#
    );
    let _ = writeln!(
        s,
        r#"<text x="{:.2}" y="26" text-anchor="middle" font-size="16">{}</text>"#,
        w / 2.0,
        escape(&fig.title)
    );
    let mid_y = PLOT_TOP + PLOT_H / 2.0;
    let _ = writeln!(
        s,
        r#"<text x="18" y="{mid_y:.2}" text-anchor="middle" transform="rotate(-90 18 {mid_y:.2})">{}</text>"#,
        escape(&fig.y_label)
    );
    for (i, panel) in fig.panels.iter().enumerate() {
        let x0 = LEFT + i as f64 * (PANEL_W + GAP);
        let frame = Frame {
            x0,
            xa: Axis::new(xs.iter().copied(), fig.log_x, x0, x0 + PANEL_W),
            ya: Axis::new(ys.iter().copied(), fig.log_y, PLOT_TOP + PLOT_H, PLOT_TOP),
        };
        frame.write_panel(&mut s, fig, panel, &format!("{id}-{i}"), i == 0);
    }
    s.push_str("</svg>\n");
    s
}

/// One panel's place and axes.
struct Frame {
    x0: f64,
    xa: Axis,
    ya: Axis,
}

impl Frame {
    fn write_panel(&self, s: &mut String, fig: &Figure, panel: &Panel, id: &str, first: bool) {
        let ((xlo, xhi), (ylo, yhi)) = (self.xa.range(), self.ya.range());
        let _ = writeln!(
            s,
            r#"<g class="panel" data-x-lo="{xlo:e}" data-x-hi="{xhi:e}" data-y-lo="{ylo:e}" data-y-hi="{yhi:e}">"#
        );
        self.write_grid_and_ticks(s, fig, first);
        let (x0, y0) = (self.x0, PLOT_TOP);
        let _ = writeln!(
            s,
            r#"<clipPath id="{id}"><rect x="{x0}" y="{y0}" width="{PANEL_W}" height="{PLOT_H}"/></clipPath>"#
        );
        let _ = writeln!(s, r#"<g clip-path="url(#{id})">"#);
        for layer in &panel.layers {
            self.write_layer(s, layer);
        }
        s.push_str("</g>\n");
        let _ = writeln!(
            s,
            r##"<rect x="{x0}" y="{y0}" width="{PANEL_W}" height="{PLOT_H}" fill="none" stroke="#000000"/>"##
        );
        let cx = x0 + PANEL_W / 2.0;
        let _ = writeln!(
            s,
            r#"<text x="{cx:.2}" y="{:.2}" text-anchor="middle" font-size="13" font-weight="bold">{}</text>"#,
            y0 - 8.0,
            escape(&panel.title)
        );
        let _ = writeln!(
            s,
            r#"<text x="{cx:.2}" y="{:.2}" text-anchor="middle">{}</text>"#,
            y0 + PLOT_H + 38.0,
            escape(&fig.x_label)
        );
        write_legend(s, x0, y0 + PLOT_H + LEGEND_TOP, &panel.legend);
        s.push_str("</g>\n");
    }

    /// Grid lines of both axes; x tick labels under every panel, y tick labels left of the
    /// first only (the range is shared).
    fn write_grid_and_ticks(&self, s: &mut String, fig: &Figure, first: bool) {
        let (x0, x1, y0, y1) = (self.x0, self.x0 + PANEL_W, PLOT_TOP, PLOT_TOP + PLOT_H);
        let (xt, yt) = (
            self.ticks(&self.xa, fig.log_x),
            self.ticks(&self.ya, fig.log_y),
        );
        s.push_str("<g class=\"grid\" stroke=\"#dddddd\" stroke-width=\"1\">\n");
        for px in xt.iter().filter_map(|(v, _)| self.xa.px(*v)) {
            let _ = writeln!(
                s,
                r#"<line x1="{px:.2}" y1="{y0}" x2="{px:.2}" y2="{y1}"/>"#
            );
        }
        for py in yt.iter().filter_map(|(v, _)| self.ya.px(*v)) {
            let _ = writeln!(
                s,
                r#"<line x1="{x0}" y1="{py:.2}" x2="{x1}" y2="{py:.2}"/>"#
            );
        }
        s.push_str("</g>\n<g class=\"tick-labels\" fill=\"#333333\">\n");
        for (v, label) in &xt {
            if let Some(px) = self.xa.px(*v) {
                let _ = writeln!(
                    s,
                    r#"<text x="{px:.2}" y="{:.2}" text-anchor="middle">{}</text>"#,
                    y1 + 16.0,
                    escape(label)
                );
            }
        }
        for (v, label) in yt.iter().filter(|_| first) {
            if let Some(py) = self.ya.px(*v) {
                let _ = writeln!(
                    s,
                    r#"<text x="{:.2}" y="{:.2}" text-anchor="end">{}</text>"#,
                    x0 - 6.0,
                    py + 4.0,
                    escape(label)
                );
            }
        }
        s.push_str("</g>\n");
    }

    /// The axis' ticks, thinned so that labels do not overlap on a narrow panel.
    fn ticks(&self, axis: &Axis, log: bool) -> Vec<(f64, String)> {
        let mut t = axis.ticks();
        if log && t.len() > 8 {
            let (lo, hi) = axis.range();
            t = log_ticks(lo.log10(), hi.log10())
                .into_iter()
                .filter(|(v, _)| (v.log10().round() - v.log10()).abs() < 1e-9)
                .collect();
            let step = t.len().div_ceil(6).max(1);
            t = t.into_iter().step_by(step).collect();
        }
        t
    }

    fn write_layer(&self, s: &mut String, layer: &Layer) {
        let to_px = |&(x, y): &(f64, f64)| Some((self.xa.px(x)?, self.ya.px(y)?));
        let (name, color) = (escape(&layer.name), layer.color);
        match &layer.style {
            Style::Line => {
                let d = broken_path(layer.points.iter().map(to_px));
                let _ = writeln!(
                    s,
                    r#"<path class="series" data-name="{name}" d="{d}" fill="none" stroke="{color}" stroke-width="1.8"/>"#
                );
            }
            Style::Points => {
                let _ = writeln!(s, r#"<g class="series" data-name="{name}" fill="{color}">"#);
                for (px, py) in layer.points.iter().filter_map(to_px) {
                    let _ = writeln!(s, r#"<circle cx="{px:.2}" cy="{py:.2}" r="2.6"/>"#);
                }
                s.push_str("</g>\n");
            }
            Style::Band { upper } => {
                let lower = layer.points.iter().filter_map(to_px);
                let mut d =
                    broken_path(lower.chain(upper.iter().rev().filter_map(to_px)).map(Some));
                if !d.is_empty() {
                    d.push_str(" Z");
                }
                let _ = writeln!(
                    s,
                    r#"<path class="series" data-name="{name}" d="{d}" fill="{color}" fill-opacity="0.22" stroke="none"/>"#
                );
            }
        }
    }
}

/// Path data through the points; a `None` ends the current piece.
fn broken_path(points: impl Iterator<Item = Option<(f64, f64)>>) -> String {
    let mut d = String::new();
    let mut pen_down = false;
    for p in points {
        match p {
            Some((x, y)) => {
                let sep = if d.is_empty() { "" } else { " " };
                let cmd = if pen_down { "L" } else { "M" };
                let _ = write!(d, "{sep}{cmd}{x:.2},{y:.2}");
                pen_down = true;
            }
            None => pen_down = false,
        }
    }
    d
}

fn write_legend(s: &mut String, x0: f64, top: f64, lines: &[LegendLine]) {
    s.push_str("<g class=\"legend\">\n");
    for (i, line) in lines.iter().enumerate() {
        let y = top + i as f64 * LEGEND_ROW;
        let mid = y - 4.0;
        match &line.swatch {
            Some((Style::Line, color)) => {
                let _ = writeln!(
                    s,
                    r#"<line x1="{x0}" y1="{mid}" x2="{}" y2="{mid}" stroke="{color}" stroke-width="2"/>"#,
                    x0 + 18.0
                );
            }
            Some((Style::Points, color)) => {
                let _ = writeln!(
                    s,
                    r#"<circle cx="{}" cy="{mid}" r="3" fill="{color}"/>"#,
                    x0 + 9.0
                );
            }
            Some((Style::Band { .. }, color)) => {
                let _ = writeln!(
                    s,
                    r#"<rect x="{x0}" y="{}" width="18" height="9" fill="{color}" fill-opacity="0.3"/>"#,
                    mid - 4.5
                );
            }
            None => {}
        }
        let fill = if line.swatch.is_some() {
            "#000000"
        } else {
            "#555555"
        };
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{y}" font-size="{LEGEND_FONT_PX}" fill="{fill}">{}</text>"#,
            x0 + 24.0,
            escape(&line.text)
        );
    }
    s.push_str("</g>\n");
}

/// An id-safe form of `title`, so that several figures' clip paths on one page differ.
fn slug(title: &str) -> String {
    let s: String = title
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() {
                c.to_ascii_lowercase()
            } else {
                '-'
            }
        })
        .collect();
    format!("fig-{}", s.trim_matches('-'))
}
