//! Errors of this crate, and the helpers that turn TOML byte offsets and key paths into
//! `file:line:column` locations with the offending key named.

use crate::effects::valid_ids;
use std::ops::Range;
use toml::Spanned;
use toml::de::{DeTable, DeValue};

/// Everything that can go wrong loading, validating or saving a calibration file.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// The text is not valid TOML, or does not have the calibration file's shape (unknown key,
    /// wrong type, wrong array length, missing field).
    #[error("{file}:{line}:{column}: {message}")]
    Parse {
        /// File name as given by the caller.
        file: String,
        /// 1-based line.
        line: usize,
        /// 1-based column (characters).
        column: usize,
        /// What is wrong, naming the key, and what to do.
        message: String,
    },
    /// The file parsed but a value is out of its valid domain.
    #[error("{file}{}: {key}: {message}", .line.map(|l| format!(":{l}")).unwrap_or_default())]
    Invalid {
        /// File name as given by the caller (`<memory>` for a model built in code).
        file: String,
        /// Dotted key path, e.g. `gyro.scale-nonlinearity.cubic[1]`.
        key: String,
        /// 1-based line of the key, when it could be found in the source.
        line: Option<usize>,
        /// What is wrong and what to do.
        message: String,
    },
    /// Reading or writing the file failed.
    #[error("{file}: cannot access the file")]
    Io {
        /// The path involved.
        file: String,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
}

/// A step of a key path: a table key or an array index.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Seg {
    Key(String),
    Index(usize),
}

/// `accel.bias.value[1]`.
pub(crate) fn format_path(path: &[Seg]) -> String {
    let mut s = String::new();
    for seg in path {
        match seg {
            Seg::Key(k) => {
                if !s.is_empty() {
                    s.push('.');
                }
                s.push_str(k);
            }
            Seg::Index(i) => s.push_str(&format!("[{i}]")),
        }
    }
    s
}

/// Inverse of [`format_path`] (keys in this format never contain dots or brackets).
pub(crate) fn parse_path(key: &str) -> Vec<Seg> {
    let mut out = Vec::new();
    for part in key.split('.') {
        let mut rest = part;
        let name_end = rest.find('[').unwrap_or(rest.len());
        if name_end > 0 {
            out.push(Seg::Key(rest[..name_end].to_string()));
        }
        rest = &rest[name_end..];
        while let Some(close) = rest.find(']') {
            if let Ok(i) = rest[1..close].parse() {
                out.push(Seg::Index(i));
            }
            rest = &rest[close + 1..];
        }
    }
    out
}

/// 1-based (line, column) of a byte offset; the column counts characters. Shared by every
/// strict TOML reader of the project (calibrations, scenarios, the daemon's configuration).
pub fn line_col(source: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(source.len());
    let before = source.get(..offset).unwrap_or(source);
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |p| p + 1);
    let column = before[line_start..].chars().count() + 1;
    (line, column)
}

fn contains(span: &Range<usize>, offset: usize) -> bool {
    span.start <= offset && offset < span.end.max(span.start + 1)
}

fn find_in_table(table: &DeTable<'_>, offset: usize, path: &mut Vec<Seg>) -> bool {
    for (k, v) in table.iter() {
        path.push(Seg::Key(k.get_ref().to_string()));
        if contains(&k.span(), offset) || find_in_value(v, offset, path) {
            return true;
        }
        path.pop();
    }
    false
}

fn find_in_value(v: &Spanned<DeValue<'_>>, offset: usize, path: &mut Vec<Seg>) -> bool {
    match v.get_ref() {
        DeValue::Table(t) if find_in_table(t, offset, path) => return true,
        DeValue::Array(a) => {
            for (i, e) in a.iter().enumerate() {
                path.push(Seg::Index(i));
                if find_in_value(e, offset, path) {
                    return true;
                }
                path.pop();
            }
        }
        _ => {}
    }
    contains(&v.span(), offset)
}

/// The key path of whatever sits at byte `offset` of `source` (a key, a value, an array element
/// or a table header).
pub(crate) fn key_path_at(source: &str, offset: usize) -> Option<Vec<Seg>> {
    let doc = DeTable::parse(source).ok()?;
    let mut path = Vec::new();
    find_in_table(doc.get_ref(), offset, &mut path).then_some(path)
}

/// 1-based line where the dotted key (e.g. `device.baud` or `gyro.scale.value[1]`) is set in
/// TOML `source`, or of its closest existing parent; `None` if the text does not parse.
pub fn line_of_key(source: &str, dotted_key: &str) -> Option<usize> {
    line_of_path(source, &parse_path(dotted_key))
}

/// 1-based line of the deepest part of `path` found in `source` (the key itself if present,
/// else its closest existing parent).
pub(crate) fn line_of_path(source: &str, path: &[Seg]) -> Option<usize> {
    let doc = DeTable::parse(source).ok()?;
    let mut best: Option<Range<usize>> = None;
    let mut table = doc.get_ref();
    let mut value: Option<&Spanned<DeValue<'_>>> = None;
    for seg in path {
        let next = match (seg, value) {
            (Seg::Key(name), _) => {
                let found = table.iter().find(|(k, _)| k.get_ref() == name);
                match found {
                    Some((k, v)) => {
                        best = Some(k.span());
                        Some(v)
                    }
                    None => None,
                }
            }
            (Seg::Index(i), Some(v)) => match v.get_ref().as_array() {
                Some(a) => a.get(*i).inspect(|e| best = Some(e.span())),
                None => None,
            },
            (Seg::Index(_), None) => None,
        };
        let Some(next) = next else { break };
        value = Some(next);
        if let Some(t) = next.get_ref().as_table() {
            table = t;
        }
    }
    best.map(|span| line_col(source, span.start).0)
}

/// Levenshtein distance, for "did you mean" hints.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut cur = vec![i + 1];
        for (j, cb) in b.iter().enumerate() {
            let sub = prev[j] + usize::from(ca != *cb);
            cur.push(sub.min(prev[j + 1] + 1).min(cur[j] + 1));
        }
        prev = cur;
    }
    prev[b.len()]
}

/// ` (did you mean `x`?)` for the closest of `candidates` within 3 edits (a name of at least 3
/// characters that starts a candidate, such as `latitude` for `latitude-deg`, counts as 1),
/// else "". The one "did you mean" rule of every config, plan, model and log reader.
pub fn did_you_mean<S: AsRef<str>>(name: &str, candidates: &[S]) -> String {
    candidates
        .iter()
        .map(|c| {
            let c = c.as_ref();
            let prefix = name.len() >= 3 && c.starts_with(name);
            (if prefix { 1 } else { edit_distance(name, c) }, c)
        })
        .filter(|(d, _)| *d <= 3)
        .min()
        .map(|(_, c)| format!(" (did you mean `{c}`?)"))
        .unwrap_or_default()
}

/// Backticked tokens of a serde message, in order.
fn backticked(message: &str) -> Vec<String> {
    message
        .split('`')
        .skip(1)
        .step_by(2)
        .map(|s| s.to_string())
        .collect()
}

/// Turn a `toml` deserialization error into [`ModelError::Parse`] naming the key and the fix.
pub(crate) fn parse_error(file: &str, source: &str, err: &toml::de::Error) -> ModelError {
    let raw = err.message().trim_end().to_string();
    let (offset, (line, column)) = match err.span() {
        Some(span) => (Some(span.start), line_col(source, span.start)),
        None => (None, (1, 1)),
    };
    // An empty span (e.g. `missing field` at offset 0) points at no key: report no path rather
    // than whatever table happens to start there.
    let path = match err.span() {
        Some(span) if !span.is_empty() => offset.and_then(|o| key_path_at(source, o)),
        _ => None,
    }
    .unwrap_or_default();
    let message = describe(&raw, &path);
    ModelError::Parse {
        file: file.to_string(),
        line,
        column,
        message,
    }
}

fn describe(raw: &str, path: &[Seg]) -> String {
    let here = format_path(path);
    if raw.starts_with("unknown field") {
        let tokens = backticked(raw);
        let name = tokens.first().cloned().unwrap_or_default();
        let expected: Vec<String> = tokens.into_iter().skip(1).collect();
        // The span points at the unknown key itself; its parent is the table it is in.
        let parent = match path.last() {
            Some(Seg::Key(k)) if *k == name => &path[..path.len() - 1],
            _ => path,
        };
        let parent_name = format_path(parent);
        let is_triad =
            matches!(parent, [Seg::Key(t)] if ["accel", "gyro", "mag"].contains(&t.as_str()));
        if is_triad {
            return format!(
                "unknown effect `{name}` in [{parent_name}]; valid effects: {}; other keys: noise, residual-rms{}",
                valid_ids(),
                did_you_mean(&name, &expected)
            );
        }
        let list = if expected.is_empty() {
            "none".to_string()
        } else {
            expected.join(", ")
        };
        let place = if parent.is_empty() {
            "at the top level".to_string()
        } else {
            format!("in [{parent_name}]")
        };
        return format!(
            "unknown key `{name}` {place}; valid keys: {list}{}",
            did_you_mean(&name, &expected)
        );
    }
    let hint = if raw.starts_with("invalid length") && raw.contains("length 3") {
        "; give one value per axis: [x, y, z]"
    } else if raw.starts_with("invalid type") && raw.contains("expected f64") {
        "; write a number, e.g. 0.0"
    } else if raw.starts_with("invalid type: map, expected a string") {
        // A TOML date-time reaches serde as a map; provenance dates are plain strings.
        "; quote the value, e.g. created = \"2025-03-01T12:00:00Z\""
    } else if raw.starts_with("missing field `format`") {
        "; the file must contain format = \"imud-calibration/1\""
    } else {
        ""
    };
    if raw.starts_with("missing field") {
        let place = if here.is_empty() {
            "at the top level".to_string()
        } else {
            format!("in [{here}]")
        };
        return format!("{raw} {place}{hint}");
    }
    if here.is_empty() {
        format!("{raw}{hint}")
    } else {
        format!("{here}: {raw}{hint}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_round_trip_through_text() {
        let p = parse_path("gyro.scale-nonlinearity.cubic[1]");
        assert_eq!(
            p,
            vec![
                Seg::Key("gyro".into()),
                Seg::Key("scale-nonlinearity".into()),
                Seg::Key("cubic".into()),
                Seg::Index(1)
            ]
        );
        assert_eq!(format_path(&p), "gyro.scale-nonlinearity.cubic[1]");
        assert_eq!(
            format_path(&parse_path("accel.temp-bias.coefficients[1][2]")),
            "accel.temp-bias.coefficients[1][2]"
        );
    }

    #[test]
    fn line_and_column_are_one_based() {
        let s = "a = 1\nbb = 2\n";
        assert_eq!(line_col(s, 0), (1, 1));
        assert_eq!(line_col(s, 6), (2, 1));
        assert_eq!(line_col(s, 9), (2, 4));
    }

    #[test]
    fn line_of_path_finds_keys_headers_and_elements() {
        let s = "format = \"x\"\n\n[gyro.scale-nonlinearity]\nquadratic = [0.0, 0.0, 0.0]\ncubic = [\n  0.0,\n  1.0,\n  0.0]\n";
        assert_eq!(
            line_of_path(s, &parse_path("gyro.scale-nonlinearity")),
            Some(3)
        );
        assert_eq!(
            line_of_path(s, &parse_path("gyro.scale-nonlinearity.cubic")),
            Some(5)
        );
        assert_eq!(
            line_of_path(s, &parse_path("gyro.scale-nonlinearity.cubic[1]")),
            Some(7)
        );
        // A missing leaf falls back to its parent.
        assert_eq!(
            line_of_path(s, &parse_path("gyro.scale-nonlinearity.std-error")),
            Some(3)
        );
        assert_eq!(line_of_path(s, &parse_path("accel.bias")), None);
    }

    #[test]
    fn edit_distance_counts_single_edits() {
        assert_eq!(edit_distance("biass", "bias"), 1);
        assert_eq!(edit_distance("vlaue", "value"), 2);
        assert_eq!(edit_distance("scale", "scale"), 0);
        assert_eq!(edit_distance("", "abc"), 3);
    }
}
