//! Reference logs: a time-stamped record of the true input in the sensor frame, such as a rate
//! table's log, as a CSV file whose header names the columns and their units:
//!
//! ```text
//! t_s,wx_deg_s,wy_deg_s,wz_deg_s,fx_m_s2,fy_m_s2,fz_m_s2
//! 12.00,0.0,0.0,20.0,0.0,0.0,9.80665
//! ```
//!
//! Time: `t_s`, `t_ms` or `t_ns` (any origin: the log's own clock). Angular rate, required:
//! `wx_rad_s`/`wx_deg_s` and likewise `wy_*`, `wz_*`, the sensor's true inertial rate (so a
//! log made from a table's rate lacks Earth's rate, 15 deg/h, which matters only for gyros
//! stable to a few deg/h). Specific force, optional but needed for the accelerometer fit:
//! `fx_m_s2`/`fx_g` and likewise. Lines starting with `#` are comments.
//!
//! A rate table logs one column, its rate about its own axis: `t_s,rate_deg_s` (or
//! `rate_rad_s`), with the table axis in sensor axes given by a comment line
//! `# table-axis = +z` (a sensor axis or a vector `[x, y, z]`; positive rates turn the table
//! right-handed about it). It applies to the rows after it, so a log of several mountings
//! (each sensor axis on the table in turn) gives a new `# table-axis` line where the unit was
//! re-mounted. Unless the log also has the specific force columns, the table axis is taken as
//! VERTICAL: the specific force is local gravity along the axis, pointing up (along `+axis` or
//! `-axis`, whichever way the measured accel points: a bias cannot flip the sign of 1 g), and a
//! still segment whose measured gravity is not along the axis is refused. Local gravity is
//! `# gravity-m-s2 = G`, else WGS-84 normal gravity at `# latitude-deg = L`, else 9.80665
//! (a note says so). With the latitude, Earth's rate along the vertical (`Omega sin L`) is
//! added to the table's rate (a table logs its rate relative to the ground) and the
//! horizontal part, which the log cannot know, is carried as gyro bias uncertainty; without
//! it, all of Earth's rate is.
//!
//! ```text
//! # table-axis = +z
//! # latitude-deg = 40.0
//! t_s,rate_deg_s
//! 0.00,0.0
//! 0.01,0.4
//! ```
//!
//! The log's clock is aligned with the recording's by cross-correlating the magnitude of the
//! reference rate with the magnitude of the measured gyro rate (scale, misalignment and bias
//! errors barely change a magnitude profile): coarse over every overlap on binned data, then at
//! the recording's sample spacing around the best coarse lag, with parabolic interpolation of
//! the peak. The correlation is zero-padded (not normalised per overlap), so a repeated
//! pattern such as three identical rate-table runs cannot match one run late. The reference is
//! then averaged over each segment's time range.

use std::path::Path;

use imu_model::Vec3;
use imu_model::units::{DEG_TO_RAD, EARTH_RATE_RAD_S, STANDARD_GRAVITY_M_S2};

use crate::ImuSeries;
use crate::plan::{format_direction, parse_direction};
use crate::reference::SegmentTruth;
use crate::segment::{Segment, SegmentKind};
use imu_model::did_you_mean;
use imu_model::earth::normal_gravity_m_s2;

/// Largest relative difference between a plateau's measured and reference rate magnitude
/// before the log is taken to be in other units or of another run.
const RATE_TOLERANCE: f64 = 0.1;
/// Largest angle between a still segment's measured and reference specific force, degrees.
const DIRECTION_TOLERANCE_DEG: f64 = 10.0;
/// Smallest correlation accepted for the time alignment.
const MIN_CORRELATION: f64 = 0.5;

/// Errors reading or using a reference log.
#[derive(Debug, thiserror::Error)]
pub enum ReferenceLogError {
    /// The file could not be read.
    #[error("{file}: cannot read the reference log")]
    Io {
        /// The log file.
        file: String,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A line of the CSV is malformed, or the header is incomplete.
    #[error("{file}:{line}: {message}")]
    Csv {
        /// The log file.
        file: String,
        /// 1-based line.
        line: usize,
        /// What is wrong and what to do.
        message: String,
    },
    /// The clocks could not be aligned.
    #[error("{file}: cannot align the log with the recording: {message}")]
    Align {
        /// The log file.
        file: String,
        /// Why, and what to do.
        message: String,
    },
    /// The log does not cover, or does not match, the recording's segments.
    #[error("{file}: {summary}:{}", .problems.iter().map(|p| format!("\n  - {p}")).collect::<String>())]
    Segments {
        /// The log file.
        file: String,
        /// One line on the whole.
        summary: String,
        /// Each problem, naming the segment and its time range.
        problems: Vec<String>,
    },
}

/// A parsed reference log (times on the log's own clock, SI units, sensor frame).
#[derive(Clone, Debug, PartialEq)]
pub struct ReferenceLog {
    /// The file, for messages.
    pub file: String,
    /// Times on the log's clock, s (strictly increasing).
    pub t_s: Vec<f64>,
    /// True angular rate, rad/s.
    pub angular_rate_rad_s: Vec<[f64; 3]>,
    /// True specific force, m/s^2, when the log has it.
    pub specific_force_m_s2: Option<Vec<[f64; 3]>>,
    /// A one-column table log: the table axis (unit, sensor frame) of each row, and local
    /// gravity and latitude for the input the log does not give. None for a three-axis log.
    pub table: Option<TableLog>,
}

/// What a one-column rate table log adds (see the module documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct TableLog {
    /// The table axis of each row (unit vector, sensor frame).
    pub axis_sensor: Vec<[f64; 3]>,
    /// Where the axis changes: (1-based line of the `# table-axis` line, first row, axis).
    pub axis_lines: Vec<(usize, usize, [f64; 3])>,
    /// Local gravity, m/s^2.
    pub gravity_m_s2: f64,
    /// Where `gravity_m_s2` comes from.
    pub gravity_source: String,
    /// Site latitude, degrees, when the log gives it (Earth's vertical rate is then added).
    pub latitude_deg: Option<f64>,
}

/// A reference log with its clock offset to the recording.
#[derive(Clone, Debug, PartialEq)]
pub struct AlignedLog {
    /// The log.
    pub log: ReferenceLog,
    /// Log clock minus recording clock for the same instant, s (the recording's clock counts
    /// from its first sample).
    pub offset_s: f64,
    /// Correlation of reference and measured rate magnitudes at `offset_s`; `None` when the
    /// offset was given rather than found.
    pub correlation: Option<f64>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Column {
    Time(f64),
    Rate(usize, f64),
    Force(usize, f64),
    /// The table's rate about its axis.
    TableRate(f64),
}

const COLUMNS: [&str; 17] = [
    "t_s",
    "t_ms",
    "t_ns",
    "wx_rad_s",
    "wy_rad_s",
    "wz_rad_s",
    "wx_deg_s",
    "wy_deg_s",
    "wz_deg_s",
    "fx_m_s2",
    "fy_m_s2",
    "fz_m_s2",
    "fx_g",
    "fy_g",
    "fz_g",
    "rate_deg_s",
    "rate_rad_s",
];

/// Settings a comment line may give (`# key = value`).
const SETTINGS: [&str; 3] = ["table-axis", "gravity-m-s2", "latitude-deg"];

fn column(name: &str) -> Option<Column> {
    let axis = |c: char| "xyz".find(c);
    Some(match name {
        "t_s" => Column::Time(1.0),
        "t_ms" => Column::Time(1e-3),
        "t_ns" => Column::Time(1e-9),
        "rate_deg_s" => Column::TableRate(DEG_TO_RAD),
        "rate_rad_s" => Column::TableRate(1.0),
        _ => {
            let mut ch = name.chars();
            let (kind, a) = (ch.next()?, axis(ch.next()?)?);
            match (kind, ch.as_str()) {
                ('w', "_rad_s") => Column::Rate(a, 1.0),
                ('w', "_deg_s") => Column::Rate(a, DEG_TO_RAD),
                ('f', "_m_s2") => Column::Force(a, 1.0),
                ('f', "_g") => Column::Force(a, STANDARD_GRAVITY_M_S2),
                _ => return None,
            }
        }
    })
}

impl ReferenceLog {
    /// Reads a reference log CSV.
    pub fn load(path: &Path) -> Result<ReferenceLog, ReferenceLogError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| ReferenceLogError::Io {
            file: file.clone(),
            source,
        })?;
        ReferenceLog::from_csv_str(&text, &file)
    }

    /// Parses reference log text; `file` names it in messages.
    pub fn from_csv_str(text: &str, file: &str) -> Result<ReferenceLog, ReferenceLogError> {
        let err = |line: usize, message: String| ReferenceLogError::Csv {
            file: file.to_string(),
            line,
            message,
        };
        const EXAMPLE: &str = "t_s,wx_deg_s,wy_deg_s,wz_deg_s[,fx_m_s2,fy_m_s2,fz_m_s2]";
        const TABLE_EXAMPLE: &str = "# table-axis = +z, then t_s,rate_deg_s";
        let mut columns: Option<Vec<Column>> = None;
        let mut log = ReferenceLog {
            file: file.to_string(),
            t_s: Vec::new(),
            angular_rate_rad_s: Vec::new(),
            specific_force_m_s2: None,
            table: None,
        };
        let mut force = Vec::new();
        // Settings from comment lines: (line, value) of each.
        let mut axis: Option<Vec3> = None;
        let mut axis_rows: Vec<[f64; 3]> = Vec::new();
        let mut axis_lines: Vec<(usize, usize, [f64; 3])> = Vec::new();
        let mut gravity: Option<(usize, f64)> = None;
        let mut latitude: Option<(usize, f64)> = None;
        let mut first_setting: Option<usize> = None;
        for (i, line) in text.lines().enumerate() {
            let n = i + 1;
            let line = line.trim();
            if let Some(comment) = line.strip_prefix('#') {
                let Some((key, value)) = comment.split_once('=') else {
                    continue;
                };
                let key = key.trim().to_ascii_lowercase().replace('_', "-");
                let value = value.trim();
                if !SETTINGS.contains(&key.as_str()) {
                    let hint = did_you_mean(&key, &SETTINGS);
                    if !hint.is_empty() && !key.contains(' ') {
                        return Err(err(
                            n,
                            format!(
                                "unknown setting `{key}`{hint}; settings: {}",
                                SETTINGS.join(", ")
                            ),
                        ));
                    }
                    continue;
                }
                first_setting.get_or_insert(n);
                let number = || {
                    value
                        .parse::<f64>()
                        .ok()
                        .filter(|v| v.is_finite())
                        .ok_or_else(|| err(n, format!("{key}: `{value}` is not a number")))
                };
                match key.as_str() {
                    "table-axis" => {
                        let a = parse_direction(value).ok_or_else(|| {
                            err(
                                n,
                                format!(
                                    "table-axis: `{value}` is not a sensor direction: write x, \
                                     -x, +y, ..., -z or a vector [x, y, z]"
                                ),
                            )
                        })?;
                        axis = Some(a);
                        axis_lines.push((n, log.t_s.len(), a.into()));
                    }
                    "gravity-m-s2" => {
                        let g = number()?;
                        if !(9.7..=9.9).contains(&g) {
                            return Err(err(
                                n,
                                format!(
                                    "gravity-m-s2: {g} is not a gravity on Earth's surface (9.78..9.83)"
                                ),
                            ));
                        }
                        if let Some((l, _)) = gravity.replace((n, g)) {
                            return Err(err(n, format!("gravity-m-s2 is given twice (line {l})")));
                        }
                    }
                    _ => {
                        let lat = number()?;
                        if !(-90.0..=90.0).contains(&lat) {
                            return Err(err(n, format!("latitude-deg: {lat} is outside -90..90")));
                        }
                        if let Some((l, _)) = latitude.replace((n, lat)) {
                            return Err(err(n, format!("latitude-deg is given twice (line {l})")));
                        }
                    }
                }
                continue;
            }
            if line.is_empty() {
                continue;
            }
            let fields: Vec<&str> = line.split(',').map(str::trim).collect();
            let Some(cols) = &columns else {
                let mut cols = Vec::new();
                for f in &fields {
                    let name = f.to_ascii_lowercase();
                    let c = column(&name).ok_or_else(|| {
                        err(
                            n,
                            format!(
                                "unknown column `{f}`; the header names the columns with their \
                                 units: time t_s|t_ms|t_ns, angular rate w{{x,y,z}}_rad_s or \
                                 _deg_s (or one table rate rate_deg_s|rate_rad_s), specific \
                                 force f{{x,y,z}}_m_s2 or _g, e.g. `{EXAMPLE}`{}",
                                did_you_mean(&name, &COLUMNS)
                            ),
                        )
                    })?;
                    let same = |o: &Column| match (o, &c) {
                        (Column::Time(_), Column::Time(_))
                        | (Column::TableRate(_), Column::TableRate(_)) => true,
                        (Column::Rate(a, _), Column::Rate(b, _))
                        | (Column::Force(a, _), Column::Force(b, _)) => a == b,
                        _ => false,
                    };
                    if cols.iter().any(same) {
                        return Err(err(n, format!("column `{f}` is given twice")));
                    }
                    cols.push(c);
                }
                let has = |p: &dyn Fn(&Column) -> bool| cols.iter().filter(|c| p(c)).count();
                let (rates, table_rate) = (
                    has(&|c| matches!(c, Column::Rate(..))),
                    has(&|c| matches!(c, Column::TableRate(_))),
                );
                if has(&|c| matches!(c, Column::Time(_))) != 1
                    || !matches!((rates, table_rate), (3, 0) | (0, 1))
                {
                    return Err(err(
                        n,
                        format!(
                            "the header needs a time column and either all three angular rate \
                             columns, e.g. `{EXAMPLE}`, or one table rate column \
                             (`{TABLE_EXAMPLE}`)"
                        ),
                    ));
                }
                match has(&|c| matches!(c, Column::Force(..))) {
                    0 => {}
                    3 => log.specific_force_m_s2 = Some(Vec::new()),
                    _ => {
                        return Err(err(
                            n,
                            "give all three specific force columns (fx, fy, fz) or none".into(),
                        ));
                    }
                }
                columns = Some(cols);
                continue;
            };
            if fields.len() != cols.len() {
                return Err(err(
                    n,
                    format!(
                        "{} fields, the header names {} columns",
                        fields.len(),
                        cols.len()
                    ),
                ));
            }
            let (mut t, mut w, mut f) = (0.0, [0.0; 3], [0.0; 3]);
            for (c, text) in cols.iter().zip(&fields) {
                let v: f64 = text
                    .parse()
                    .ok()
                    .filter(|v: &f64| v.is_finite())
                    .ok_or_else(|| err(n, format!("`{text}` is not a number")))?;
                match *c {
                    Column::Time(k) => t = v * k,
                    Column::Rate(a, k) => w[a] = v * k,
                    Column::Force(a, k) => f[a] = v * k,
                    Column::TableRate(k) => {
                        let a = axis.ok_or_else(|| {
                            err(
                                n,
                                format!(
                                    "a table rate column is the rate about the table axis: say \
                                     which sensor axis that is with a line `# table-axis = +z` \
                                     (a sensor axis or a vector [x, y, z]) before the rows, \
                                     e.g. `{TABLE_EXAMPLE}`"
                                ),
                            )
                        })?;
                        w = (a * (v * k)).into();
                        axis_rows.push(a.into());
                    }
                }
            }
            if let Some(&last) = log.t_s.last()
                && t <= last
            {
                return Err(err(
                    n,
                    format!("time {t} s does not increase (previous {last} s)"),
                ));
            }
            log.t_s.push(t);
            log.angular_rate_rad_s.push(w);
            force.push(f);
        }
        if columns.is_none() || log.t_s.len() < 2 {
            return Err(err(
                text.lines().count().max(1),
                format!("a reference log needs a header (`{EXAMPLE}`) and at least two rows"),
            ));
        }
        if let Some(f) = &mut log.specific_force_m_s2 {
            *f = force;
        }
        if axis_rows.is_empty()
            && let Some(l) = first_setting
        {
            return Err(err(
                l,
                format!(
                    "the settings {} apply to a rate table's one-column log (rate_deg_s or \
                     rate_rad_s); this log gives the three axes",
                    SETTINGS.join(", ")
                ),
            ));
        }
        if !axis_rows.is_empty() {
            let latitude_deg = latitude.map(|(_, l)| l);
            let (gravity_m_s2, gravity_source) = match (gravity, latitude_deg) {
                (Some((_, g)), _) => (g, format!("{g} m/s^2 (given in the log)")),
                (None, Some(lat)) => {
                    let g = normal_gravity_m_s2(lat, 0.0);
                    (
                        g,
                        format!("{g:.5} m/s^2 (WGS-84 normal gravity at latitude {lat} deg)"),
                    )
                }
                (None, None) => (
                    STANDARD_GRAVITY_M_S2,
                    format!(
                        "{STANDARD_GRAVITY_M_S2} m/s^2 (standard gravity: give `# gravity-m-s2 \
                         = G` or `# latitude-deg = L` in the log for the local value)"
                    ),
                ),
            };
            log.table = Some(TableLog {
                axis_sensor: axis_rows,
                axis_lines,
                gravity_m_s2,
                gravity_source,
                latitude_deg,
            });
        }
        Ok(log)
    }

    /// Use a known clock offset (log clock minus recording clock, s) instead of finding it.
    pub fn with_offset(self, offset_s: f64) -> AlignedLog {
        AlignedLog {
            log: self,
            offset_s,
            correlation: None,
        }
    }

    /// Reference rate magnitude at log time `t` (linear interpolation; `None` outside).
    fn magnitude_at(&self, mags: &[f64], t: f64, cursor: &mut usize) -> Option<f64> {
        let ts = &self.t_s;
        if t < ts[0] || t > ts[ts.len() - 1] {
            return None;
        }
        while *cursor + 1 < ts.len() && ts[*cursor + 1] < t {
            *cursor += 1;
        }
        while *cursor > 0 && ts[*cursor] > t {
            *cursor -= 1;
        }
        let i = *cursor;
        if i + 1 >= ts.len() {
            return Some(mags[i]);
        }
        let u = (t - ts[i]) / (ts[i + 1] - ts[i]);
        Some(mags[i] + (mags[i + 1] - mags[i]) * u)
    }

    /// Find the clock offset to `series` by cross-correlating rate magnitudes.
    pub fn align(self, series: &ImuSeries) -> Result<AlignedLog, ReferenceLogError> {
        let fail = |message: String| ReferenceLogError::Align {
            file: self.file.clone(),
            message,
        };
        if series.len() < 10 {
            return Err(fail("the recording has fewer than 10 samples".into()));
        }
        let rec: Vec<f64> = series
            .gyro_rad_s
            .iter()
            .map(|w| Vec3::from(*w).norm())
            .collect();
        let refm: Vec<f64> = self
            .angular_rate_rad_s
            .iter()
            .map(|w| Vec3::from(*w).norm())
            .collect();
        let mean = imu_stats::descriptive::mean;
        let (rec_mean, ref_mean) = (mean(&rec), mean(&refm));
        let ref_std =
            (refm.iter().map(|m| (m - ref_mean).powi(2)).sum::<f64>() / refm.len() as f64).sqrt();
        if ref_std < 1f64.to_radians() {
            return Err(fail(format!(
                "the log's rate barely changes (std {:.3} deg/s), so there is nothing to align \
                 on; give the offset by hand (imu-calibrate --reference-offset-s)",
                ref_std.to_degrees()
            )));
        }
        let (t_rec_end, t_ref0) = (series.t_s[series.len() - 1], self.t_s[0]);
        let t_ref_span = self.t_s[self.t_s.len() - 1] - t_ref0;

        // Coarse: bin means on a common spacing, zero-padded correlation over every lag.
        let dt_c = (t_rec_end.max(t_ref_span) / 4000.0).max(0.5);
        let bins = |t: &[f64], v: &[f64], t0: f64, m: f64| -> Vec<f64> {
            let n = ((t[t.len() - 1] - t0) / dt_c).floor() as usize + 1;
            let (mut sum, mut count) = (vec![0.0; n], vec![0usize; n]);
            for (ti, vi) in t.iter().zip(v) {
                let k = (((ti - t0) / dt_c).floor() as usize).min(n - 1);
                sum[k] += vi - m;
                count[k] += 1;
            }
            let mut last = 0.0;
            sum.iter()
                .zip(&count)
                .map(|(s, &c)| {
                    if c > 0 {
                        last = s / c as f64;
                    }
                    last
                })
                .collect()
        };
        let a = bins(&series.t_s, &rec, 0.0, rec_mean);
        let b = bins(&self.t_s, &refm, t_ref0, ref_mean);
        let (na, nb) = (a.len() as i64, b.len() as i64);
        let mut best = (f64::NEG_INFINITY, 0i64);
        for k in -(na - 1)..nb {
            let lo = (-k).max(0);
            let hi = na.min(nb - k);
            let c: f64 = (lo..hi).map(|i| a[i as usize] * b[(i + k) as usize]).sum();
            if c > best.0 {
                best = (c, k);
            }
        }
        let coarse_s = t_ref0 + best.1 as f64 * dt_c;

        // Fine: the recording's own samples against the interpolated log, around the coarse lag.
        let dt_f = 1.0 / series.sample_rate_hz();
        let m = (2.0 * dt_c / dt_f).ceil() as i64;
        let corr_at = |tau: f64| -> f64 {
            let mut cursor = 0;
            let mut c = 0.0;
            for (t, r) in series.t_s.iter().zip(&rec) {
                if let Some(v) = self.magnitude_at(&refm, t + tau, &mut cursor) {
                    c += (r - rec_mean) * (v - ref_mean);
                }
            }
            c
        };
        let fine: Vec<(f64, f64)> = (-m..=m)
            .map(|i| {
                let tau = coarse_s + i as f64 * dt_f;
                (tau, corr_at(tau))
            })
            .collect();
        let k = (0..fine.len())
            .max_by(|&i, &j| fine[i].1.total_cmp(&fine[j].1))
            .expect("at least one lag");
        let mut offset_s = fine[k].0;
        if k > 0 && k + 1 < fine.len() {
            let (l, c, r) = (fine[k - 1].1, fine[k].1, fine[k + 1].1);
            let den = l - 2.0 * c + r;
            if den < 0.0 {
                offset_s += (0.5 * (l - r) / den).clamp(-0.5, 0.5) * dt_f;
            }
        }

        // Pearson correlation over the overlap at the chosen offset: the quality check.
        let mut cursor = 0;
        let pairs: Vec<(f64, f64)> = series
            .t_s
            .iter()
            .zip(&rec)
            .filter_map(|(t, r)| {
                self.magnitude_at(&refm, t + offset_s, &mut cursor)
                    .map(|v| (*r, v))
            })
            .collect();
        let (rec_side, ref_side): (Vec<f64>, Vec<f64>) = pairs.iter().copied().unzip();
        let correlation =
            imu_stats::descriptive::correlation(&rec_side, &ref_side).unwrap_or(f64::NAN);
        if pairs.len() < 10 || correlation.is_nan() || correlation < MIN_CORRELATION {
            return Err(fail(format!(
                "the best offset ({offset_s:.3} s, log clock minus recording clock) overlaps \
                 {} samples with correlation {correlation:.2} (< {MIN_CORRELATION}): the log does \
                 not look like this recording's motion (other run, wrong units or columns?)",
                pairs.len()
            )));
        }
        Ok(AlignedLog {
            log: self,
            offset_s,
            correlation: Some(correlation),
        })
    }
}

impl AlignedLog {
    /// The mean reference over each segment's time range (temperature and time since
    /// power-on from the recording), after checking that the log matches the measurements.
    pub fn segment_truth(
        &self,
        series: &ImuSeries,
        segments: &[Segment],
    ) -> Result<Vec<SegmentTruth>, ReferenceLogError> {
        let log = &self.log;
        let mut problems = Vec::new();
        let mut out = Vec::with_capacity(segments.len());
        let (ref_lo, ref_hi) = (
            log.t_s[0] - self.offset_s,
            log.t_s[log.t_s.len() - 1] - self.offset_s,
        );
        for (k, s) in segments.iter().enumerate() {
            let head = format!("segment {} at {:.1}-{:.1} s", k + 1, s.start_s, s.end_s);
            let lo = log.t_s.partition_point(|&t| t < s.start_s + self.offset_s);
            let hi = log.t_s.partition_point(|&t| t <= s.end_s + self.offset_s);
            if hi <= lo {
                problems.push(format!(
                    "{head}: no log rows (the log covers {ref_lo:.1}-{ref_hi:.1} s on the \
                     recording's clock)"
                ));
                continue;
            }
            let n = (hi - lo) as f64;
            let mut w = Vec3::zeros();
            for v in &log.angular_rate_rad_s[lo..hi] {
                w += Vec3::from(*v) / n;
            }
            let logged_f = log.specific_force_m_s2.as_ref().map(|f| {
                let mut m = Vec3::zeros();
                for v in &f[lo..hi] {
                    m += Vec3::from(*v) / n;
                }
                m
            });
            // A table log: the segment's table axis, which way is up (along the axis unless the
            // log gives the specific force), and Earth's vertical rate.
            let mut table_up = None;
            if let Some(t) = &log.table {
                let axes = &t.axis_sensor[lo..hi];
                let a = Vec3::from(axes[0]);
                if axes.iter().any(|x| Vec3::from(*x) != a) {
                    problems.push(format!(
                        "{head}: the table axis changes within the segment (a `# table-axis` \
                         line among its rows): put it where the unit was re-mounted"
                    ));
                    continue;
                }
                let along = s.mean_accel().dot(&a);
                let up = match logged_f {
                    Some(f) => f.normalize(),
                    None if along.abs() < 0.5 * t.gravity_m_s2 => {
                        problems.push(format!(
                            "{head}: the measured specific force {} is not along the table axis \
                             {} (without specific force columns the table axis is taken as \
                             vertical): give the columns fx_m_s2, fy_m_s2, fz_m_s2 for a \
                             tilted table",
                            format_direction(&s.mean_accel().normalize()),
                            format_direction(&a)
                        ));
                        continue;
                    }
                    None => a * along.signum(),
                };
                if let Some(lat) = t.latitude_deg {
                    w += up * (EARTH_RATE_RAD_S * lat.to_radians().sin());
                }
                if s.kind == SegmentKind::Plateau {
                    let (meas, refr) = (s.mean_gyro().dot(&a), w.dot(&a));
                    if meas.signum() != refr.signum() {
                        problems.push(format!(
                            "{head}: measured {:.2} deg/s about {}, the log says {:.2} deg/s: \
                             does the table turn the other way about this axis (table-axis {})?",
                            meas.to_degrees(),
                            format_direction(&a),
                            refr.to_degrees(),
                            format_direction(&-a)
                        ));
                    }
                }
                table_up = Some((up, t.gravity_m_s2));
            }
            let f = match (logged_f, table_up) {
                (Some(f), _) => f,
                (None, Some((up, g))) => up * g,
                (None, None) => {
                    problems.push(format!(
                        "{head}: the log has no specific force columns (fx_m_s2, fy_m_s2, \
                         fz_m_s2 or fx_g, ...): the accelerometer fit needs the true specific \
                         force of every segment; add them, or calibrate with a test plan \
                         (--plan)"
                    ));
                    continue;
                }
            };
            match s.kind {
                SegmentKind::Plateau => {
                    let (meas, refr) = (s.mean_gyro().norm(), w.norm());
                    if (meas - refr).abs() > RATE_TOLERANCE * refr {
                        problems.push(format!(
                            "{head}: measured rate {:.2} deg/s, the log says {:.2} deg/s (more \
                             than {:.0} % apart: units of the rate columns, or another run?)",
                            meas.to_degrees(),
                            refr.to_degrees(),
                            100.0 * RATE_TOLERANCE
                        ));
                    }
                }
                SegmentKind::Static => {
                    let angle = s.mean_accel().angle(&f).to_degrees();
                    if angle > DIRECTION_TOLERANCE_DEG {
                        problems.push(format!(
                            "{head}: measured up {} is {angle:.1} deg from the log's {} \
                             (tolerance {DIRECTION_TOLERANCE_DEG} deg)",
                            format_direction(&s.mean_accel().normalize()),
                            format_direction(&f.normalize())
                        ));
                    }
                }
            }
            let (temp_c, time_since_power_on_s) =
                crate::reference::recording_conditions(series, s, None, 0.0);
            out.push(SegmentTruth {
                specific_force_m_s2: f.into(),
                angular_rate_rad_s: w.into(),
                temp_c,
                time_since_power_on_s,
            });
        }
        if problems.is_empty() {
            return Ok(out);
        }
        Err(ReferenceLogError::Segments {
            file: log.file.clone(),
            summary: format!(
                "the log does not give the true input of {} of {} segments",
                problems.len(),
                segments.len()
            ),
            problems,
        })
    }

    /// The log rows over segment `s` (on the recording's clock).
    fn rows(&self, s: &Segment) -> std::ops::Range<usize> {
        let t = &self.log.t_s;
        let lo = t.partition_point(|&x| x < s.start_s + self.offset_s);
        let hi = t.partition_point(|&x| x <= s.end_s + self.offset_s);
        lo..hi.max(lo)
    }

    /// What a table log cannot know of the gyro's true input over `segments`, per axis, rad/s:
    /// the horizontal part of Earth's rate (all of it without a latitude) where the table stands
    /// still, and what a partial turn leaves of it on a plateau (as for a test plan). None for a
    /// three-axis log (its rate is the true inertial rate).
    pub fn gyro_bias_std_rad_s(&self, segments: &[Segment]) -> Option<[f64; 3]> {
        let t = self.log.table.as_ref()?;
        let mut sd = [0.0f64; 3];
        for s in segments {
            let r = self.rows(s);
            let Some(a) = t.axis_sensor.get(r.start).map(|a| Vec3::from(*a)) else {
                continue;
            };
            let turned_rad = (s.mean_gyro().dot(&a) * (s.end_s - s.start_s)).abs();
            let left = match s.kind {
                SegmentKind::Static => 1.0,
                SegmentKind::Plateau => (2.0 / turned_rad.max(1e-9)).min(1.0),
            };
            for (b, m) in sd.iter_mut().enumerate() {
                // What a partial turn leaves of the horizontal part; without a latitude the
                // whole rate is unknown.
                let left = if t.latitude_deg.is_some() { left } else { 1.0 };
                let x = left
                    * imu_model::earth::unknown_heading_variance_rad2_s2(t.latitude_deg, a[b])
                        .sqrt();
                *m = m.max(x);
            }
        }
        Some(sd)
    }

    /// Remarks for the report: the offset and how it was found, and for a table log its axes,
    /// gravity and Earth's rate.
    pub fn notes(&self, series: &ImuSeries) -> Vec<String> {
        let mut notes = vec![match self.correlation {
            Some(r) => format!(
                "reference log {}: log clock = recording clock {:+.3} s (found by \
                 cross-correlating rate magnitudes, correlation {r:.3})",
                self.log.file, self.offset_s
            ),
            None => format!(
                "reference log {}: log clock = recording clock {:+.3} s (given)",
                self.log.file, self.offset_s
            ),
        }];
        if let Some(t) = &self.log.table {
            let axes: Vec<String> = t
                .axis_lines
                .iter()
                .map(|(line, _, a)| {
                    format!("{} from line {line}", format_direction(&Vec3::from(*a)))
                })
                .collect();
            notes.push(format!(
                "reference log {}: a rate table's rate about its axis ({}); {}",
                self.log.file,
                axes.join(", "),
                if self.log.specific_force_m_s2.is_some() {
                    "specific force from the log".to_string()
                } else {
                    format!(
                        "the table axis is taken as vertical: specific force {} along it, \
                         pointing up the way the measured accel says",
                        t.gravity_source
                    )
                }
            ));
            notes.push(match t.latitude_deg {
                Some(lat) => format!(
                    "Earth's rate: its vertical part at latitude {lat} deg is added to the \
                     table's rate; the horizontal part, which the log cannot know, is carried \
                     as gyro bias uncertainty"
                ),
                None => "Earth's rate is not in a table's log and no `# latitude-deg` is \
                         given: all of it (7.3e-5 rad/s) is carried as gyro bias uncertainty"
                    .to_string(),
            });
        }
        if series.temp.is_empty() {
            notes.push(format!(
                "the recording has no temperature readings: {} deg C assumed; temperature \
                 effects cannot be fitted",
                imu_model::units::REFERENCE_TEMP_C
            ));
        }
        notes
    }

    /// One-line description for reports and provenance.
    pub fn describe(&self) -> String {
        format!(
            "reference log {} ({} rows{}, clock offset {:+.3} s{})",
            self.log.file,
            self.log.t_s.len(),
            if self.log.table.is_some() {
                ", one table-rate column"
            } else {
                ""
            },
            self.offset_s,
            if self.correlation.is_some() {
                ", found by cross-correlation"
            } else {
                ", given"
            }
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_names_columns_and_units() {
        let log = ReferenceLog::from_csv_str(
            "# a rate table\nt_ms,wz_deg_s,wx_deg_s,wy_deg_s\n1000,90,0,0\n1010,-90,0,0\n",
            "r.csv",
        )
        .unwrap();
        assert_eq!(log.t_s, [1.0, 1.01]);
        assert!((log.angular_rate_rad_s[0][2] - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!(log.specific_force_m_s2.is_none());
        let e = ReferenceLog::from_csv_str("t_s,wx_deg_s,wy_deg_s,wz_dg_s\n", "r.csv")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("r.csv:1:") && e.contains("did you mean `wz_deg_s`"),
            "{e}"
        );
        let e = ReferenceLog::from_csv_str("t_s,wx_deg_s,wy_deg_s\n0,0,0\n", "r.csv")
            .unwrap_err()
            .to_string();
        assert!(e.contains("all three angular rate"), "{e}");
        let e = ReferenceLog::from_csv_str(
            "t_s,wx_deg_s,wy_deg_s,wz_deg_s\n0,0,0,0\n0,0,0,0\n",
            "r.csv",
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.starts_with("r.csv:3:") && e.contains("does not increase"),
            "{e}"
        );
    }

    #[test]
    fn a_table_log_has_one_rate_column_about_its_axis() {
        let log = ReferenceLog::from_csv_str(
            "# table-axis = -y\n# latitude-deg = 40\nt_s,rate_deg_s\n0,10\n1,20\n\
             # table_axis = [1, 0, 1]\n2,30\n",
            "t.csv",
        )
        .unwrap();
        let t = log.table.as_ref().unwrap();
        let d = DEG_TO_RAD;
        assert_eq!(log.angular_rate_rad_s[0], [0.0, -10.0 * d, 0.0]);
        let w2 = Vec3::from(log.angular_rate_rad_s[2]);
        assert!((w2 - Vec3::new(1.0, 0.0, 1.0).normalize() * (30.0 * d)).norm() < 1e-15);
        assert_eq!(t.axis_lines.len(), 2);
        assert_eq!((t.axis_lines[1].0, t.axis_lines[1].1), (6, 2));
        assert!((t.gravity_m_s2 - normal_gravity_m_s2(40.0, 0.0)).abs() < 1e-12);
        assert_eq!(t.latitude_deg, Some(40.0));
        // Without an axis the rate cannot be placed: say how to give it.
        let e = ReferenceLog::from_csv_str("t_s,rate_deg_s\n0,1\n1,2\n", "t.csv")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("t.csv:2:") && e.contains("`# table-axis = +z`"),
            "{e}"
        );
        // A misspelt setting is named, not taken for a comment.
        let e = ReferenceLog::from_csv_str("# table-axs = +z\nt_s,rate_deg_s\n0,1\n1,2\n", "t.csv")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("t.csv:1:") && e.contains("did you mean `table-axis`"),
            "{e}"
        );
        // Table settings in a three-axis log.
        let e = ReferenceLog::from_csv_str(
            "# gravity-m-s2 = 9.81\nt_s,wx_deg_s,wy_deg_s,wz_deg_s\n0,0,0,1\n1,0,0,2\n",
            "t.csv",
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.starts_with("t.csv:1:") && e.contains("apply to a rate table's one-column log"),
            "{e}"
        );
        let e = ReferenceLog::from_csv_str("t_s,rate_deg_s,wz_deg_s\n0,1,1\n1,2,2\n", "t.csv")
            .unwrap_err()
            .to_string();
        assert!(e.contains("or one table rate column"), "{e}");
    }

    #[test]
    fn a_table_log_takes_its_axis_as_vertical_and_checks_the_turn() {
        let g = STANDARD_GRAVITY_M_S2;
        let seg = |kind, accel: [f64; 3], gyro: [f64; 3], t: f64| Segment {
            kind,
            start_s: t,
            end_s: t + 10.0,
            first_sample: (t * 100.0).round() as usize,
            n: 1000,
            mean_accel_m_s2: accel,
            mean_gyro_rad_s: gyro,
            std_accel_m_s2: [0.01; 3],
            std_gyro_rad_s: [0.001; 3],
        };
        let mut csv = String::from("# table-axis = +z\nt_s,rate_deg_s\n");
        for k in 0..400 {
            let t = k as f64 * 0.1;
            csv.push_str(&format!("{t},{}\n", if t < 20.0 { 0.0 } else { 30.0 }));
        }
        let log = ReferenceLog::from_csv_str(&csv, "t.csv")
            .unwrap()
            .with_offset(0.0);
        // (Only its clock is used, for the segments' conditions.)
        let series = ImuSeries {
            t_s: (0..4000).map(|k| k as f64 * 0.01).collect(),
            ..ImuSeries::default()
        };
        let w = 30f64.to_radians();
        // The unit upside down on the table: gravity along -z, so up is -z.
        let segs = [
            seg(SegmentKind::Static, [0.02, 0.0, -g], [0.0; 3], 2.0),
            seg(SegmentKind::Plateau, [0.0, 0.0, -g], [0.0, 0.0, w], 25.0),
        ];
        let truth = log.segment_truth(&series, &segs).unwrap();
        assert_eq!(truth[0].specific_force_m_s2, [0.0, 0.0, -g]);
        assert_eq!(truth[1].specific_force_m_s2, [0.0, 0.0, -g]);
        assert!((truth[1].angular_rate_rad_s[2] - w).abs() < 1e-12);
        // Without a latitude, all of Earth's rate is unknown.
        let sd = log.gyro_bias_std_rad_s(&segs).unwrap();
        assert!(
            sd.iter()
                .all(|s| (s - EARTH_RATE_RAD_S / 3f64.sqrt()).abs() < 1e-18)
        );
        // Gravity across the axis: the table is not vertical (or the axis is wrong).
        let tilted = [seg(SegmentKind::Static, [g, 0.0, 0.0], [0.0; 3], 2.0)];
        let e = log.segment_truth(&series, &tilted).unwrap_err().to_string();
        assert!(
            e.contains("segment 1 at 2.0-12.0 s: the measured specific force +x is not along the table axis +z"),
            "{e}"
        );
        // The table turning the other way about the axis than the log says.
        let reversed = [seg(
            SegmentKind::Plateau,
            [0.0, 0.0, g],
            [0.0, 0.0, -w],
            25.0,
        )];
        let e = log
            .segment_truth(&series, &reversed)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("measured -30.00 deg/s about +z, the log says 30.00 deg/s")
                && e.contains("(table-axis -z)"),
            "{e}"
        );
    }

    /// Steps of rate about z on a 100 Hz grid; the log runs on a clock `offset` ahead.
    #[test]
    fn finds_a_clock_offset_between_repeated_patterns() {
        let rate = |t: f64| -> f64 {
            // Three identical runs of 0, 20, 40, 0 deg/s, 10 s each, with 0.5 s ramps between
            // levels: a repeated pattern.
            let levels = [0.0, 20.0, 40.0, 0.0];
            let u = t.rem_euclid(40.0);
            let k = ((u / 10.0) as usize).min(3);
            let ramp = ((u - 10.0 * k as f64) / 0.5).min(1.0);
            levels[(k + 3) % 4] + (levels[k] - levels[(k + 3) % 4]) * ramp
        };
        let n = 12_000;
        let t_s: Vec<f64> = (0..n).map(|i| i as f64 * 0.01).collect();
        let series = ImuSeries {
            gyro_rad_s: t_s
                .iter()
                .map(|&t| [0.003, -0.002, rate(t).to_radians() * 1.01 + 0.01])
                .collect(),
            accel_m_s2: vec![[0.0, 0.0, 9.8]; n],
            t_s: t_s.clone(),
            ..ImuSeries::default()
        };
        let offset = 1234.56;
        let mut csv = String::from("t_s,wx_deg_s,wy_deg_s,wz_deg_s\n");
        for t in (0..n).map(|i| i as f64 * 0.02 - 3.0) {
            csv.push_str(&format!("{},0,0,{}\n", t + offset, rate(t)));
        }
        let log = ReferenceLog::from_csv_str(&csv, "r.csv").unwrap();
        let a = log.align(&series).unwrap();
        assert!((a.offset_s - offset).abs() < 0.005, "{}", a.offset_s);
        assert!(a.correlation.unwrap() > 0.95);
    }
}
