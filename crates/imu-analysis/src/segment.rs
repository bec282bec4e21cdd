//! Automatic detection of static intervals and constant-rate plateaus in an IMU series, the
//! input of the calibration fits (Aslan & Saranli 3.1.2, 3.2.2, 3.2.3: multi-position static
//! tests and rate-table plateaus).
//!
//! A centred moving window gives, at every sample, the standard deviation of the accel and gyro
//! vectors (root of the summed per-axis variances, so a slow rotation that keeps |g| constant
//! still shows up as motion). Quiet samples are those whose window std lies below a threshold
//! chosen from the data: a multiple of a low quantile of the window std over the whole
//! recording (the noise floor of the quietest stretches). Runs of quiet samples are trimmed at
//! both ends, kept when long enough, and classified as static (small mean rate) or as a rate
//! plateau (large, steady rate).

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
    /// Shortest segment kept (after trimming), s.
    pub min_duration_s: f64,
    /// |mean gyro| above which a quiet run is a rate plateau instead of static, rad/s.
    pub plateau_min_rate_rad_s: f64,
}

impl Default for SegmentOptions {
    fn default() -> Self {
        SegmentOptions {
            window_s: 1.0,
            floor_quantile: 0.1,
            threshold_factor: 2.0,
            trim_s: 0.5,
            min_duration_s: 3.0,
            // 3 deg/s: far above MEMS gyro biases (< 1 deg/s) and Earth rate.
            plateau_min_rate_rad_s: 0.05,
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
    // A quiet run already ends half a window before the motion; trim a little more.
    let trim = (opts.trim_s * rate_hz).round() as usize;
    let min_n = ((opts.min_duration_s * rate_hz).round() as usize).max(2);

    let mut segments = Vec::new();
    let n = series.len();
    let mut i = 0;
    while i < n {
        if !(sa[i] <= thr_a && sg[i] <= thr_g) {
            i += 1;
            continue;
        }
        let start = i;
        while i < n && sa[i] <= thr_a && sg[i] <= thr_g {
            i += 1;
        }
        // The run is [start, i). Its ends (within half a window of motion) are trimmed, except
        // at the ends of the recording, where there is no motion to keep away from.
        let lo = if start == 0 { 0 } else { start + trim };
        let hi = if i == n { n } else { i.saturating_sub(trim) };
        if hi <= lo || hi - lo < min_n {
            continue;
        }
        let (mean_a, std_a) = stats(&series.accel_m_s2[lo..hi]);
        let (mean_g, std_g) = stats(&series.gyro_rad_s[lo..hi]);
        let rate = Vec3::from(mean_g).norm();
        segments.push(Segment {
            kind: if rate > opts.plateau_min_rate_rad_s {
                SegmentKind::Plateau
            } else {
                SegmentKind::Static
            },
            start_s: series.t_s[lo],
            end_s: series.t_s[hi - 1],
            first_sample: lo,
            n: hi - lo,
            mean_accel_m_s2: mean_a,
            mean_gyro_rad_s: mean_g,
            std_accel_m_s2: std_a,
            std_gyro_rad_s: std_g,
        });
    }
    Ok(Segmentation {
        segments,
        accel_std_threshold_m_s2: thr_a,
        gyro_std_threshold_rad_s: thr_g,
        window_samples: w,
        options: opts.clone(),
        skipped: Vec::new(),
    })
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
}
