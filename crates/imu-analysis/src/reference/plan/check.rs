//! Matching a plan to a recording: its segmentation (detected or by hand, skip steps), the
//! alignment of expected and detected segments, the checks of each match, and each segment's
//! true input (gravity, rates, Earth's rate and what the plan leaves unknown of it).

use super::*;
use crate::note::{Note, TempAssumed};

impl Plan {
    /// True when the plan gives every segment's time range by hand.
    pub fn explicit_windows(&self) -> bool {
        self.entries.iter().all(|e| e.window_s.is_some())
    }

    /// Number of entries of one kind (skip entries not counted).
    pub fn count(&self, kind: SegmentKind) -> usize {
        self.entries
            .iter()
            .filter(|e| e.kind == kind && !e.skip)
            .count()
    }

    /// Number of skip entries.
    pub fn count_skips(&self) -> usize {
        self.entries.iter().filter(|e| e.skip).count()
    }

    /// The segments of `series`: detected, or, when the plan gives time ranges, exactly those
    /// (detection still runs for its thresholds, which the report shows). Detected segments
    /// matched to a skip step are moved to [`Segmentation::skipped`].
    pub fn segmentation(
        &self,
        series: &ImuSeries,
        opts: &SegmentOptions,
    ) -> Result<Segmentation, PlanSegmentationError> {
        let mut seg = crate::segment::detect(series, opts)?;
        if !self.explicit_windows() {
            if self.count_skips() > 0 {
                let pairs = self.check(&seg.segments, true)?;
                let skipped: Vec<(usize, usize)> = pairs
                    .into_iter()
                    .filter(|(e, _)| self.entries[*e].skip)
                    .collect();
                for &(e, s) in skipped.iter().rev() {
                    let segment = seg.segments.remove(s);
                    seg.skipped.insert(
                        0,
                        crate::segment::SkippedSegment {
                            number: s + 1,
                            by: self.entries[e].name(),
                            segment,
                        },
                    );
                }
            }
            return Ok(seg);
        }
        let mut segments = Vec::with_capacity(self.entries.len());
        for e in &self.entries {
            let [a, b] = e.window_s.expect("explicit");
            let lo = series.t_s.partition_point(|&t| t < a);
            let hi = series.t_s.partition_point(|&t| t <= b);
            if hi < lo + 2 {
                let end = series.t_s.last().copied().unwrap_or(0.0);
                return Err(PlanMismatch {
                    file: self.file.clone(),
                    summary: "a time range given by hand holds no data".into(),
                    problems: vec![format!(
                        "{}: {a}-{b} s holds {} samples (the recording spans 0-{end:.1} s)",
                        e.name(),
                        hi.saturating_sub(lo)
                    )],
                }
                .into());
            }
            segments.push(Segment::from_samples(series, lo..hi, e.kind));
        }
        seg.segments = segments;
        Ok(seg)
    }

    /// The true input of each of `segments` (which must follow the plan, see [`PlanMismatch`]).
    pub fn segment_truth(
        &self,
        series: &ImuSeries,
        segments: &[Segment],
    ) -> Result<Vec<SegmentTruth>, PlanMismatch> {
        Ok(self
            .resolve(series, segments)?
            .into_iter()
            .map(|r| r.truth)
            .collect())
    }

    /// What the plan leaves unknown about the true input of `segments`, and notes.
    pub fn caveats(
        &self,
        series: &ImuSeries,
        segments: &[Segment],
    ) -> Result<PlanCaveats, PlanMismatch> {
        let resolved = self.resolve(series, segments)?;
        let mut notes = vec![Note::PlanGravity {
            file: self.file.clone(),
            gravity_source: self.gravity_source.clone(),
        }];
        let mut sd = [0.0f64; 3];
        let mut n_unknown = 0;
        for r in &resolved {
            if r.rate_std_rad_s.iter().any(|s| *s > 0.0) {
                n_unknown += 1;
            }
            for (m, x) in sd.iter_mut().zip(r.rate_std_rad_s) {
                *m = m.max(x);
            }
        }
        let gyro_bias_std_rad_s = (n_unknown > 0).then_some(sd);
        if n_unknown > 0 {
            notes.push(Note::EarthRateUnknown {
                unknown: n_unknown,
                segments: resolved.len(),
                max_std_rad_s: sd,
                g_sensitivity_bound_rad_s_per_m_s2: EARTH_RATE_RAD_S
                    * self.latitude_deg.map_or(1.0, |l| l.to_radians().cos())
                    / self.gravity_m_s2,
            });
        }
        if series.temp.is_empty() {
            notes.push(Note::NoTemperature {
                assumed_c: self.temp_c.unwrap_or(REFERENCE_TEMP_C),
                source: if self.temp_c.is_some() {
                    TempAssumed::PlanTempC
                } else {
                    TempAssumed::PlanDefault
                },
            });
        }
        Ok(PlanCaveats {
            gyro_bias_std_rad_s,
            notes,
        })
    }

    /// Match, check and compute the truth of every segment.
    pub(super) fn resolve(
        &self,
        series: &ImuSeries,
        segments: &[Segment],
    ) -> Result<Vec<Resolved>, PlanMismatch> {
        // The segments skip steps matched are gone (see `segmentation`): match the rest.
        let pairs = self.check(segments, false)?;
        Ok(pairs
            .into_iter()
            .map(|(e, s)| self.truth_of(&self.entries[e], &segments[s], series))
            .collect())
    }

    /// Problems of matching entry `e` with segment `s` (empty if compatible).
    /// A plateau's rate is checked after removing `rest_rad_s`, the gyro's reading at rest (raw
    /// gyros read several deg/s when still: a 20 deg/s step reading 17.7 deg/s is on plan).
    pub(super) fn problems(
        &self,
        e: &PlanEntry,
        s: &Segment,
        index: usize,
        rest_rad_s: Vec3,
    ) -> Vec<String> {
        if e.skip {
            return Vec::new();
        }
        let head = format!(
            "{}: segment {} at {:.1}-{:.1} s",
            e.name(),
            index + 1,
            s.start_s,
            s.end_s
        );
        let kind = |k: SegmentKind| match k {
            SegmentKind::Static => "static",
            SegmentKind::Plateau => "a rate plateau",
        };
        if e.kind != s.kind {
            return vec![format!(
                "{head}: the plan expects {} but the segment is {} (mean rate {:.2} deg/s)",
                kind(e.kind),
                kind(s.kind),
                s.mean_gyro().norm().to_degrees()
            )];
        }
        let mut out = Vec::new();
        out.extend(self.up_problem(e, s, &head));
        out.extend(self.rate_problem(e, s, &head, rest_rad_s));
        out
    }

    /// The problem of segment `s`'s measured up direction against entry `e`'s, if any.
    fn up_problem(&self, e: &PlanEntry, s: &Segment, head: &str) -> Option<String> {
        let tol = self.direction_tolerance_deg;
        let planned_f = self.specific_force_dir(e);
        let measured_f = s.mean_accel();
        if let Some(pf) = planned_f
            && measured_f.norm() > 0.0
        {
            let angle = pf.angle(&measured_f).to_degrees();
            if angle > tol {
                return Some(format!(
                    "{head}: measured up {} is {angle:.1} deg from the planned {} (tolerance \
                     {tol} deg)",
                    format_direction(&measured_f.normalize()),
                    format_direction(&pf),
                ));
            }
        }
        None
    }

    /// The problem of plateau `s`'s rate (minus `rest_rad_s`) against entry `e`'s planned rate
    /// and axis, if any: the rate first, the axis only when the rate is on plan.
    fn rate_problem(
        &self,
        e: &PlanEntry,
        s: &Segment,
        head: &str,
        rest_rad_s: Vec3,
    ) -> Option<String> {
        let tol = self.direction_tolerance_deg;
        let axis = e.axis_sensor.map(Vec3::from)?;
        let nominal_deg_s = e.rate_rad_s.to_degrees();
        let w = s.mean_gyro() - rest_rad_s;
        let about_deg_s = w.dot(&axis).to_degrees();
        let rest_deg_s = rest_rad_s.norm().to_degrees();
        let after_rest = if rest_deg_s >= 0.05 {
            format!(" after removing the rest reading of {rest_deg_s:.2} deg/s")
        } else {
            String::new()
        };
        let off_percent = 100.0 * (about_deg_s - nominal_deg_s).abs() / nominal_deg_s.abs();
        if about_deg_s.signum() != nominal_deg_s.signum()
            || off_percent > self.rate_tolerance_percent
        {
            return Some(format!(
                "{head}: measured {about_deg_s:.2} deg/s about {}{after_rest}, planned \
                 {nominal_deg_s} deg/s ({off_percent:.0} % off, tolerance {} %)",
                format_direction(&axis),
                self.rate_tolerance_percent
            ));
        }
        let planned_axis = axis * nominal_deg_s.signum();
        let angle = planned_axis.angle(&w).to_degrees();
        (angle > tol).then(|| {
            format!(
                "{head}: measured rotation axis {} is {angle:.1} deg from the planned {} \
                 (tolerance {tol} deg)",
                format_direction(&w.normalize()),
                format_direction(&planned_axis)
            )
        })
    }

    /// Unit direction of the planned mean specific force, when gravity dominates it.
    pub(super) fn specific_force_dir(&self, e: &PlanEntry) -> Option<Vec3> {
        let up = e.up();
        match e.axis_sensor.map(Vec3::from) {
            None => Some(up),
            Some(a) => {
                let along = up.dot(&a);
                (along.abs() > 0.5).then(|| a * along.signum())
            }
        }
    }

    /// Align entries (with or without the skip entries) with segments (a Needleman-Wunsch
    /// alignment: a position too many or too few shows as a gap where it happens instead of
    /// shifting every later match), then check every matched pair. Returns `(entry, segment)`
    /// index pairs covering both lists (entry indices into `self.entries`).
    pub(super) fn check(
        &self,
        segments: &[Segment],
        with_skips: bool,
    ) -> Result<Vec<(usize, usize)>, PlanMismatch> {
        let used: Vec<usize> = (0..self.entries.len())
            .filter(|&e| with_skips || !self.entries[e].skip)
            .collect();
        let ne = used.len();
        let rest = crate::segment::rest_rate(segments);
        let path = self.align_segments(segments, &used, rest);

        let mut problems = Vec::new();
        let mut pairs = Vec::new();
        // The segment that came last before a gap, for saying where a missing one should be.
        let mut last_segment: Option<usize> = None;
        for step in &path {
            match *step {
                AlignStep::Pair(e, s) => {
                    problems.extend(self.problems(&self.entries[e], &segments[s], s, rest));
                    pairs.push((e, s));
                    last_segment = Some(s);
                }
                AlignStep::NoSegment(e) => {
                    problems.push(missing_segment_problem(
                        &self.entries[e].name(),
                        segments,
                        last_segment,
                    ));
                }
                AlignStep::NoEntry(s) => {
                    problems.push(unplanned_segment_problem(s, &segments[s]));
                    last_segment = Some(s);
                }
            }
        }
        if problems.is_empty() {
            return Ok(pairs);
        }
        let summary = self.mismatch_summary(segments, ne, with_skips, problems.len());
        Err(PlanMismatch {
            file: self.file.clone(),
            summary,
            problems,
        })
    }

    /// The Needleman-Wunsch alignment of the `used` entries with `segments`, in order
    /// (entry indices into `self.entries`).
    fn align_segments(
        &self,
        segments: &[Segment],
        used: &[usize],
        rest_rad_s: Vec3,
    ) -> Vec<AlignStep> {
        let (ne, ns) = (used.len(), segments.len());
        let cost = |e: usize, s: usize| -> f64 {
            let (pe, sg) = (&self.entries[used[e]], &segments[s]);
            if pe.skip {
                0.0
            } else if pe.kind != sg.kind {
                1.8
            } else if self.problems(pe, sg, s, rest_rad_s).is_empty() {
                0.0
            } else {
                1.0
            }
        };
        const GAP: f64 = 1.0;
        let mut d = vec![vec![0.0f64; ns + 1]; ne + 1];
        for (i, row) in d.iter_mut().enumerate() {
            row[0] = i as f64 * GAP;
        }
        for (j, x) in d[0].iter_mut().enumerate() {
            *x = j as f64 * GAP;
        }
        for i in 1..=ne {
            for j in 1..=ns {
                d[i][j] = (d[i - 1][j - 1] + cost(i - 1, j - 1))
                    .min(d[i - 1][j] + GAP)
                    .min(d[i][j - 1] + GAP);
            }
        }
        // Trace back, preferring matches; collect the alignment in order.
        let mut path = Vec::new();
        let (mut i, mut j) = (ne, ns);
        while i > 0 || j > 0 {
            if i > 0 && j > 0 && (d[i][j] - (d[i - 1][j - 1] + cost(i - 1, j - 1))).abs() < 1e-9 {
                path.push(AlignStep::Pair(used[i - 1], j - 1));
                i -= 1;
                j -= 1;
            } else if i > 0 && (j == 0 || (d[i][j] - (d[i - 1][j] + GAP)).abs() < 1e-9) {
                path.push(AlignStep::NoSegment(used[i - 1]));
                i -= 1;
            } else {
                path.push(AlignStep::NoEntry(j - 1));
                j -= 1;
            }
        }
        path.reverse();
        path
    }

    /// The headline of a failed check: the counts when the plan expects `ne` segments and
    /// the recording has another number, else the number of mismatches.
    fn mismatch_summary(
        &self,
        segments: &[Segment],
        ne: usize,
        with_skips: bool,
        n_problems: usize,
    ) -> String {
        let ns = segments.len();
        let count = |k: SegmentKind| segments.iter().filter(|s| s.kind == k).count();
        if ne != ns {
            let skips = if with_skips && self.count_skips() > 0 {
                format!(", {} skip", self.count_skips())
            } else {
                String::new()
            };
            format!(
                "the plan expects {ne} segments ({} static, {} plateau{skips}), the recording has \
                 {ns} ({} static, {} plateau); fix the plan, or give the time ranges by hand \
                 (start-s/end-s, windows-s)",
                self.count(SegmentKind::Static),
                self.count(SegmentKind::Plateau),
                count(SegmentKind::Static),
                count(SegmentKind::Plateau),
            )
        } else {
            format!(
                "the recording does not follow the plan ({ne} segments each; {} {})",
                n_problems,
                if n_problems == 1 {
                    "mismatch"
                } else {
                    "mismatches"
                }
            )
        }
    }

    /// Earth's rate in sensor axes for an orientation, and the per-axis standard deviation of
    /// what the plan leaves unknown of it.
    pub(super) fn earth_rate(&self, up: &Vec3, north: Option<&Vec3>) -> (Vec3, [f64; 3]) {
        let om = EARTH_RATE_RAD_S;
        match (self.latitude_deg, north) {
            (Some(lat), Some(n)) => {
                let l = lat.to_radians();
                ((n * l.cos() + up * l.sin()) * om, [0.0; 3])
            }
            (Some(lat), None) => (
                up * imu_model::earth::earth_rate_split_rad_s(lat).0,
                std::array::from_fn(|a| unknown_heading_variance_rad2_s2(Some(lat), up[a]).sqrt()),
            ),
            (None, _) => (
                Vec3::zeros(),
                [unknown_heading_variance_rad2_s2(None, 0.0).sqrt(); 3],
            ),
        }
    }

    pub(super) fn truth_of(&self, e: &PlanEntry, s: &Segment, series: &ImuSeries) -> Resolved {
        let g = self.gravity_m_s2;
        let up = e.up();
        let north = e.north_sensor.map(Vec3::from);
        let (earth, earth_sd) = self.earth_rate(&up, north.as_ref());
        let (f, w, sd) = match e.axis_sensor.map(Vec3::from) {
            None => (up * g, earth, earth_sd),
            Some(a) => {
                // The table axis keeps its direction in space, so gravity's and Earth rate's
                // components along it hold; the perpendicular parts turn with the table and
                // average out over whole turns. What is left of Earth rate's perpendicular part
                // after a partial turn (at most |mean of a unit phasor over the angle turned|
                // = 2/angle) is carried as uncertainty. Gravity's perpendicular part is zero
                // for a vertical table axis (the usual set-up); otherwise the along-axis mean
                // is an approximation (the accel is not fitted to plateaus).
                let along_sd = (0..3)
                    .map(|b| (a[b] * earth_sd[b]).powi(2))
                    .sum::<f64>()
                    .sqrt();
                let turned_rad = (e.rate_rad_s * (s.end_s - s.start_s)).abs();
                let perp = EARTH_RATE_RAD_S * (2.0 / turned_rad.max(1e-9)).min(1.0);
                let sd = std::array::from_fn(|b| {
                    let along = a[b].abs() * along_sd;
                    let across = perp * ((1.0 - a[b] * a[b]).max(0.0) / 2.0).sqrt();
                    along.hypot(across)
                });
                (a * (g * up.dot(&a)), a * (e.rate_rad_s + earth.dot(&a)), sd)
            }
        };
        let (temp_c, time_since_power_on_s) = crate::reference::segment_truth::recording_conditions(
            series,
            s,
            self.temp_c,
            self.powered_on_before_s,
        );
        Resolved {
            truth: SegmentTruth {
                specific_force_m_s2: f.into(),
                angular_rate_rad_s: w.into(),
                temp_c,
                time_since_power_on_s,
            },
            rate_std_rad_s: sd,
        }
    }

    /// One-line description for reports and provenance.
    pub fn describe(&self) -> String {
        format!(
            "test plan {}{} ({} segments: {} static, {} rate plateaus{}{})",
            self.file,
            self.name
                .as_deref()
                .map(|n| format!(" `{n}`"))
                .unwrap_or_default(),
            self.entries.len(),
            self.count(SegmentKind::Static),
            self.count(SegmentKind::Plateau),
            match self.count_skips() {
                0 => String::new(),
                k => format!(", {k} skipped"),
            },
            if self.explicit_windows() {
                ", time ranges given by hand"
            } else {
                ""
            }
        )
    }
}

/// A matched segment's truth and the unknown part of its angular rate.
pub(super) struct Resolved {
    pub(super) truth: SegmentTruth,
    pub(super) rate_std_rad_s: [f64; 3],
}

/// One step of the alignment of plan entries with segments.
enum AlignStep {
    /// Entry and segment matched.
    Pair(usize, usize),
    /// An entry without a segment.
    NoSegment(usize),
    /// A segment without an entry.
    NoEntry(usize),
}

/// `entry` has no segment: where it was expected, after the `last_segment` matched.
fn missing_segment_problem(
    entry: &str,
    segments: &[Segment],
    last_segment: Option<usize>,
) -> String {
    let after = match last_segment {
        Some(s) => format!(
            "after segment {} ({:.1}-{:.1} s)",
            s + 1,
            segments[s].start_s,
            segments[s].end_s
        ),
        None => "before the first segment".into(),
    };
    let next = segments.get(last_segment.map_or(0, |s| s + 1)).map_or_else(
        || " (the recording has no more segments)".to_string(),
        |n| {
            format!(
                " and before the segment at {:.1}-{:.1} s",
                n.start_s, n.end_s
            )
        },
    );
    format!("{entry} has no segment: expected {after}{next}")
}

/// Segment `s` (`sg`) is in no plan entry: what it measured.
fn unplanned_segment_problem(s: usize, sg: &Segment) -> String {
    let what = match sg.kind {
        SegmentKind::Static => format!(
            "static, measured up {}",
            format_direction(&sg.mean_accel().normalize())
        ),
        SegmentKind::Plateau => {
            let w = sg.mean_gyro();
            format!(
                "rate plateau, {:.2} deg/s about {}",
                w.norm().to_degrees(),
                format_direction(&w.normalize())
            )
        }
    };
    format!(
        "segment {} at {:.1}-{:.1} s ({what}) is not in the plan",
        s + 1,
        sg.start_s,
        sg.end_s
    )
}
