//! What a series says about itself: length, data rate, start date, samples lost in time gaps,
//! temperature at a time, and whether the sensor moved (the noise tools' warning).

use super::ImuSeries;

impl ImuSeries {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t_s.len()
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.t_s.is_empty()
    }

    /// Data rate, Hz (NaN with fewer than two samples or no time between them): samples per
    /// second over the gap-free stretches, `(t_last - t_first) / (n - 1)` pooled over them.
    /// Robust to stamps quantised to a device tick longer than the interval (a polled
    /// 3DM-GX1's 6.5536 ms ticks at 200 or 500 Hz), where the median interval is a whole
    /// number of ticks (or 0); see [`interval_s`].
    pub fn sample_rate_hz(&self) -> f64 {
        1.0 / interval_s(&self.t_s)
    }

    /// When the series started, ISO 8601 UTC (`2026-01-01T00:00:00.000000000Z`): `t0_ns` of a
    /// recording format (MCAP, bags: Unix-epoch stamps), or of a text file whose time column
    /// is Unix time (an origin after 2001-09-09: no relative clock of a recording has run for
    /// 31 years). `None` when unknown: no samples, `t0_ns` 0, or a text file's relative times.
    pub fn started_utc(&self) -> Option<String> {
        /// 1e9 s after the Unix epoch (2001-09-09T01:46:40Z), ns.
        const UNIX_TIME_AFTER_NS: u64 = 1_000_000_000_000_000_000;
        let dated = match self.input.topic {
            Some(_) => self.t0_ns > 0,
            None => self.t0_ns >= UNIX_TIME_AFTER_NS,
        };
        (dated && !self.is_empty()).then(|| imu_rec::recording::utc_iso8601_ns(self.t0_ns))
    }

    /// Temperature at `t_s`, linearly interpolated (held at the ends); NaN without readings.
    pub fn temp_at(&self, t_s: f64) -> f64 {
        let i = self.temp.partition_point(|&(t, _)| t <= t_s);
        match (i, self.temp.len()) {
            (_, 0) => f64::NAN,
            (0, _) => self.temp[0].1,
            (i, n) if i == n => self.temp[n - 1].1,
            (i, _) => {
                let ((t0, c0), (t1, c1)) = (self.temp[i - 1], self.temp[i]);
                c0 + (c1 - c0) * (t_s - t0) / (t1 - t0)
            }
        }
    }
}

/// Steps over this many intervals (plus the stamps' own spread) are gaps.
const GAP_INTERVALS: f64 = 1.5;

/// The sample interval of stamps `t_s`, s (NaN with fewer than two samples or no time between
/// them), in three steps: a first interval from the median of `K`-sample steps (quantisation
/// errors divided by `K`; the few windows holding a gap do not move a median), the spread of
/// single steps (10th to 90th percentile: one tick for quantised stamps, the jitter of host
/// stamps, 0 for exact ones), then gaps are steps beyond `GAP_INTERVALS` first intervals plus
/// that spread, and the interval is the time over the gap-free stretches divided by their
/// steps: each stretch's error is that of its two end stamps only.
fn interval_s(t_s: &[f64]) -> f64 {
    interval_and_gap_limit_s(t_s).0
}

/// [`interval_s`] and the step beyond which a step is a gap (NaN, NaN with fewer than two
/// samples).
fn interval_and_gap_limit_s(t_s: &[f64]) -> (f64, f64) {
    const K: usize = 64;
    let n = t_s.len();
    if n < 2 {
        return (f64::NAN, f64::NAN);
    }
    let k = K.min(n - 1);
    let first = median(
        (0..n - k)
            .map(|i| (t_s[i + k] - t_s[i]) / k as f64)
            .collect(),
    );
    let mut steps: Vec<f64> = t_s.windows(2).map(|w| w[1] - w[0]).collect();
    let spread = quantile(&mut steps, 0.9) - quantile(&mut steps, 0.1);
    let limit = GAP_INTERVALS * first + spread;
    let (mut time, mut count, mut start) = (0.0, 0usize, 0usize);
    for i in 1..=n {
        if i == n || t_s[i] - t_s[i - 1] > limit {
            time += t_s[i - 1] - t_s[start];
            count += i - 1 - start;
            start = i;
        }
    }
    if count == 0 || time <= 0.0 {
        return (if first > 0.0 { first } else { f64::NAN }, limit);
    }
    (time / count as f64, limit)
}

impl ImuSeries {
    /// Samples lost, judged by the time gaps against the series' own interval (that of
    /// [`sample_rate_hz`](Self::sample_rate_hz)): a step `dt` beyond `GAP_INTERVALS` (1.5)
    /// intervals (plus the stamps' own spread: a tick of quantised stamps, host jitter) counts
    /// `round(dt / interval) - 1` samples. Gaps between a session's files count too: they are
    /// steps of the joined series. 0 with fewer than two samples.
    pub fn missing_samples(&self) -> u64 {
        let (interval, limit) = interval_and_gap_limit_s(&self.t_s);
        if !(interval > 0.0 && limit.is_finite()) {
            return 0;
        }
        self.t_s
            .windows(2)
            .map(|w| w[1] - w[0])
            .filter(|&dt| dt > limit)
            .map(|dt| ((dt / interval).round() as u64).saturating_sub(1))
            .sum()
    }
}

/// The median of `v` (not empty).
fn median(mut v: Vec<f64>) -> f64 {
    quantile(&mut v, 0.5)
}

/// The element at rank `q * (len - 1)` (rounded down) of `v` (not empty), reordering `v`.
fn quantile(v: &mut [f64], q: f64) -> f64 {
    let i = ((v.len() - 1) as f64 * q) as usize;
    *v.select_nth_unstable_by(i, f64::total_cmp).1
}

impl ImuSeries {
    /// Says whether the sensor moved: means over 10-second windows that differ by more than
    /// 0.5 m/s^2 (about 50 mg: a tilt of ~3 degrees) on an accelerometer axis or 0.02 rad/s on a
    /// gyro axis cannot be noise or drift of a still MEMS unit. `None` when the data look static.
    /// Noise analyses of moving data measure the motion, so their tools warn with this text.
    pub fn motion_warning(&self) -> Option<String> {
        let rate = self.sample_rate_hz();
        if !rate.is_finite() {
            return None;
        }
        let window = ((10.0 * rate) as usize).max(1);
        let spans = |data: &[[f64; 3]]| -> [f64; 3] {
            std::array::from_fn(|axis| {
                let means: Vec<f64> = data
                    .chunks(window)
                    .filter(|c| c.len() == window)
                    .map(|c| c.iter().map(|v| v[axis]).sum::<f64>() / window as f64)
                    .collect();
                let (lo, hi) = means
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &m| {
                        (lo.min(m), hi.max(m))
                    });
                if means.len() < 2 { 0.0 } else { hi - lo }
            })
        };
        let (accel, gyro) = (spans(&self.accel_m_s2), spans(&self.gyro_rad_s));
        let names = ["x", "y", "z"];
        for i in 0..3 {
            if accel[i] > 0.5 {
                return Some(format!(
                    "the sensor moved: 10 s means of accel {} span {:.3} m/s^2; an Allan analysis of moving data measures the motion, not the noise (record with the IMU still)",
                    names[i], accel[i]
                ));
            }
            if gyro[i] > 0.02 {
                return Some(format!(
                    "the sensor moved: 10 s means of gyro {} span {:.4} rad/s; an Allan analysis of moving data measures the motion, not the noise (record with the IMU still)",
                    names[i], gyro[i]
                ));
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn motion_is_told_from_noise() {
        let n = 10_000;
        let still = ImuSeries {
            t_s: (0..n).map(|i| i as f64 * 0.01).collect(),
            accel_m_s2: (0..n)
                .map(|i| [0.01 * ((i * 7919) % 13) as f64, 0.0, 9.8])
                .collect(),
            gyro_rad_s: vec![[1e-3, 0.0, 0.0]; n],
            ..ImuSeries::default()
        };
        assert_eq!(still.motion_warning(), None);
        let mut tilted = still.clone();
        for v in &mut tilted.accel_m_s2[n / 2..] {
            v[0] += 1.7; // a 10-degree tilt halfway through
        }
        let w = tilted.motion_warning().expect("a tilt is motion");
        assert!(w.contains("accel x"), "{w}");
    }

    #[test]
    fn temperature_interpolation() {
        let s = ImuSeries {
            temp: vec![(0.0, 20.0), (10.0, 30.0)],
            ..ImuSeries::default()
        };
        assert_eq!(s.temp_at(-1.0), 20.0);
        assert_eq!(s.temp_at(5.0), 25.0);
        assert_eq!(s.temp_at(11.0), 30.0);
    }

    /// Stamps of a polled 3DM-GX1: each sample stamped with the device's 6.5536 ms tick
    /// counter, so at 200 and 500 Hz most steps are 0 or one tick (the median interval said
    /// 152.6 Hz or infinity). One stretch of 0.5 s is missing; the estimate must be within
    /// 0.05 % (two ticks over the ~40 s recording).
    #[test]
    fn rate_of_tick_quantised_stamps() {
        const TICK_S: f64 = 6.5536e-3;
        for rate_hz in [200.0, 500.0, 100.0, 37.0] {
            let n = (40.0 * rate_hz) as usize;
            let gap = (n / 3)..(n / 3 + (0.5 * rate_hz) as usize);
            let t_s: Vec<f64> = (0..n)
                .filter(|i| !gap.contains(i))
                .map(|i| ((i as f64 / rate_hz + 0.0031) / TICK_S).floor() * TICK_S)
                .collect();
            let s = ImuSeries {
                t_s,
                ..ImuSeries::default()
            };
            let got = s.sample_rate_hz();
            assert!(
                (got / rate_hz - 1.0).abs() < 5e-4,
                "{rate_hz} Hz read as {got} Hz"
            );
            // The hole, to within the tick of the stamps on either side of it in samples.
            let lost = gap.len() as i64;
            let said = s.missing_samples() as i64;
            let tick_samples = (TICK_S * rate_hz).ceil() as i64;
            assert!(
                (said - lost).abs() <= tick_samples,
                "{rate_hz} Hz: {said} lost, truth {lost}"
            );
        }
    }

    #[test]
    fn rate_of_exact_and_jittered_stamps() {
        let exact = ImuSeries {
            t_s: (0..1000).map(|i| i as f64 * 0.01).collect(),
            ..ImuSeries::default()
        };
        assert!((exact.sample_rate_hz() - 100.0).abs() < 1e-9);
        // Host stamps with +-2 ms of jitter and a 3 s hole.
        let jittered = ImuSeries {
            t_s: (0..4000)
                .filter(|i| !(1000..1300).contains(i))
                .map(|i| i as f64 * 0.01 + 0.002 * (((i * 7919) % 101) as f64 / 50.0 - 1.0))
                .collect(),
            ..ImuSeries::default()
        };
        let got = jittered.sample_rate_hz();
        assert!((got / 100.0 - 1.0).abs() < 3e-4, "{got}");
        assert_eq!(jittered.missing_samples(), 300);
        assert_eq!(exact.missing_samples(), 0);
        let one = ImuSeries {
            t_s: vec![1.0],
            ..ImuSeries::default()
        };
        assert!(one.sample_rate_hz().is_nan());
        assert_eq!(one.missing_samples(), 0);
    }
}
