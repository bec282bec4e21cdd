//! Automatic detection of static intervals and constant-rate plateaus in an IMU series, the
//! input of the calibration fits (Aslan & Saranli 3.1.2, 3.2.2, 3.2.3: multi-position static
//! tests and rate-table plateaus).
//!
//! A centred moving window gives, at every sample, the standard deviation of the accel and gyro
//! vectors (root of the summed per-axis variances, so a slow rotation that keeps |g| constant
//! still shows up as motion). Quiet samples are those whose window std lies below a threshold
//! chosen from the data: a multiple of a low quantile of the window std over the whole
//! recording (the noise floor of the quietest stretches). Runs of quiet samples are trimmed at
//! both ends (less for a short run, down to the window's own margin), kept when long enough,
//! and classified as static or as a rate plateau relative to the gyro's reading at rest: raw
//! MEMS gyros read several deg/s when still, so a fixed threshold on |mean rate| would call
//! every still pose a plateau. The reading at rest is estimated from the quiet runs themselves
//! (the largest group whose mean rates agree, among those slow enough to be an offset), and
//! reported with the segments.

use imu_model::Vec3;

use crate::ImuSeries;

/// Settings of [`detect`].
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct SegmentOptions {
    /// Length of the centred moving window, s.
    pub window_s: f64,
    /// Quantile (0..1) of the window std taken as the noise floor.
    pub floor_quantile: f64,
    /// Threshold = `threshold_factor` x noise floor, for accel and gyro separately.
    pub threshold_factor: f64,
    /// Time cut from each end of a quiet run (which already stops half a window short of the motion), s.
    pub trim_s: f64,
    /// Shortest segment kept (after trimming), s. A quiet run shorter than this plus both
    /// trims is trimmed less (never below the half window the detector already keeps away
    /// from motion), so still poses down to `min_duration_s + window_s` are used.
    pub min_duration_s: f64,
    /// |mean gyro - reading at rest| above which a quiet run is a rate plateau instead of
    /// static, rad/s.
    pub plateau_min_rate_rad_s: f64,
    /// Largest |mean gyro| of a still run that can be a gyro offset (raw MEMS gyros: up to
    /// ~10 deg/s), rad/s: the reading at rest is looked for among the quiet runs below it.
    #[serde(default = "default_max_rest_rate_rad_s")]
    pub max_rest_rate_rad_s: f64,
    /// Shortest rate plateau kept (after the full trim), s: a table holds its rate for many
    /// seconds, so a brief steady rotation is a move, not a plateau.
    #[serde(default = "default_min_plateau_s")]
    pub min_plateau_s: f64,
}

fn default_min_plateau_s() -> f64 {
    3.0
}

/// 20 deg/s: twice the largest offset of an uncompensated MEMS gyro, below the slowest plateaus
/// of the paper's rate-table test.
fn default_max_rest_rate_rad_s() -> f64 {
    20f64.to_radians()
}

impl SegmentOptions {
    /// The shortest still pose that yields a segment, s (the minimum duration plus the window
    /// the detector loses at the two motions around it).
    pub fn shortest_still_s(&self) -> f64 {
        self.min_duration_s + self.window_s
    }
}

impl Default for SegmentOptions {
    fn default() -> Self {
        SegmentOptions {
            window_s: 1.0,
            floor_quantile: 0.1,
            threshold_factor: 2.0,
            trim_s: 0.5,
            min_duration_s: 1.0,
            // 3 deg/s from the reading at rest: far above the noise of a 1 s mean and Earth rate.
            plateau_min_rate_rad_s: 0.05,
            max_rest_rate_rad_s: default_max_rest_rate_rad_s(),
            min_plateau_s: default_min_plateau_s(),
        }
    }
}

/// Kind of a detected segment.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SegmentKind {
    /// No rotation beyond Earth rate and bias: a static position.
    Static,
    /// A steady, large angular rate (rate-table plateau).
    Plateau,
}

/// One detected interval with its statistics (sensor frame).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Segment {
    /// Static or plateau.
    pub kind: SegmentKind,
    /// Time of the first sample, s (series time base).
    pub start_s: f64,
    /// Time of the last sample, s.
    pub end_s: f64,
    /// Index of the first sample in the series.
    pub first_sample: usize,
    /// Number of samples (`first_sample .. first_sample + n`).
    pub n: usize,
    /// Mean specific force, m/s^2.
    pub mean_accel_m_s2: [f64; 3],
    /// Mean angular rate, rad/s.
    pub mean_gyro_rad_s: [f64; 3],
    /// Per-axis sample standard deviation of the accel, m/s^2.
    pub std_accel_m_s2: [f64; 3],
    /// Per-axis sample standard deviation of the gyro, rad/s.
    pub std_gyro_rad_s: [f64; 3],
}

impl Segment {
    /// Sample range in the series.
    pub fn range(&self) -> std::ops::Range<usize> {
        self.first_sample..self.first_sample + self.n
    }

    /// Mean specific force as a vector, m/s^2.
    pub fn mean_accel(&self) -> Vec3 {
        Vec3::from(self.mean_accel_m_s2)
    }

    /// Mean angular rate as a vector, rad/s.
    pub fn mean_gyro(&self) -> Vec3 {
        Vec3::from(self.mean_gyro_rad_s)
    }

    /// A segment of `kind` over the samples `range` of `series` (given by hand rather than
    /// detected), with its statistics. `range` must be non-empty and inside the series.
    pub fn from_samples(
        series: &ImuSeries,
        range: std::ops::Range<usize>,
        kind: SegmentKind,
    ) -> Segment {
        let (mean_a, std_a) = stats(&series.accel_m_s2[range.clone()]);
        let (mean_g, std_g) = stats(&series.gyro_rad_s[range.clone()]);
        Segment {
            kind,
            start_s: series.t_s[range.start],
            end_s: series.t_s[range.end - 1],
            first_sample: range.start,
            n: range.len(),
            mean_accel_m_s2: mean_a,
            mean_gyro_rad_s: mean_g,
            std_accel_m_s2: std_a,
            std_gyro_rad_s: std_g,
        }
    }
}

/// What [`detect`] found, with the thresholds it chose.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Segmentation {
    /// Segments in time order.
    pub segments: Vec<Segment>,
    /// Chosen accel window-std threshold, m/s^2.
    pub accel_std_threshold_m_s2: f64,
    /// Chosen gyro window-std threshold, rad/s.
    pub gyro_std_threshold_rad_s: f64,
    /// Window length in samples.
    pub window_samples: usize,
    /// The options used.
    pub options: SegmentOptions,
    /// Detected segments left out of the fit (by a plan's skip step), in time order.
    #[serde(default)]
    pub skipped: Vec<SkippedSegment>,
    /// The gyro's reading at rest estimated from the quiet runs (the offset plateaus are
    /// measured from), rad/s; None when no quiet run was slow enough to be one (then 0 is used).
    #[serde(default)]
    pub rest_rate_rad_s: Option<[f64; 3]>,
    /// Quiet runs too short to use, in time order.
    #[serde(default)]
    pub dropped: Vec<DroppedRun>,
}

/// A quiet run that did not become a segment.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DroppedRun {
    /// Time of its first quiet sample, s.
    pub start_s: f64,
    /// Time of its last quiet sample, s.
    pub end_s: f64,
    /// Why it was dropped.
    pub reason: DropReason,
}

/// Why a quiet run was not used.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DropReason {
    /// Shorter than the minimum duration even untrimmed.
    TooShort,
    /// A steady rotation shorter than a rate plateau.
    ShortPlateau,
}

impl DroppedRun {
    /// `0.8 s at 12.0 s (shorter than 1 s)`, for notes.
    pub fn describe(&self, opts: &SegmentOptions) -> String {
        let what = match self.reason {
            DropReason::TooShort => format!(
                "shorter than {} s (a still pose needs {} s)",
                opts.min_duration_s,
                opts.shortest_still_s()
            ),
            DropReason::ShortPlateau => format!(
                "a steady rotation shorter than a {} s rate plateau",
                opts.min_plateau_s
            ),
        };
        format!(
            "{:.1} s at {:.1} s ({what})",
            self.end_s - self.start_s,
            self.start_s
        )
    }
}

/// A detected segment that is not fitted.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SkippedSegment {
    /// 1-based position among the detected segments.
    pub number: usize,
    /// What skipped it (the plan step).
    pub by: String,
    /// The segment.
    pub segment: Segment,
}

impl SkippedSegment {
    /// `segment 5 at 120.0-180.0 s (static)`, for notes.
    pub fn describe(&self) -> String {
        let s = &self.segment;
        format!(
            "segment {} at {:.1}-{:.1} s ({})",
            self.number,
            s.start_s,
            s.end_s,
            match s.kind {
                SegmentKind::Static => "static",
                SegmentKind::Plateau => "rate plateau",
            }
        )
    }
}

impl Segmentation {
    /// Segments of one kind.
    pub fn of_kind(&self, kind: SegmentKind) -> impl Iterator<Item = &Segment> {
        self.segments.iter().filter(move |s| s.kind == kind)
    }

    /// Number of segments of one kind.
    pub fn count(&self, kind: SegmentKind) -> usize {
        self.of_kind(kind).count()
    }

    /// What detection saw and estimated, for a fit's notes: the gyro's reading at rest when it
    /// is not negligible (plateaus are measured from it), and each quiet run dropped and why.
    pub fn notes(&self) -> Vec<crate::note::Note> {
        use crate::note::Note;
        let mut notes = Vec::new();
        if let Some(rest) = self.rest_rate_rad_s.map(Vec3::from)
            && rest.norm().to_degrees() >= 0.5
        {
            let deg = rest.map(f64::to_degrees);
            notes.push(Note::GyroRestRate {
                rest_deg_s: [deg[0], deg[1], deg[2]],
            });
        }
        if !self.dropped.is_empty() {
            notes.push(Note::QuietRunsDropped {
                seen: self.segments.len() + self.skipped.len() + self.dropped.len(),
                used: self.segments.len(),
                dropped: self.dropped.clone(),
                options: Box::new(self.options.clone()),
            });
        }
        notes
    }
}

/// Failures of segmentation.
#[derive(Debug, thiserror::Error)]
pub enum SegmentError {
    /// The series is too short for even one window.
    #[error(
        "{origin}: {n_samples} samples at {rate_hz:.1} Hz is shorter than a {window_s} s window"
    )]
    TooShort {
        /// Where the data came from.
        origin: String,
        /// Samples in the series.
        n_samples: usize,
        /// Its sample rate, Hz.
        rate_hz: f64,
        /// The window asked for, s.
        window_s: f64,
    },
    /// Invalid options.
    #[error("invalid segmentation option: {0}")]
    Options(String),
}

/// Too few segments for a fit: say what the data lacks.
#[derive(Debug, thiserror::Error)]
#[error(
    "{what}: found {found} {kind:?} segment(s) of >= {min_duration_s} s, need at least {needed} \
     (thresholds: accel std {accel_thr:.3e} m/s^2, gyro std {gyro_thr:.3e} rad/s); {hint}"
)]
pub struct TooFewSegments {
    /// What the segments were for.
    pub what: String,
    /// Kind that was short.
    pub kind: SegmentKind,
    /// Found.
    pub found: usize,
    /// Needed.
    pub needed: usize,
    /// Minimum duration used, s.
    pub min_duration_s: f64,
    /// Accel threshold, m/s^2.
    pub accel_thr: f64,
    /// Gyro threshold, rad/s.
    pub gyro_thr: f64,
    /// What to record instead.
    pub hint: String,
}

impl Segmentation {
    /// Error unless at least `needed` segments of `kind` were found; `what` names the purpose.
    pub fn require(
        &self,
        kind: SegmentKind,
        needed: usize,
        what: &str,
    ) -> Result<(), TooFewSegments> {
        let found = self.count(kind);
        if found >= needed {
            return Ok(());
        }
        let hint = match kind {
            SegmentKind::Static => format!(
                "the recording lacks still positions: hold the unit still in at least {needed} \
                 distinct orientations for {} s or more each",
                self.options.min_duration_s
            ),
            SegmentKind::Plateau => format!(
                "the recording lacks constant-rate plateaus above {:.3} rad/s: record a rate \
                 table run (config/scenarios/rate-table.toml)",
                self.options.plateau_min_rate_rad_s
            ),
        };
        Err(TooFewSegments {
            what: what.to_string(),
            kind,
            found,
            needed,
            min_duration_s: self.options.min_duration_s,
            accel_thr: self.accel_std_threshold_m_s2,
            gyro_thr: self.gyro_std_threshold_rad_s,
            hint,
        })
    }
}

/// Std of a 3-vector signal over a centred window of `w` samples at every sample (windows are
/// clipped at the ends): sqrt of the sum of per-axis variances. Prefix sums of centred data keep
/// the cancellation error small.
fn window_std(x: &[[f64; 3]], w: usize) -> Vec<f64> {
    let n = x.len();
    let mut mean = [0.0; 3];
    for v in x {
        for a in 0..3 {
            mean[a] += v[a] / n as f64;
        }
    }
    let mut s1 = vec![[0.0; 3]; n + 1];
    let mut s2 = vec![[0.0; 3]; n + 1];
    for (i, v) in x.iter().enumerate() {
        for a in 0..3 {
            let d = v[a] - mean[a];
            s1[i + 1][a] = s1[i][a] + d;
            s2[i + 1][a] = s2[i][a] + d * d;
        }
    }
    let h = w / 2;
    (0..n)
        .map(|i| {
            let lo = i.saturating_sub(h);
            let hi = (i + h + 1).min(n);
            let m = (hi - lo) as f64;
            let var: f64 = (0..3)
                .map(|a| {
                    let s = s1[hi][a] - s1[lo][a];
                    let q = s2[hi][a] - s2[lo][a];
                    ((q - s * s / m) / (m - 1.0).max(1.0)).max(0.0)
                })
                .sum();
            var.sqrt()
        })
        .collect()
}

fn quantile(v: &[f64], q: f64) -> f64 {
    let mut s: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    s.sort_by(f64::total_cmp);
    if s.is_empty() {
        return f64::NAN;
    }
    let k = ((s.len() - 1) as f64 * q).round() as usize;
    s[k.min(s.len() - 1)]
}

fn stats(x: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    let n = x.len() as f64;
    let mut mean = [0.0; 3];
    for v in x {
        for a in 0..3 {
            mean[a] += v[a];
        }
    }
    mean.iter_mut().for_each(|m| *m /= n);
    let mut var = [0.0; 3];
    for v in x {
        for a in 0..3 {
            var[a] += (v[a] - mean[a]).powi(2);
        }
    }
    let std = var.map(|s| (s / (n - 1.0).max(1.0)).sqrt());
    (mean, std)
}

/// Find static intervals and rate plateaus in `series`.
pub fn detect(series: &ImuSeries, opts: &SegmentOptions) -> Result<Segmentation, SegmentError> {
    if !(opts.window_s > 0.0
        && opts.threshold_factor > 0.0
        && (0.0..=1.0).contains(&opts.floor_quantile)
        && opts.trim_s >= 0.0
        && opts.min_duration_s >= 0.0)
    {
        return Err(SegmentError::Options(format!("{opts:?}")));
    }
    let rate_hz = series.sample_rate_hz();
    let w = if rate_hz.is_finite() {
        (opts.window_s * rate_hz).round() as usize
    } else {
        0
    };
    if w < 3 || series.len() < w {
        return Err(SegmentError::TooShort {
            origin: series.origin.clone(),
            n_samples: series.len(),
            rate_hz,
            window_s: opts.window_s,
        });
    }
    let sa = window_std(&series.accel_m_s2, w);
    let sg = window_std(&series.gyro_rad_s, w);
    let thr_a = opts.threshold_factor * quantile(&sa, opts.floor_quantile);
    let thr_g = opts.threshold_factor * quantile(&sg, opts.floor_quantile);
    let mut quiet: Vec<bool> = sa
        .iter()
        .zip(&sg)
        .map(|(a, g)| *a <= thr_a && *g <= thr_g)
        .collect();
    // A labelled session's parts bound its segments: a segment never spans two parts.
    if let Some(labels) = &series.labels {
        for (i, w) in labels.per_sample.windows(2).enumerate() {
            if w[0] != w[1] {
                quiet[i + 1] = false;
            }
        }
    }
    let (runs, mut dropped) = kept_runs(series, &quiet, opts, rate_hz);
    let candidates: Vec<Segment> = runs
        .iter()
        .map(|r| Segment::from_samples(series, r.used.clone(), SegmentKind::Static))
        .collect();
    let rest = rest_reading(&candidates, opts);
    let rest_v = rest.map_or(Vec3::zeros(), Vec3::from);
    let min_plateau_n = ((opts.min_plateau_s * rate_hz).round() as usize).max(2);
    let mut segments = Vec::with_capacity(candidates.len());
    for (s, run) in candidates.into_iter().zip(runs) {
        if (s.mean_gyro() - rest_v).norm() <= opts.plateau_min_rate_rad_s {
            segments.push(s);
        } else if run.fully_trimmed.len() >= min_plateau_n {
            segments.push(Segment::from_samples(
                series,
                run.fully_trimmed,
                SegmentKind::Plateau,
            ));
        } else {
            dropped.push(DroppedRun {
                start_s: series.t_s[run.quiet.start],
                end_s: series.t_s[run.quiet.end - 1],
                reason: DropReason::ShortPlateau,
            });
        }
    }
    dropped.sort_by(|a, b| a.start_s.total_cmp(&b.start_s));
    Ok(Segmentation {
        segments,
        accel_std_threshold_m_s2: thr_a,
        gyro_std_threshold_rad_s: thr_g,
        window_samples: w,
        options: opts.clone(),
        skipped: Vec::new(),
        rest_rate_rad_s: rest,
        dropped,
    })
}

/// One quiet run long enough to use.
struct QuietRun {
    /// The whole quiet run.
    quiet: std::ops::Range<usize>,
    /// Trimmed by `trim_s` at each end that borders motion (empty if too short for that).
    fully_trimmed: std::ops::Range<usize>,
    /// Trimmed as far as the minimum duration allows: the samples a still segment uses.
    used: std::ops::Range<usize>,
}

/// The quiet runs long enough to use, and the runs dropped.
/// A run's ends (within half a window of motion) are trimmed by `trim_s`, or by less when the
/// run is short, so that it keeps `min_duration_s`; the ends of the recording are not trimmed
/// (there is no motion to keep away from).
fn kept_runs(
    series: &ImuSeries,
    quiet: &[bool],
    opts: &SegmentOptions,
    rate_hz: f64,
) -> (Vec<QuietRun>, Vec<DroppedRun>) {
    let trim = (opts.trim_s * rate_hz).round() as usize;
    let min_n = ((opts.min_duration_s * rate_hz).round() as usize).max(2);
    let n = quiet.len();
    let (mut kept, mut dropped) = (Vec::new(), Vec::new());
    let mut i = 0;
    while i < n {
        if !quiet[i] {
            i += 1;
            continue;
        }
        let start = i;
        while i < n && quiet[i] {
            i += 1;
        }
        // The run is [start, i).
        let cut_lo = if start == 0 { 0 } else { trim };
        let cut_hi = if i == n { 0 } else { trim };
        let len = i - start;
        if len < min_n {
            // A lone quiet sample or two is noise crossing the threshold, not a pose.
            if len >= 2 {
                dropped.push(DroppedRun {
                    start_s: series.t_s[start],
                    end_s: series.t_s[i - 1],
                    reason: DropReason::TooShort,
                });
            }
            continue;
        }
        // Trim in proportion when both full trims would leave less than the minimum.
        let spare = len - min_n;
        let used = if cut_lo + cut_hi <= spare {
            start + cut_lo..i - cut_hi
        } else {
            let lo_share = spare * cut_lo / (cut_lo + cut_hi);
            start + lo_share..i - (spare - lo_share)
        };
        let full_lo = start + cut_lo;
        let fully_trimmed = full_lo..i.saturating_sub(cut_hi).max(full_lo);
        kept.push(QuietRun {
            quiet: start..i,
            fully_trimmed,
            used,
        });
    }
    (kept, dropped)
}

/// The gyro's reading at rest: among the runs whose mean rate is slow enough to be an offset,
/// the one with the most samples within half the plateau threshold of it; the sample-weighted
/// mean rate of that group (the one rule the daemon's still detector shares). None when no run
/// qualifies.
fn rest_reading(segments: &[Segment], opts: &SegmentOptions) -> Option<[f64; 3]> {
    let points: Vec<([f64; 3], f64)> = segments
        .iter()
        .map(|s| (s.mean_gyro_rad_s, s.n as f64))
        .collect();
    imu_stats::descriptive::largest_agreeing_group(
        &points,
        0.5 * opts.plateau_min_rate_rad_s,
        opts.max_rest_rate_rad_s,
    )
}

/// The sample-weighted mean rate of `segments`, rad/s.
fn weighted_mean_rate<'a>(segments: impl Iterator<Item = &'a Segment>) -> Vec3 {
    let (sum, n) = segments.fold((Vec3::zeros(), 0usize), |(sum, n), s| {
        (sum + s.mean_gyro() * s.n as f64, n + s.n)
    });
    sum / n.max(1) as f64
}

/// The gyro's reading at rest from already classified segments (the sample-weighted mean rate
/// of the static ones; zero when there are none), rad/s: what a plateau's rate is measured from.
pub fn rest_rate(segments: &[Segment]) -> Vec3 {
    weighted_mean_rate(segments.iter().filter(|s| s.kind == SegmentKind::Static))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn series(parts: &[(f64, [f64; 3], [f64; 3])], rate_hz: f64) -> ImuSeries {
        // Deterministic pseudo-noise so the window std has a floor.
        let mut t_s = Vec::new();
        let mut acc = Vec::new();
        let mut gyr = Vec::new();
        let mut k = 0u64;
        let mut noise = || {
            k = k
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((k >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.02
        };
        for (dur, a, g) in parts {
            for _ in 0..(dur * rate_hz) as usize {
                t_s.push(t_s.len() as f64 / rate_hz);
                acc.push([a[0] + noise(), a[1] + noise(), a[2] + noise()]);
                gyr.push([g[0] + noise(), g[1] + noise(), g[2] + noise()]);
            }
        }
        ImuSeries {
            t_s,
            accel_m_s2: acc,
            gyro_rad_s: gyr,
            temp: vec![],
            t0_ns: 0,
            origin: "synthetic".into(),
            stopped_early: None,
            unfinished: None,
            ..ImuSeries::default()
        }
    }

    #[test]
    fn finds_static_and_plateaus_between_moves() {
        let z = [0.0; 3];
        let s = series(
            &[
                (10.0, [0.0, 0.0, 9.8], z),
                (2.0, [5.0, 3.0, 7.0], [1.0, 0.5, 0.0]),
                (10.0, [9.8, 0.0, 0.0], z),
                (1.0, [9.8, 0.0, 0.0], [0.0, 0.0, 0.5]),
                (8.0, [9.8, 0.0, 0.0], [0.0, 0.0, 1.0]),
                (1.0, [9.8, 0.0, 0.0], [0.0, 0.0, 0.5]),
                (10.0, [0.0, -9.8, 0.0], z),
            ],
            100.0,
        );
        let seg = detect(&s, &SegmentOptions::default()).unwrap();
        let kinds: Vec<_> = seg.segments.iter().map(|s| s.kind).collect();
        use SegmentKind::*;
        assert_eq!(kinds, [Static, Static, Plateau, Static], "{seg:#?}");
        assert!((seg.segments[1].mean_accel_m_s2[0] - 9.8).abs() < 0.01);
        assert!((seg.segments[2].mean_gyro_rad_s[2] - 1.0).abs() < 0.01);
        // Trimmed: the first static run ends 10 s in, minus half a window and the trim.
        assert!(
            (seg.segments[0].end_s - 9.0).abs() < 0.05,
            "{}",
            seg.segments[0].end_s
        );
        assert!(seg.require(Static, 3, "accel").is_ok());
        let e = seg
            .require(Plateau, 4, "gyro scale")
            .unwrap_err()
            .to_string();
        assert!(e.contains("rate table"), "{e}");
    }

    #[test]
    fn a_raw_gyro_offset_does_not_turn_still_poses_into_plateaus() {
        // An uncompensated gyro reading [4, -6, 7] deg/s at rest (|w| 10 deg/s, over three
        // times the fixed 3 deg/s threshold), and a 30 deg/s table plateau about z.
        let rest = [4f64.to_radians(), -6f64.to_radians(), 7f64.to_radians()];
        let spin = [rest[0], rest[1], rest[2] + 30f64.to_radians()];
        let move_rate = [1.0, 0.5, 0.0];
        let s = series(
            &[
                (10.0, [0.0, 0.0, 9.8], rest),
                (2.0, [5.0, 3.0, 7.0], move_rate),
                (10.0, [9.8, 0.0, 0.0], rest),
                (1.0, [9.8, 0.0, 0.0], [0.0, 0.0, 0.5]),
                (8.0, [9.8, 0.0, 0.0], spin),
                (1.0, [9.8, 0.0, 0.0], [0.0, 0.0, 0.5]),
                (10.0, [0.0, -9.8, 0.0], rest),
            ],
            100.0,
        );
        let seg = detect(&s, &SegmentOptions::default()).unwrap();
        let kinds: Vec<_> = seg.segments.iter().map(|s| s.kind).collect();
        use SegmentKind::*;
        assert_eq!(kinds, [Static, Static, Plateau, Static], "{seg:#?}");
        let est = Vec3::from(seg.rest_rate_rad_s.unwrap());
        assert!((est - Vec3::from(rest)).norm() < 1e-3, "{est:?}");
        let typed = seg.notes();
        let notes = typed
            .iter()
            .map(ToString::to_string)
            .collect::<Vec<_>>()
            .join("\n");
        assert!(
            matches!(typed[0], crate::note::Note::GyroRestRate { rest_deg_s }
                if (rest_deg_s[0] - 4.0).abs() < 0.01 && (rest_deg_s[1] + 6.0).abs() < 0.01),
            "{typed:?}"
        );
        assert!(notes.contains("reads [4.00, -6.00, "), "{notes}");
        // The 2 s steady move is reported as dropped, not silently lost.
        assert_eq!(seg.dropped.len(), 1, "{:?}", seg.dropped);
        assert_eq!(seg.dropped[0].reason, DropReason::ShortPlateau);
        assert!(
            notes.contains("5 quiet interval(s) seen, 4 used, 1 dropped"),
            "{notes}"
        );
        // Without the rest reading, all three still poses would read as plateaus.
        let fixed = SegmentOptions {
            max_rest_rate_rad_s: 0.0,
            ..SegmentOptions::default()
        };
        let seg = detect(&s, &fixed).unwrap();
        assert_eq!(seg.count(Static), 0, "{:?}", seg.segments);
    }

    #[test]
    fn still_poses_down_to_two_seconds_are_used_and_shorter_ones_reported() {
        let z = [0.0; 3];
        let mv = [5.0, 3.0, 7.0];
        let turn = [0.7, -0.4, 0.3];
        let s = series(
            &[
                (6.0, [0.0, 0.0, 9.8], z),
                (1.0, mv, turn),
                (2.0, [9.8, 0.0, 0.0], z),
                (1.0, mv, turn),
                (3.0, [0.0, 9.8, 0.0], z),
                (1.0, mv, turn),
                (1.5, [0.0, 0.0, -9.8], z),
                (1.0, mv, turn),
                (6.0, [-9.8, 0.0, 0.0], z),
            ],
            100.0,
        );
        let seg = detect(&s, &SegmentOptions::default()).unwrap();
        let ups: Vec<[i32; 3]> = seg
            .segments
            .iter()
            .map(|s| s.mean_accel_m_s2.map(|a| (a / 9.8).round() as i32))
            .collect();
        assert_eq!(
            ups,
            [[0, 0, 1], [1, 0, 0], [0, 1, 0], [-1, 0, 0]],
            "{seg:#?}"
        );
        assert!(seg.segments.iter().all(|s| s.kind == SegmentKind::Static));
        // The 2 s pose keeps at least the minimum duration; the 3 s pose its full trim.
        let two = &seg.segments[1];
        assert!(two.end_s - two.start_s >= 0.98, "{two:?}");
        let three = &seg.segments[2];
        assert!(
            (three.end_s - three.start_s - 1.0).abs() < 0.05,
            "{three:?}"
        );
        // The 1.5 s pose is dropped, and the notes say so and why.
        assert_eq!(seg.dropped.len(), 1, "{:?}", seg.dropped);
        let typed = seg.notes();
        assert!(
            typed
                .iter()
                .any(|n| matches!(n, crate::note::Note::QuietRunsDropped {
                seen: 5, used: 4, dropped, ..
            } if dropped.len() == 1)),
            "{typed:?}"
        );
        let notes = typed
            .iter()
            .map(ToString::to_string)
            .collect::<Vec<_>>()
            .join("\n");
        assert!(
            notes.contains("5 quiet interval(s) seen, 4 used, 1 dropped"),
            "{notes}"
        );
        assert!(notes.contains("a still pose needs 2 s"), "{notes}");
    }

    #[test]
    fn labelled_parts_bound_the_segments() {
        // 20 s still at one orientation, labelled as two parts: two segments, split where the
        // label changes, not one.
        let mut s = series(&[(20.0, [0.0, 0.0, 9.8], [0.0; 3])], 100.0);
        let mut labels = crate::input::Labels::default();
        for k in 0..s.len() {
            labels.push(if k < 1200 { "rest-a" } else { "rest-b" });
        }
        let seg = detect(&s, &SegmentOptions::default()).unwrap();
        assert_eq!(seg.segments.len(), 1);
        s.labels = Some(labels);
        let seg = detect(&s, &SegmentOptions::default()).unwrap();
        assert_eq!(seg.segments.len(), 2, "{:?}", seg.segments);
        assert!(seg.segments[0].range().end <= 1200, "{:?}", seg.segments[0]);
        assert!(seg.segments[1].first_sample > 1200, "{:?}", seg.segments[1]);
    }
}
