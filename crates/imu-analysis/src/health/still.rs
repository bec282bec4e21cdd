//! The still-period detector, running sample by sample: the offline segmentation's rules
//! (`crate::segment`) made incremental and bounded in memory.
//!
//! Samples are grouped in blocks of `block-s` (the offline moving window). A block is quiet when
//! the root-summed standard deviation of its accel and of its gyro samples both lie below
//! `threshold-factor` x their noise floor: a low quantile of the recent blocks' deviations (the
//! offline rule), capped at three times what the calibration's noise tables predict for a still
//! unit so that a unit that never rests cannot call its motion still. A run of quiet blocks loses
//! one block at each end that borders motion (the trim), is kept when at least `min-still-s`
//! remain, and is cut into windows of at most `max-window-s` while the unit stays still. A
//! window is still, not a rate plateau, when its mean rate agrees with the gyro's reading at
//! rest: the largest group of agreeing window means ([`largest_agreeing_group`], the rule the
//! offline segmentation uses), so a raw offset of several deg/s is never mistaken for rotation.

use std::collections::VecDeque;

use imu_model::Vec3;
use imu_stats::descriptive::largest_agreeing_group;

use crate::segment::SegmentOptions;

/// Settings of the detector (`[health]` in the daemon's configuration; the defaults are its
/// defaults, the offline segmentation's `SegmentOptions` where they share a setting).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StillOptions {
    /// Block (window) length, s.
    pub block_s: f64,
    /// Quiet threshold = this x the noise floor.
    pub threshold_factor: f64,
    /// Quantile of the recent blocks' deviations taken as the noise floor.
    pub floor_quantile: f64,
    /// Shortest still window kept after trimming, s.
    pub min_still_s: f64,
    /// Longest still window, s: a long rest yields a window every this many seconds.
    pub max_window_s: f64,
    /// |mean rate - reading at rest| above which a quiet window is a rate plateau, rad/s.
    pub plateau_min_rate_rad_s: f64,
    /// Largest |mean rate| that can be the gyro's reading at rest, rad/s.
    pub max_rest_rate_rad_s: f64,
}

impl Default for StillOptions {
    /// The offline segmentation's defaults, and a still window every 30 s of a long rest.
    fn default() -> Self {
        let s = SegmentOptions::default();
        StillOptions {
            block_s: s.window_s,
            threshold_factor: s.threshold_factor,
            floor_quantile: s.floor_quantile,
            min_still_s: s.min_duration_s,
            max_window_s: 30.0,
            plateau_min_rate_rad_s: s.plateau_min_rate_rad_s,
            max_rest_rate_rad_s: s.max_rest_rate_rad_s,
        }
    }
}

/// Blocks whose deviations make the data floor (one hour of 1 s blocks).
const FLOOR_HISTORY: usize = 3600;
/// Blocks seen before the data floor is trusted.
const FLOOR_MIN_BLOCKS: usize = 20;
/// Recent quiet windows the reading at rest is looked for among.
const REST_HISTORY: usize = 64;

/// Running mean and sum of squared deviations per axis (Welford; merged by Chan's formula).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Moments {
    /// Samples.
    pub n: f64,
    /// Mean per axis.
    pub mean: [f64; 3],
    /// Sum of squared deviations from the mean per axis.
    pub m2: [f64; 3],
}

impl Moments {
    fn push(&mut self, v: &[f64; 3]) {
        self.n += 1.0;
        for ((x, mean), m2) in v.iter().zip(&mut self.mean).zip(&mut self.m2) {
            let d = x - *mean;
            *mean += d / self.n;
            *m2 += d * (x - *mean);
        }
    }

    fn merge(&mut self, o: &Moments) {
        let n = self.n + o.n;
        if n == 0.0 {
            return;
        }
        for a in 0..3 {
            let d = o.mean[a] - self.mean[a];
            self.mean[a] += d * o.n / n;
            self.m2[a] += o.m2[a] + d * d * self.n * o.n / n;
        }
        self.n = n;
    }

    /// Sample variance per axis.
    pub fn variance(&self) -> [f64; 3] {
        self.m2.map(|m| m / (self.n - 1.0).max(1.0))
    }

    /// Root of the summed per-axis variances (the offline window deviation).
    fn root_sum_std(&self) -> f64 {
        self.variance().iter().sum::<f64>().sqrt()
    }
}

/// Samples of one block (or window): times, moments and temperature.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Block {
    t0_ns: u64,
    t1_ns: u64,
    accel: Moments,
    gyro: Moments,
    temp_sum_c: f64,
    temp_n: f64,
}

impl Block {
    fn starting(t_ns: u64) -> Block {
        Block {
            t0_ns: t_ns,
            t1_ns: t_ns,
            ..Block::default()
        }
    }

    fn merge(&mut self, o: &Block) {
        self.t0_ns = self.t0_ns.min(o.t0_ns);
        self.t1_ns = self.t1_ns.max(o.t1_ns);
        self.accel.merge(&o.accel);
        self.gyro.merge(&o.gyro);
        self.temp_sum_c += o.temp_sum_c;
        self.temp_n += o.temp_n;
    }

    fn duration_s(&self) -> f64 {
        (self.t1_ns.saturating_sub(self.t0_ns)) as f64 * 1e-9
    }
}

/// A still window: the unit rested throughout.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StillWindow {
    /// First sample time, ns.
    pub start_ns: u64,
    /// Last sample time, ns.
    pub end_ns: u64,
    /// Accel moments (mean corrected specific force, m/s^2).
    pub accel: Moments,
    /// Gyro moments (mean corrected rate, rad/s).
    pub gyro: Moments,
    /// Mean temperature, deg C (NaN if none).
    pub temp_c: f64,
}

impl StillWindow {
    /// Duration, s.
    pub fn duration_s(&self) -> f64 {
        (self.end_ns.saturating_sub(self.start_ns)) as f64 * 1e-9
    }

    /// Sample rate, Hz.
    pub fn rate_hz(&self) -> f64 {
        (self.accel.n - 1.0).max(1.0) / self.duration_s().max(1e-9)
    }

    /// Mean specific force, m/s^2.
    pub fn mean_accel(&self) -> Vec3 {
        Vec3::from(self.accel.mean)
    }

    /// Mean rate, rad/s.
    pub fn mean_gyro(&self) -> Vec3 {
        Vec3::from(self.gyro.mean)
    }
}

/// What a closed quiet run yields.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Detected {
    /// The unit was still.
    Still(StillWindow),
    /// A steady rotation (its mean rate is far from the reading at rest): not a reference.
    Plateau,
}

/// What the noise tables predict for a still unit's block deviation (root of the summed
/// per-axis variances) of one triad: `sqrt(white_var_per_hz * rate_hz + quantization_var)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExpectedStill {
    /// Sum over the axes of the white-noise density squared, U^2/Hz.
    pub white_var_per_hz: f64,
    /// Sum over the axes of the quantization variance (step^2 / 12), U^2.
    pub quantization_var: f64,
}

impl ExpectedStill {
    /// The block deviation at `rate_hz`.
    pub fn block_std(&self, rate_hz: f64) -> f64 {
        (self.white_var_per_hz * rate_hz + self.quantization_var).sqrt()
    }
}

/// The incremental detector.
#[derive(Debug, Clone)]
pub struct StillDetector {
    opts: StillOptions,
    /// What the noise tables predict for a still unit (accel, gyro).
    expected: Option<(ExpectedStill, ExpectedStill)>,
    /// The sample rate of the latest full block, Hz.
    rate_hz: f64,
    block: Option<Block>,
    /// The quiet blocks of the current run.
    run: Vec<Block>,
    /// The current run follows motion (its first block is trimmed).
    run_after_motion: bool,
    history_accel: VecDeque<f64>,
    history_gyro: VecDeque<f64>,
    rest_points: VecDeque<([f64; 3], f64)>,
}

impl StillDetector {
    /// A detector; `expected` is what the noise tables predict for a still unit (accel, gyro),
    /// when there are tables.
    pub fn new(
        opts: StillOptions,
        expected: Option<(ExpectedStill, ExpectedStill)>,
    ) -> StillDetector {
        StillDetector {
            opts,
            expected,
            rate_hz: f64::NAN,
            block: None,
            run: Vec::new(),
            run_after_motion: false,
            history_accel: VecDeque::new(),
            history_gyro: VecDeque::new(),
            rest_points: VecDeque::new(),
        }
    }

    /// Forgets the current block and run (a new device session: the stream was interrupted).
    pub fn interrupt(&mut self) {
        self.block = None;
        self.run.clear();
        self.run_after_motion = true;
    }

    /// The quiet thresholds (accel, gyro) now, `None` while the floor is unknown.
    pub fn thresholds(&self) -> Option<(f64, f64)> {
        let q = |h: &VecDeque<f64>| {
            (h.len() >= FLOOR_MIN_BLOCKS).then(|| {
                let mut v: Vec<f64> = h.iter().copied().collect();
                let k = ((v.len() - 1) as f64 * self.opts.floor_quantile).round() as usize;
                *v.select_nth_unstable_by(k, f64::total_cmp).1
            })
        };
        let (qa, qg) = (q(&self.history_accel), q(&self.history_gyro));
        // At the stream's own rate (white noise per block grows with it).
        let expected_floor = self
            .expected
            .filter(|_| self.rate_hz.is_finite())
            .map(|(a, g)| (a.block_std(self.rate_hz), g.block_std(self.rate_hz)));
        let floor = match (expected_floor, qa.zip(qg)) {
            (Some((ea, eg)), Some((qa, qg))) => (qa.min(3.0 * ea), qg.min(3.0 * eg)),
            (Some(e), None) => e,
            (None, Some(q)) => q,
            (None, None) => return None,
        };
        Some((
            self.opts.threshold_factor * floor.0,
            self.opts.threshold_factor * floor.1,
        ))
    }

    /// One corrected sample; returns a window when a quiet run closed or reached the longest
    /// window.
    pub fn push(
        &mut self,
        t_ns: u64,
        accel: &[f64; 3],
        gyro: &[f64; 3],
        temp_c: f64,
    ) -> Option<Detected> {
        let block_ns = (self.opts.block_s * 1e9) as u64;
        let mut out = None;
        if let Some(b) = self.block
            && t_ns.saturating_sub(b.t0_ns) >= block_ns
        {
            out = self.close_block(b);
            self.block = None;
        }
        let b = self.block.get_or_insert_with(|| Block::starting(t_ns));
        b.t1_ns = t_ns;
        b.accel.push(accel);
        b.gyro.push(gyro);
        if temp_c.is_finite() {
            b.temp_sum_c += temp_c;
            b.temp_n += 1.0;
        }
        out
    }

    /// A full block: judged quiet or not, the run extended or closed.
    fn close_block(&mut self, b: Block) -> Option<Detected> {
        if b.accel.n < 3.0 {
            return None;
        }
        self.rate_hz = (b.accel.n - 1.0) / b.duration_s().max(1e-9);
        let (sa, sg) = (b.accel.root_sum_std(), b.gyro.root_sum_std());
        let quiet = self
            .thresholds()
            .is_some_and(|(ta, tg)| sa <= ta && sg <= tg);
        for (h, v) in [(&mut self.history_accel, sa), (&mut self.history_gyro, sg)] {
            if h.len() == FLOOR_HISTORY {
                h.pop_front();
            }
            h.push_back(v);
        }
        if quiet {
            self.run.push(b);
            let lead = usize::from(self.run_after_motion);
            // Full: emit all but the last block, which starts the next window (it may yet
            // border motion).
            let span_s = self.span_s(lead, self.run.len());
            if span_s >= self.opts.max_window_s + self.opts.block_s {
                let w = self.window(lead, self.run.len() - 1);
                let last = self.run.pop();
                self.run.clear();
                self.run.extend(last);
                self.run_after_motion = false;
                return w;
            }
            return None;
        }
        // Motion: the run ends; its last block borders the motion.
        let n = self.run.len();
        let lead = usize::from(self.run_after_motion);
        let w = (n > lead + 1).then(|| self.window(lead, n - 1)).flatten();
        self.run.clear();
        self.run_after_motion = true;
        w
    }

    fn span_s(&self, from: usize, to: usize) -> f64 {
        if to <= from {
            return 0.0;
        }
        (self.run[to - 1].t1_ns.saturating_sub(self.run[from].t0_ns)) as f64 * 1e-9
    }

    /// The window of run blocks `from..to`, classified; `None` when shorter than the minimum.
    fn window(&mut self, from: usize, to: usize) -> Option<Detected> {
        let mut w = self.run[from];
        for b in &self.run[from + 1..to] {
            w.merge(b);
        }
        if w.duration_s() < self.opts.min_still_s {
            return None;
        }
        if self.rest_points.len() == REST_HISTORY {
            self.rest_points.pop_front();
        }
        self.rest_points.push_back((w.gyro.mean, w.gyro.n));
        let points: Vec<([f64; 3], f64)> = self.rest_points.iter().copied().collect();
        let rest = largest_agreeing_group(
            &points,
            0.5 * self.opts.plateau_min_rate_rad_s,
            self.opts.max_rest_rate_rad_s,
        );
        let still = rest.is_some_and(|r| {
            (Vec3::from(w.gyro.mean) - Vec3::from(r)).norm() <= self.opts.plateau_min_rate_rad_s
        });
        Some(if still {
            Detected::Still(StillWindow {
                start_ns: w.t0_ns,
                end_ns: w.t1_ns,
                accel: w.accel,
                gyro: w.gyro,
                temp_c: if w.temp_n > 0.0 {
                    w.temp_sum_c / w.temp_n
                } else {
                    f64::NAN
                },
            })
        } else {
            Detected::Plateau
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A still unit at `rate_hz` with white noise of density 1e-3 (accel) and 1e-4 (gyro) per
    /// axis and a 5 deg/s raw gyro offset, 12 s still, 2 s of turning, 12 s still.
    fn windows_at(rate_hz: f64) -> Vec<Detected> {
        let opts = StillOptions {
            block_s: 1.0,
            threshold_factor: 2.0,
            floor_quantile: 0.1,
            min_still_s: 1.0,
            max_window_s: 30.0,
            plateau_min_rate_rad_s: 0.05,
            max_rest_rate_rad_s: 20f64.to_radians(),
        };
        let expected = |n: f64| ExpectedStill {
            white_var_per_hz: 3.0 * n * n,
            quantization_var: 0.0,
        };
        let mut d = StillDetector::new(opts, Some((expected(1e-3), expected(1e-4))));
        let mut state = 1u64;
        let mut uniform = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        // Uniform in [-a, a] has standard deviation a / sqrt(3).
        let (sa, sg) = (1e-3 * rate_hz.sqrt(), 1e-4 * rate_hz.sqrt());
        let offset = 5f64.to_radians();
        let mut out = Vec::new();
        let n = (26.0 * rate_hz) as u64;
        for k in 0..n {
            let t_s = k as f64 / rate_hz;
            let turning = (12.0..14.0).contains(&t_s);
            let w = if turning { 1.0 } else { 0.0 };
            let tilt = if turning { (t_s - 12.0) * w } else { 0.0 };
            let accel = [
                9.8 * tilt.sin() + uniform() * sa * 3f64.sqrt(),
                uniform() * sa * 3f64.sqrt(),
                9.8 * tilt.cos() + uniform() * sa * 3f64.sqrt(),
            ];
            let gyro = [
                offset + uniform() * sg * 3f64.sqrt(),
                w + uniform() * sg * 3f64.sqrt(),
                uniform() * sg * 3f64.sqrt(),
            ];
            out.extend(d.push((t_s * 1e9) as u64, &accel, &gyro, 25.0));
        }
        // The last run closes on motion: two seconds of shaking.
        for k in n..n + (2.0 * rate_hz) as u64 + 1 {
            let t_s = k as f64 / rate_hz;
            let shake = if k % 2 == 0 { 5.0 } else { -5.0 };
            out.extend(d.push(
                (t_s * 1e9) as u64,
                &[shake, 0.0, 9.8],
                &[0.0, shake, 0.0],
                25.0,
            ));
        }
        out
    }

    #[test]
    fn still_windows_are_found_at_any_rate_through_a_raw_gyro_offset() {
        for rate_hz in [20.0, 100.0, 1000.0] {
            let found = windows_at(rate_hz);
            let still: Vec<&StillWindow> = found
                .iter()
                .filter_map(|d| match d {
                    Detected::Still(w) => Some(w),
                    Detected::Plateau => None,
                })
                .collect();
            assert_eq!(still.len(), 2, "{rate_hz} Hz: {found:?}");
            for w in &still {
                assert!(w.duration_s() >= 9.0, "{rate_hz} Hz: {w:?}");
                assert!((w.mean_gyro()[0] - 5f64.to_radians()).abs() < 1e-3);
            }
        }
    }
}
