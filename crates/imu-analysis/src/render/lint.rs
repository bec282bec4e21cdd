//! Mechanical checks of a rendered SVG (ours: one root, quoted attributes, no CDATA), for the
//! tests of every page that draws: every number is finite, every text lies inside the view box
//! (its width estimated from the font size and the number of characters), no two texts overlap,
//! and the axis ranges a [`super::figure`] panel declares can be read back.
//!
//! A text's box: `0.6 x font size` per character wide (generous for a sans-serif), from
//! `0.8 x size` above the baseline to `0.25 x size` below, placed by `text-anchor`, turned by a
//! `rotate(a cx cy)` transform. The font size is the text's own or the nearest enclosing one.

/// Width of one character as a share of the font size (an upper estimate for sans-serif).
pub const CHAR_WIDTH_EM: f64 = 0.6;

/// One start, end or empty tag, with its attributes, and the text that follows it.
struct Tag<'a> {
    name: &'a str,
    attrs: Vec<(&'a str, &'a str)>,
    closing: bool,
    empty: bool,
    text_after: &'a str,
}

impl Tag<'_> {
    fn attr(&self, key: &str) -> Option<&str> {
        self.attrs.iter().find(|(k, _)| *k == key).map(|(_, v)| *v)
    }
}

fn tags(svg: &str) -> Vec<Tag<'_>> {
    let mut out = Vec::new();
    let mut rest = svg;
    while let Some(start) = rest.find('<') {
        let Some(len) = rest[start..].find('>') else {
            break;
        };
        let inner = &rest[start + 1..start + len];
        rest = &rest[start + len + 1..];
        let text_after = &rest[..rest.find('<').unwrap_or(rest.len())];
        let closing = inner.starts_with('/');
        let empty = inner.ends_with('/');
        let body = inner.trim_start_matches('/').trim_end_matches('/');
        let name = body.split_whitespace().next().unwrap_or("");
        out.push(Tag {
            name,
            attrs: attributes(&body[name.len()..]),
            closing,
            empty,
            text_after,
        });
    }
    out
}

fn attributes(mut s: &str) -> Vec<(&str, &str)> {
    let mut out = Vec::new();
    while let Some(eq) = s.find("=\"") {
        let key = s[..eq].trim();
        let Some(end) = s[eq + 2..].find('"') else {
            break;
        };
        out.push((key, &s[eq + 2..eq + 2 + end]));
        s = &s[eq + 3 + end..];
    }
    out
}

/// The number of characters `text` shows (entities count as one).
fn shown_chars(text: &str) -> usize {
    let mut n = 0;
    let mut in_entity = false;
    for c in text.chars() {
        match c {
            '&' => {
                in_entity = true;
                n += 1;
            }
            ';' if in_entity => in_entity = false,
            _ if in_entity => {}
            _ => n += 1,
        }
    }
    n
}

/// An axis-aligned box: x0, y0, x1, y1.
type Bbox = [f64; 4];

/// Every text's estimated box with its text.
fn text_boxes(svg: &str) -> Result<Vec<(Bbox, String)>, String> {
    let mut sizes: Vec<f64> = Vec::new();
    let mut out = Vec::new();
    for t in tags(svg) {
        if t.closing {
            if t.name != "text" {
                sizes.pop();
            }
            continue;
        }
        let inherited = sizes.last().copied().unwrap_or(16.0);
        let size = match t.attr("font-size") {
            Some(v) => v
                .parse::<f64>()
                .map_err(|_| format!("font-size {v:?} of <{}>", t.name))?,
            None => inherited,
        };
        if t.name == "text" {
            out.push((text_box(&t, size)?, t.text_after.to_string()));
        } else if !t.empty {
            sizes.push(size);
        }
    }
    Ok(out)
}

fn num(t: &Tag, key: &str) -> Result<f64, String> {
    let v = t.attr(key).unwrap_or("0");
    v.parse::<f64>()
        .map_err(|_| format!("{key}={v:?} of <{}> is not a number", t.name))
}

fn text_box(t: &Tag, size: f64) -> Result<Bbox, String> {
    let (x, y) = (num(t, "x")?, num(t, "y")?);
    let w = shown_chars(t.text_after) as f64 * CHAR_WIDTH_EM * size;
    let x0 = match t.attr("text-anchor") {
        Some("middle") => x - w / 2.0,
        Some("end") => x - w,
        _ => x,
    };
    let corners = [
        (x0, y - 0.8 * size),
        (x0 + w, y - 0.8 * size),
        (x0, y + 0.25 * size),
        (x0 + w, y + 0.25 * size),
    ];
    let corners = match t.attr("transform") {
        None => corners,
        Some(tr) => rotated(tr, corners)?,
    };
    let mut b = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for (cx, cy) in corners {
        b = [b[0].min(cx), b[1].min(cy), b[2].max(cx), b[3].max(cy)];
    }
    Ok(b)
}

/// The corners turned by `rotate(a cx cy)` (the only transform our charts put on text).
fn rotated(tr: &str, corners: [(f64, f64); 4]) -> Result<[(f64, f64); 4], String> {
    let args = tr
        .strip_prefix("rotate(")
        .and_then(|r| r.strip_suffix(')'))
        .ok_or_else(|| format!("unsupported transform {tr:?}"))?;
    let v: Vec<f64> = args
        .split([' ', ','])
        .filter(|s| !s.is_empty())
        .map(str::parse)
        .collect::<Result<_, _>>()
        .map_err(|_| format!("bad transform {tr:?}"))?;
    let (a, cx, cy) = match v[..] {
        [a] => (a, 0.0, 0.0),
        [a, cx, cy] => (a, cx, cy),
        _ => return Err(format!("bad transform {tr:?}")),
    };
    let (s, c) = a.to_radians().sin_cos();
    Ok(corners.map(|(x, y)| {
        let (dx, dy) = (x - cx, y - cy);
        (cx + c * dx - s * dy, cy + s * dx + c * dy)
    }))
}

/// The root's view box: width, height.
fn view_box(svg: &str) -> Result<(f64, f64), String> {
    let root = tags(svg)
        .into_iter()
        .find(|t| t.name == "svg")
        .ok_or("no <svg> element")?;
    let vb = root.attr("viewBox").ok_or("the <svg> has no viewBox")?;
    let v: Vec<f64> = vb
        .split_whitespace()
        .map(str::parse)
        .collect::<Result<_, _>>()
        .map_err(|_| format!("bad viewBox {vb:?}"))?;
    match v[..] {
        [0.0, 0.0, w, h] => Ok((w, h)),
        _ => Err(format!("viewBox {vb:?} does not start at 0 0")),
    }
}

/// Attributes holding names, not numbers.
const NAME_ATTRIBUTES: [&str; 5] = ["data-name", "class", "id", "clip-path", "font-family"];

/// Whether `s` holds a word `NaN`, `inf` or `infinity` (as Rust and browsers write them).
fn has_non_finite(s: &str) -> bool {
    s.split(|c: char| !c.is_ascii_alphabetic())
        .any(|w| ["nan", "inf", "infinity"].contains(&w.to_ascii_lowercase().as_str()))
}

/// Every problem found in `svg`: a non-finite number in an attribute, a text (partly) outside
/// the view box, two texts that overlap. Empty when the SVG passes.
pub fn check_svg(svg: &str) -> Vec<String> {
    let mut problems = Vec::new();
    for t in tags(svg) {
        for (k, v) in &t.attrs {
            if !NAME_ATTRIBUTES.contains(k) && has_non_finite(v) {
                problems.push(format!("<{} {k}=\"{v}\">: not a finite number", t.name));
            }
        }
        if has_non_finite(t.text_after) {
            problems.push(format!("text {:?}: not a finite number", t.text_after));
        }
    }
    let (w, h) = match view_box(svg) {
        Ok(wh) => wh,
        Err(e) => return [problems, vec![e]].concat(),
    };
    let boxes = match text_boxes(svg) {
        Ok(b) => b,
        Err(e) => return [problems, vec![e]].concat(),
    };
    for (b, text) in &boxes {
        if b[0] < 0.0 || b[1] < 0.0 || b[2] > w || b[3] > h {
            problems.push(format!(
                "text {text:?} at [{:.0}, {:.0}]..[{:.0}, {:.0}] leaves the view box {w} x {h}",
                b[0], b[1], b[2], b[3]
            ));
        }
    }
    for (i, (a, ta)) in boxes.iter().enumerate() {
        for (b, tb) in &boxes[i + 1..] {
            let overlap = a[0] < b[2] && b[0] < a[2] && a[1] < b[3] && b[1] < a[3];
            if overlap {
                problems.push(format!("texts {ta:?} and {tb:?} overlap"));
            }
        }
    }
    problems
}

/// The axis ranges each figure panel declares, in data units: `[x_lo, x_hi, y_lo, y_hi]`.
pub fn panel_ranges(svg: &str) -> Vec<[f64; 4]> {
    tags(svg)
        .into_iter()
        .filter(|t| !t.closing && t.name == "g" && t.attr("class") == Some("panel"))
        .filter_map(|t| {
            let get = |k: &str| t.attr(k)?.parse::<f64>().ok();
            Some([
                get("data-x-lo")?,
                get("data-x-hi")?,
                get("data-y-lo")?,
                get("data-y-hi")?,
            ])
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_texts_outside_overlapping_and_non_finite() {
        let ok = r#"<svg viewBox="0 0 100 50" font-size="10"><text x="50" y="20" text-anchor="middle">abcde</text></svg>"#;
        assert!(check_svg(ok).is_empty(), "{:?}", check_svg(ok));
        let wide = ok.replace("abcde", "abcdefghijklmnopqrstu");
        assert!(check_svg(&wide)[0].contains("leaves the view box"));
        let end = ok.replace("middle", "end").replace("x=\"50\"", "x=\"20\"");
        assert!(check_svg(&end)[0].contains("leaves the view box"));
        let nan = ok.replace("y=\"20\"", "y=\"NaN\"");
        assert!(check_svg(&nan).iter().any(|p| p.contains("not a finite")));
        let two = ok.replace(
            "</svg>",
            r#"<g font-size="10"><text x="52" y="22">x</text></g></svg>"#,
        );
        assert!(
            check_svg(&two)[0].contains("overlap"),
            "{:?}",
            check_svg(&two)
        );
        let rotated = r#"<svg viewBox="0 0 100 50" font-size="10"><text x="10" y="25" text-anchor="middle" transform="rotate(-90 10 25)">abcdefghi</text></svg>"#;
        assert!(check_svg(rotated)[0].contains("leaves"), "54 px tall in 50");
        let fits = rotated.replace("abcdefgh", "abcdef");
        assert!(check_svg(&fits).is_empty(), "{:?}", check_svg(&fits));
    }

    #[test]
    fn reads_panel_ranges_and_inline_documents() {
        let page = r#"<p>x</p><svg viewBox="0 0 1 1"><g class="panel" data-x-lo="1e-2" data-x-hi="1e2" data-y-lo="3e-5" data-y-hi="2e-3"></g></svg><svg viewBox="0 0 1 1"></svg>"#;
        let docs = crate::render::html::inline_svgs(page);
        assert_eq!(docs.len(), 2);
        assert_eq!(panel_ranges(docs[0]), vec![[1e-2, 1e2, 3e-5, 2e-3]]);
        assert!(panel_ranges(docs[1]).is_empty());
    }
}
