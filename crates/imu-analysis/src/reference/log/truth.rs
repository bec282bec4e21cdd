//! A reference log's truth over segments: mean specific force and rate, and what a table log
//! cannot know of the gyro's input.

use super::*;

impl AlignedLog {
    /// The mean reference over each segment's time range (temperature and time since
    /// power-on from the recording), after checking that the log matches the measurements.
    pub fn segment_truth(
        &self,
        series: &ImuSeries,
        segments: &[Segment],
    ) -> Result<Vec<SegmentTruth>, ReferenceLogError> {
        let mut problems = Vec::new();
        let mut out = Vec::with_capacity(segments.len());
        for (k, s) in segments.iter().enumerate() {
            if let Some(truth) = self.one_segment_truth(series, k, s, &mut problems) {
                out.push(truth);
            }
        }
        if problems.is_empty() {
            return Ok(out);
        }
        Err(ReferenceLogError::Segments {
            file: self.log.file.clone(),
            summary: format!(
                "the log does not give the true input of {} of {} segments",
                problems.len(),
                segments.len()
            ),
            problems,
        })
    }

    /// The truth over segment `k` (`s`), with every disagreement with the measurements added
    /// to `problems`; None when the log cannot give it.
    fn one_segment_truth(
        &self,
        series: &ImuSeries,
        k: usize,
        s: &Segment,
        problems: &mut Vec<String>,
    ) -> Option<SegmentTruth> {
        let log = &self.log;
        let head = format!("segment {} at {:.1}-{:.1} s", k + 1, s.start_s, s.end_s);
        let rows = self.rows(s);
        if rows.is_empty() {
            let (ref_lo, ref_hi) = (
                log.t_s[0] - self.offset_s,
                log.t_s[log.t_s.len() - 1] - self.offset_s,
            );
            problems.push(format!(
                "{head}: no log rows (the log covers {ref_lo:.1}-{ref_hi:.1} s on the \
                 recording's clock)"
            ));
            return None;
        }
        let mut w = mean_of_rows(&log.angular_rate_rad_s[rows.clone()]);
        let logged_f = log
            .specific_force_m_s2
            .as_ref()
            .map(|f| mean_of_rows(&f[rows.clone()]));
        let table_up = match &log.table {
            Some(t) => Some(table_up(t, s, &head, rows, logged_f, &mut w, problems)?),
            None => None,
        };
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
                return None;
            }
        };
        check_against_measurement(s, &head, f, w, problems);
        let (temp_c, time_since_power_on_s) =
            crate::reference::segment_truth::recording_conditions(series, s, None, 0.0);
        Some(SegmentTruth {
            specific_force_m_s2: f.into(),
            angular_rate_rad_s: w.into(),
            temp_c,
            time_since_power_on_s,
        })
    }

    /// The log rows over segment `s` (on the recording's clock).
    pub(super) fn rows(&self, s: &Segment) -> std::ops::Range<usize> {
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
    pub fn notes(&self, series: &ImuSeries) -> Vec<crate::note::Note> {
        use crate::note::{Note, TempAssumed};
        let mut notes = vec![Note::LogClock {
            file: self.log.file.clone(),
            offset_s: self.offset_s,
            correlation: self.correlation,
        }];
        if let Some(t) = &self.log.table {
            notes.push(Note::TableAxes {
                file: self.log.file.clone(),
                axes: t
                    .axis_lines
                    .iter()
                    .map(|(line, _, a)| (*line, *a))
                    .collect(),
                gravity_source: self
                    .log
                    .specific_force_m_s2
                    .is_none()
                    .then(|| t.gravity_source.clone()),
            });
            notes.push(Note::TableEarthRate {
                latitude_deg: t.latitude_deg,
            });
        }
        if series.temp.is_empty() {
            notes.push(Note::NoTemperature {
                assumed_c: imu_model::units::REFERENCE_TEMP_C,
                source: TempAssumed::Log,
            });
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

/// The mean of a segment's log rows (each row divided by the count, then summed, in order).
fn mean_of_rows(rows: &[[f64; 3]]) -> Vec3 {
    let n = rows.len() as f64;
    let mut m = Vec3::zeros();
    for v in rows {
        m += Vec3::from(*v) / n;
    }
    m
}

/// A table log over one segment: the segment's table axis, which way is up (along the axis
/// unless the log gives the specific force `logged_f`), and Earth's vertical rate added to
/// `w`. Returns (up, gravity); None, with the problem added, when the segment's table axis or
/// its up direction cannot be known.
fn table_up(
    t: &TableLog,
    s: &Segment,
    head: &str,
    rows: std::ops::Range<usize>,
    logged_f: Option<Vec3>,
    w: &mut Vec3,
    problems: &mut Vec<String>,
) -> Option<(Vec3, f64)> {
    let axes = &t.axis_sensor[rows];
    let a = Vec3::from(axes[0]);
    if axes.iter().any(|x| Vec3::from(*x) != a) {
        problems.push(format!(
            "{head}: the table axis changes within the segment (a `# table-axis` \
             line among its rows): put it where the unit was re-mounted"
        ));
        return None;
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
            return None;
        }
        None => a * along.signum(),
    };
    if let Some(lat) = t.latitude_deg {
        *w += up * (EARTH_RATE_RAD_S * lat.to_radians().sin());
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
    Some((up, t.gravity_m_s2))
}

/// Checks a segment's reference (specific force `f`, rate `w`) against its measurements: the
/// rate magnitude on a plateau, the direction of up when static.
fn check_against_measurement(
    s: &Segment,
    head: &str,
    f: Vec3,
    w: Vec3,
    problems: &mut Vec<String>,
) {
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
}
