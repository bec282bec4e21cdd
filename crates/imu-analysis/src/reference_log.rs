//! Reference logs: a time-stamped record of the true input in the sensor frame, such as a rate
//! table's log, as a CSV file whose header names the columns and their units:
//!
//! ```text
//! t_s,wx_deg_s,wy_deg_s,wz_deg_s,fx_m_s2,fy_m_s2,fz_m_s2
//! 12.00,0.0,0.0,20.0,0.0,0.0,9.80665
//! ```
//!
//! Time: `t_s`, `t_ms` or `t_ns` (any origin: the log's own clock). Angular rate, required:
//! `wx_rad_s`/`wx_deg_s` and likewise `wy_*`, `wz_*`. Specific force, optional but needed for
//! the accelerometer fit: `fx_m_s2`/`fx_g` and likewise. A log of a table's rate about one
//! axis is written as three columns with the other two zero; the rate is the sensor's true
//! inertial rate, so a table log lacks Earth's rate (15 deg/h), which matters only for gyros
//! stable to a few deg/h. Lines starting with `#` are comments.
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
use imu_model::units::{DEG_TO_RAD, STANDARD_GRAVITY_M_S2};

use crate::ImuSeries;
use crate::plan::{did_you_mean, format_direction};
use crate::reference::SegmentTruth;
use crate::segment::{Segment, SegmentKind};

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
}

const COLUMNS: [&str; 15] = [
    "t_s", "t_ms", "t_ns", "wx_rad_s", "wy_rad_s", "wz_rad_s", "wx_deg_s", "wy_deg_s", "wz_deg_s",
    "fx_m_s2", "fy_m_s2", "fz_m_s2", "fx_g", "fy_g", "fz_g",
];

fn column(name: &str) -> Option<Column> {
    let axis = |c: char| "xyz".find(c);
    Some(match name {
        "t_s" => Column::Time(1.0),
        "t_ms" => Column::Time(1e-3),
        "t_ns" => Column::Time(1e-9),
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
        let mut columns: Option<Vec<Column>> = None;
        let mut log = ReferenceLog {
            file: file.to_string(),
            t_s: Vec::new(),
            angular_rate_rad_s: Vec::new(),
            specific_force_m_s2: None,
        };
        let mut force = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let n = i + 1;
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
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
                                 _deg_s, specific force f{{x,y,z}}_m_s2 or _g, e.g. \
                                 `{EXAMPLE}`{}",
                                did_you_mean(&name, &COLUMNS)
                            ),
                        )
                    })?;
                    let same = |o: &Column| match (o, &c) {
                        (Column::Time(_), Column::Time(_)) => true,
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
                if has(&|c| matches!(c, Column::Time(_))) != 1
                    || has(&|c| matches!(c, Column::Rate(..))) != 3
                {
                    return Err(err(
                        n,
                        format!(
                            "the header needs a time column and all three angular rate \
                             columns, e.g. `{EXAMPLE}`"
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
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
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
        let correlation = pearson(&pairs);
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

fn pearson(pairs: &[(f64, f64)]) -> f64 {
    let n = pairs.len() as f64;
    if pairs.len() < 2 {
        return f64::NAN;
    }
    let (ma, mb) = (
        pairs.iter().map(|p| p.0).sum::<f64>() / n,
        pairs.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (a, b) in pairs {
        sab += (a - ma) * (b - mb);
        saa += (a - ma).powi(2);
        sbb += (b - mb).powi(2);
    }
    sab / (saa * sbb).sqrt()
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
            let f = match &log.specific_force_m_s2 {
                Some(f) => {
                    let mut m = Vec3::zeros();
                    for v in &f[lo..hi] {
                        m += Vec3::from(*v) / n;
                    }
                    m
                }
                None => {
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

    /// Remarks for the report: the offset and how it was found.
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
        if series.temp.is_empty() {
            notes.push(format!(
                "the recording has no temperature readings: {} deg C assumed; temperature \
                 effects cannot be fitted",
                crate::plan::FALLBACK_TEMP_C
            ));
        }
        notes
    }

    /// One-line description for reports and provenance.
    pub fn describe(&self) -> String {
        format!(
            "reference log {} ({} rows, clock offset {:+.3} s{})",
            self.log.file,
            self.log.t_s.len(),
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
