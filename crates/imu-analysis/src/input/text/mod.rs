//! Text recordings in any layout: comma, semicolon, tab or whitespace separated columns, told by
//! content and never by extension (`.csv`, `.txt`, `.dat`, `.tsv`, MATLAB's ASCII `.mat`), with
//! `#` or `%` comment lines and an optional header line (only a line without any number is one).
//! Columns are chosen by 0-based index or by header name; a `part` or `label` column names the
//! part of a labelled session each sample belongs to. Accelerometer and gyro come from one file
//! or from two on one clock (the gyro interpolated to the accelerometer's times). A file without
//! a time column (a published dataset that gives its rate apart) is read at a rate the caller
//! gives: row `n`'s time is `start + n / rate`, across the parts of a labelled session too (a
//! per-part sample index, restarting in each part, cannot give that time; it is just a column).

use std::path::{Path, PathBuf};

use super::{AccelUnit, GyroUnit, ImuSeries, InputError, Labels};

mod layout;
mod rows;

use rows::{Clock, Spec, Table, read_table};

/// How to read a text file: `time, ax, ay, az, gx, gy, gz` (a header line is skipped), or the
/// accelerometer's `time, ax, ay, az` with the gyro's `time, gx, gy, gz` in a second file.
#[derive(Debug, Clone, PartialEq)]
pub struct CsvOptions {
    /// Seconds per unit of the time column (1 for s, 1e-9 for ns).
    pub time_scale_s: f64,
    /// The sample rate of a file without a time column, Hz: its columns are then the values
    /// only (`ax, ay, az, gx, gy, gz`, or `ax, ay, az` with a gyro file, whose rows are on the
    /// same rate) and row `n` (0-based, data rows only) is at `start_s + n / rate_hz`.
    pub rate_hz: Option<f64>,
    /// The time of the first row when `rate_hz` is given, s (the origin that orders the files
    /// of a session).
    pub start_s: f64,
    /// Accelerometer unit.
    pub accel: AccelUnit,
    /// Gyro unit.
    pub gyro: GyroUnit,
    /// The gyro's own file (`time, gx, gy, gz`, same clock) when the recording's CSV holds
    /// only the accelerometer (`time, ax, ay, az`): the gyro is interpolated linearly to the
    /// accelerometer's times.
    pub gyro_file: Option<PathBuf>,
}

impl Default for CsvOptions {
    fn default() -> Self {
        Self {
            time_scale_s: 1.0,
            rate_hz: None,
            start_s: 0.0,
            accel: AccelUnit::MetersPerSecond2,
            gyro: GyroUnit::RadPerSecond,
            gyro_file: None,
        }
    }
}

/// A column of a text file: a 0-based index, or a name from its header line (matched without
/// regard to case).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ColumnRef {
    /// 0-based: the first column is 0.
    Index(usize),
    /// A header name.
    Name(String),
}

impl std::str::FromStr for ColumnRef {
    type Err = String;
    /// Digits are an index, anything else a name.
    fn from_str(s: &str) -> Result<Self, String> {
        let s = s.trim();
        if s.is_empty() {
            return Err("an empty column: give a 0-based index or a header name".into());
        }
        Ok(match s.parse::<usize>() {
            Ok(i) => ColumnRef::Index(i),
            Err(_) => ColumnRef::Name(s.to_string()),
        })
    }
}

/// Which columns hold what, for files whose columns are not in the default order.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Columns {
    /// The recording's columns: time, ax, ay, az, gx, gy, gz (7), or time, ax, ay, az (4)
    /// with a gyro file. `None`: the first columns, a label column left out.
    pub main: Option<Vec<ColumnRef>>,
    /// The gyro file's columns: time, gx, gy, gz. `None`: the first four.
    pub gyro: Option<Vec<ColumnRef>>,
    /// The label column of the recording. `None`: a header column named `part` or `label`, if
    /// any.
    pub label: Option<ColumnRef>,
}

/// Reads a text file of time plus accelerometer and gyro axes (streamed line by line), or,
/// with `options.gyro_file`, the accelerometer's file and the gyro's file; columns in the
/// default order (without the time with `options.rate_hz`).
pub fn read_csv(path: &Path, options: &CsvOptions) -> Result<ImuSeries, InputError> {
    read_text(path, options, &Columns::default())
}

/// [`read_csv`] with the columns chosen by `columns`.
pub fn read_text(
    path: &Path,
    options: &CsvOptions,
    columns: &Columns,
) -> Result<ImuSeries, InputError> {
    let mut series = ImuSeries {
        origin: path.display().to_string(),
        ..ImuSeries::default()
    };
    let clock = match options.rate_hz {
        Some(rate_hz) if !(rate_hz > 0.0 && rate_hz.is_finite() && options.start_s.is_finite()) => {
            return Err(InputError::NoData {
                path: path.to_path_buf(),
                message: format!(
                    "a rate of {rate_hz} Hz from {} s cannot time the rows: give a positive rate",
                    options.start_s
                ),
            });
        }
        Some(rate_hz) => Clock::Rate {
            rate_hz,
            start_s: options.start_s,
        },
        None => Clock::Column {
            time_scale_s: options.time_scale_s,
        },
    };
    // Without a time column the roles are the values only.
    let roles = |r: &'static [&'static str]| match clock {
        Clock::Rate { .. } => &r[1..],
        Clock::Column { .. } => r,
    };
    let main_spec = |r| Spec {
        roles: roles(r),
        columns: columns.main.as_deref(),
        label: columns.label.as_ref(),
        clock,
    };
    let (t, accel, gyro, labels) = match &options.gyro_file {
        None => {
            let table: Table<6> = read_table(path, &main_spec(&ONE_FILE))?;
            let (a, g) = table
                .values
                .iter()
                .map(|r| ([r[0], r[1], r[2]], [r[3], r[4], r[5]]))
                .unzip();
            (table.t, a, g, table.labels)
        }
        Some(gyro_path) => {
            let acc: Table<3> = read_table(path, &main_spec(&ACCEL_FILE))?;
            let gyr: Table<3> = read_table(
                gyro_path,
                &Spec {
                    roles: roles(&GYRO_FILE),
                    columns: columns.gyro.as_deref(),
                    label: None,
                    clock,
                },
            )?;
            series.origin = format!("{} + {}", path.display(), gyro_path.display());
            series.input.files.push(gyro_path.clone());
            align(path, gyro_path, acc, gyr)?
        }
    };
    let t0 = t[0];
    // The time column's own origin, for ordering the files of a session (never negative).
    series.t0_ns = if t0 >= 0.0 {
        (t0 * 1e9).round() as u64
    } else {
        0
    };
    series.t_s = t.iter().map(|x| x - t0).collect();
    series.accel_m_s2 = accel
        .iter()
        .map(|r| std::array::from_fn(|k| options.accel.to_m_s2(k, r[k])))
        .collect();
    series.gyro_rad_s = gyro
        .iter()
        .map(|r| std::array::from_fn(|k| options.gyro.to_rad_s(k, r[k])))
        .collect();
    series.labels = labels;
    series.input.files.insert(0, path.to_path_buf());
    Ok(series)
}

const ONE_FILE: [&str; 7] = ["time", "ax", "ay", "az", "gx", "gy", "gz"];
const ACCEL_FILE: [&str; 4] = ["time", "ax", "ay", "az"];
const GYRO_FILE: [&str; 4] = ["time", "gx", "gy", "gz"];

/// Times, accelerometer rows, gyro rows, labels.
type Aligned = (Vec<f64>, Vec<[f64; 3]>, Vec<[f64; 3]>, Option<Labels>);

/// The gyro at the accelerometer's times (same clock), linear between its samples;
/// accelerometer samples outside the gyro's span are dropped (with their labels).
fn align(
    path: &Path,
    gyro_path: &Path,
    acc: Table<3>,
    gyr: Table<3>,
) -> Result<Aligned, InputError> {
    let (t, a, tg, g) = (&acc.t, &acc.values, &gyr.t, &gyr.values);
    let (mut t_out, mut a_out, mut g_out) = (Vec::new(), Vec::new(), Vec::new());
    let mut kept = Vec::new();
    let mut j = 0;
    for (i, (ti, ai)) in t.iter().zip(a).enumerate() {
        while j + 1 < tg.len() && tg[j + 1] < *ti {
            j += 1;
        }
        if *ti < tg[0] || *ti > tg[tg.len() - 1] {
            continue;
        }
        let gi = if j + 1 < tg.len() {
            let w = ((ti - tg[j]) / (tg[j + 1] - tg[j])).clamp(0.0, 1.0);
            std::array::from_fn(|k| g[j][k] + w * (g[j + 1][k] - g[j][k]))
        } else {
            g[j]
        };
        t_out.push(*ti);
        a_out.push(*ai);
        g_out.push(gi);
        kept.push(i);
    }
    if t_out.is_empty() {
        return Err(InputError::NoData {
            path: gyro_path.to_path_buf(),
            message: format!(
                "the gyro's times ({:.3}-{:.3} s) do not overlap the accelerometer's \
                 ({:.3}-{:.3} s) in {}: both files must be on one clock",
                tg[0],
                tg[tg.len() - 1],
                t[0],
                t[t.len() - 1],
                path.display()
            ),
        });
    }
    let labels = acc.labels.map(|l| Labels {
        per_sample: kept.iter().map(|&i| l.per_sample[i]).collect(),
        names: l.names,
    });
    Ok((t_out, a_out, g_out, labels))
}

#[cfg(test)]
mod tests;
