//! The rows of a text file, streamed line by line: time plus `N` value columns chosen by index
//! or header name (or the `N` values alone, timed by their row at a given rate), and the label
//! column when there is one. The layout comes from the first
//! content lines (`layout`); every error names the file, the line and the column.

use std::io::BufRead;
use std::path::Path;

use super::layout::{self, Separator};
use super::{ColumnRef, InputError, Labels};

/// Content lines read ahead to tell the layout.
const SNIFF_LINES: usize = 16;

/// What to read from a file.
pub(super) struct Spec<'a> {
    /// Names of the time (unless the clock is a rate) and value columns, for messages
    /// (`t, ax, ay, az`).
    pub roles: &'a [&'a str],
    /// The time and value columns (`--columns`); `None`: the first ones, the label's left out.
    pub columns: Option<&'a [ColumnRef]>,
    /// The label column (`--label-column`); `None`: a header column named `part` or `label`.
    pub label: Option<&'a ColumnRef>,
    /// Where the times come from.
    pub clock: Clock,
}

/// Where a row's time comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Clock {
    /// The first chosen column, times this many seconds per unit.
    Column { time_scale_s: f64 },
    /// No time column: data row `n` (0-based) is at `start_s + n / rate_hz`.
    Rate { rate_hz: f64, start_s: f64 },
}

/// The rows read: times (s, as written times the scale), values as written, labels.
pub(super) struct Table<const N: usize> {
    pub t: Vec<f64>,
    pub values: Vec<[f64; N]>,
    pub labels: Option<Labels>,
}

/// The layout and the columns, resolved against the file's first lines.
struct Resolved {
    sep: Separator,
    header: Option<Vec<String>>,
    /// Time (unless the clock is a rate) then value columns, 0-based.
    cols: Vec<usize>,
    label: Option<usize>,
    /// What the columns are, for messages: `t, ax, ay, az` with the header's names.
    described: String,
}

/// Reads the table of `path` as `spec` says.
pub(super) fn read_table<const N: usize>(
    path: &Path,
    spec: &Spec<'_>,
) -> Result<Table<N>, InputError> {
    let io = |source| InputError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let mut reader = std::io::BufReader::with_capacity(1 << 20, file);
    let mut ahead: Vec<(usize, String)> = Vec::new();
    let mut number = 0;
    let mut line = Vec::new();
    while ahead.len() < SNIFF_LINES {
        line.clear();
        if reader.read_until(b'\n', &mut line).map_err(io)? == 0 {
            break;
        }
        number += 1;
        let text = String::from_utf8_lossy(&line);
        if !layout::is_comment(text.trim()) {
            ahead.push((number, text.trim().to_string()));
        }
    }
    let resolved = resolve(path, spec, &ahead)?;
    let mut table = Builder::<N>::new(spec.clock, resolved.label.is_some());
    let skip = usize::from(resolved.header.is_some());
    for (n, text) in ahead.iter().skip(skip) {
        table.push(path, &resolved, *n, text)?;
    }
    loop {
        line.clear();
        if reader.read_until(b'\n', &mut line).map_err(io)? == 0 {
            break;
        }
        number += 1;
        // Text in any 8-bit encoding: numbers are ASCII, other bytes only matter in labels.
        let text = String::from_utf8_lossy(&line);
        let text = text.trim();
        if !layout::is_comment(text) {
            table.push(path, &resolved, number, text)?;
        }
    }
    if table.t.is_empty() {
        return Err(InputError::NoData {
            path: path.to_path_buf(),
            message: "no data lines".into(),
        });
    }
    Ok(table.finish())
}

/// The separator, header and columns from the first content lines.
fn resolve(
    path: &Path,
    spec: &Spec<'_>,
    ahead: &[(usize, String)],
) -> Result<Resolved, InputError> {
    let lines: Vec<&str> = ahead.iter().map(|(_, l)| l.as_str()).collect();
    let sep = layout::separator(&lines);
    let header = lines.first().and_then(|l| layout::header(l, sep));
    let header_line = ahead.first().map_or(1, |(n, _)| *n);
    let bad = |message: String| InputError::Csv {
        path: path.to_path_buf(),
        line: header_line,
        message,
    };
    let find = |c: &ColumnRef| -> Result<usize, InputError> {
        match (c, &header) {
            (ColumnRef::Index(i), _) => Ok(*i),
            (ColumnRef::Name(n), Some(h)) => h
                .iter()
                .position(|x| x.eq_ignore_ascii_case(n))
                .ok_or_else(|| bad(format!("no column `{n}` in the header ({})", h.join(", ")))),
            (ColumnRef::Name(n), None) => Err(bad(format!(
                "column `{n}` is named but the file has no header line: give 0-based indices"
            ))),
        }
    };
    let label = match spec.label {
        Some(c) => Some(find(c)?),
        None => header.as_ref().and_then(|h| {
            h.iter()
                .position(|x| x.eq_ignore_ascii_case("part") || x.eq_ignore_ascii_case("label"))
        }),
    };
    let cols: Vec<usize> = match spec.columns {
        Some(list) if list.len() != spec.roles.len() => {
            return Err(bad(format!(
                "{} columns chosen for {} ({})",
                list.len(),
                spec.roles.len(),
                spec.roles.join(", ")
            )));
        }
        Some(list) => list.iter().map(find).collect::<Result<_, _>>()?,
        None => (0..)
            .filter(|i| Some(*i) != label)
            .take(spec.roles.len())
            .collect(),
    };
    let described = spec
        .roles
        .iter()
        .zip(&cols)
        .map(|(role, &c)| match header.as_ref().and_then(|h| h.get(c)) {
            Some(name) if !name.eq_ignore_ascii_case(role) => format!("{role} = `{name}`"),
            _ => role.to_string(),
        })
        .collect::<Vec<_>>()
        .join(", ");
    Ok(Resolved {
        sep,
        header,
        cols,
        label,
        described,
    })
}

/// The table as it grows, with the labels interned.
struct Builder<const N: usize> {
    clock: Clock,
    t: Vec<f64>,
    values: Vec<[f64; N]>,
    labels: Option<Labels>,
}

impl<const N: usize> Builder<N> {
    fn new(clock: Clock, labelled: bool) -> Self {
        Builder {
            clock,
            t: Vec::new(),
            values: Vec::new(),
            labels: labelled.then(Labels::default),
        }
    }

    /// One data line.
    fn push(
        &mut self,
        path: &Path,
        r: &Resolved,
        number: usize,
        text: &str,
    ) -> Result<(), InputError> {
        let err = |message: String| InputError::Csv {
            path: path.to_path_buf(),
            line: number,
            message,
        };
        let fields = r.sep.split(text);
        let widest = r.cols.iter().chain(&r.label).max().copied().unwrap_or(0);
        if fields.len() <= widest {
            return Err(err(format!(
                "expected {} columns ({}{}), got {} ({}-separated)",
                widest + 1,
                r.described,
                r.label
                    .map_or(String::new(), |c| format!(", label in column {}", c + 1)),
                fields.len(),
                r.sep.name()
            )));
        }
        let mut v = [0.0; 8];
        for (k, &c) in r.cols.iter().enumerate() {
            let f = fields[c];
            v[k] = f.parse::<f64>().map_err(|_| {
                err(format!(
                    "column {} is not a number: `{f}` (expected {})",
                    c + 1,
                    r.described
                ))
            })?;
            if !v[k].is_finite() {
                return Err(err(format!("column {} is not finite: `{f}`", c + 1)));
            }
        }
        let (t, first_value) = match self.clock {
            Clock::Column { time_scale_s } => (v[0] * time_scale_s, 1),
            Clock::Rate { rate_hz, start_s } => (start_s + self.t.len() as f64 / rate_hz, 0),
        };
        if let Some(&last) = self.t.last()
            && t <= last
        {
            return Err(err(format!(
                "time {} does not increase (the line before: {last} s); a file without a time \
                 column (a sample index that restarts in each part is none) is read with \
                 --rate-hz",
                v[0]
            )));
        }
        if let (Some(labels), Some(c)) = (&mut self.labels, r.label) {
            labels.push(fields[c]);
        }
        self.t.push(t);
        self.values
            .push(std::array::from_fn(|i| v[i + first_value]));
        Ok(())
    }

    fn finish(self) -> Table<N> {
        Table {
            t: self.t,
            values: self.values,
            labels: self.labels,
        }
    }
}
