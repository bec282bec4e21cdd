//! Sample time stamps: device-clock spacing, host-clock offset and drift from a robust fit.
//!
//! The device's tick counter is the truth for the spacing of samples; the host only knows when
//! each frame's last byte arrived, which is the sample time plus a latency that is never
//! negative and sometimes large (a loaded host, a stalled link: up to seconds). So, as NTP-style
//! filters do, the fit uses the *lower envelope* of `arrival - device time`: the smallest value
//! per [`BUCKET_S`] of device time, over the last [`BUCKETS`] buckets. The lower convex hull of
//! those minima gives a line no stall can lift; minima far above it (buckets a stall covered)
//! are left out, and a least-squares line through the rest averages the link's latency noise.
//!
//! Stamps follow the device clock: each is the previous one plus the device-time spacing scaled
//! by the fitted rate, nudged towards the fitted line by at most [`MAX_SLEW`] of the spacing
//! (more while far off, e.g. after start-up). So stamps are strictly increasing, a stall cannot
//! bend them, and a late or early host wake-up does not appear in them at all.
//!
//! Files: here the device-clock fit ([`ClockFit`]) and the wall stamps ([`WallStamps`]);
//! `gnss.rs` the wall stamps that follow a unit's GNSS time ([`GnssClock`],
//! `device.time-source = "gnss"`).

pub mod gnss;

pub use gnss::{GnssClock, GnssState};

/// Device time per bucket of the lower envelope, s.
pub const BUCKET_S: f64 = 1.0;
/// Buckets kept for the fit (the fit's baseline, s, at one bucket per second).
pub const BUCKETS: usize = 128;
/// Buckets needed before the fit is trusted.
const MIN_BUCKETS: usize = 3;
/// Largest correction of a stamp towards the fit, as a fraction of its spacing (5000 ppm).
pub const MAX_SLEW: f64 = 0.005;
/// Beyond this distance from the fit, corrections may take half the spacing.
const FAR_OFF_S: f64 = 0.05;
/// Smallest spacing between two stamps, ns (stamps never repeat).
const MIN_SPACING_NS: u64 = 1_000;
/// Minima more than this above the envelope, in robust standard deviations, are left out.
const REJECT_SIGMAS: f64 = 3.0;
/// ... and never when closer than this, s.
const REJECT_FLOOR_S: f64 = 100e-6;

/// The lowest `arrival - device time` point of one bucket.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Minimum {
    bucket: i64,
    x_s: f64,
    y_s: f64,
}

/// The fitted line `arrival - device time = offset_s + drift * device time` (times since the
/// session's first sample).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Line {
    offset_s: f64,
    drift: f64,
    residual_s: f64,
}

/// The fit's state for one device session (stamps stay monotonic across sessions).
#[derive(Debug, Clone)]
pub struct ClockFit {
    nominal_tick_period_s: f64,
    /// Host ns and device position (ticks) of the session's first sample.
    origin: Option<(u64, f64)>,
    minima: [Minimum; BUCKETS],
    n_minima: usize,
    /// Where the next closed bucket goes in `minima` (a ring).
    next: usize,
    current: Option<Minimum>,
    envelope_min_y_s: f64,
    line: Option<Line>,
    last_stamp_ns: Option<u64>,
}

impl ClockFit {
    /// The tick period the fit starts from, s.
    pub fn nominal_tick_period_s(&self) -> f64 {
        self.nominal_tick_period_s
    }

    /// A fit that starts from the nominal tick period.
    pub fn new(nominal_tick_period_s: f64) -> Self {
        Self {
            nominal_tick_period_s,
            origin: None,
            minima: [Minimum {
                bucket: 0,
                x_s: 0.0,
                y_s: 0.0,
            }; BUCKETS],
            n_minima: 0,
            next: 0,
            current: None,
            envelope_min_y_s: f64::INFINITY,
            line: None,
            last_stamp_ns: None,
        }
    }

    /// Forgets the device clock (after a reconnect the device may have been power-cycled); the
    /// next stamps still follow the last one.
    pub fn reset(&mut self) {
        let last = self.last_stamp_ns;
        *self = Self::new(self.nominal_tick_period_s);
        self.last_stamp_ns = last;
    }

    /// Forgets the fit but not the session's origin nor the last stamp: the stamps go on
    /// smoothly towards a new fit (after the sample positions became exact).
    pub fn restart_fit(&mut self) {
        let (origin, last) = (self.origin, self.last_stamp_ns);
        self.reset();
        self.origin = origin;
        self.last_stamp_ns = last;
    }

    /// Adds a sample at `position_ticks` on the device time line, `spacing_ticks` of device time
    /// after the previous one, that arrived at host monotonic `host_ns`; returns its stamp, ns.
    pub fn update(&mut self, position_ticks: f64, spacing_ticks: f64, host_ns: u64) -> u64 {
        let (h0, p0) = *self.origin.get_or_insert((host_ns, position_ticks));
        let x_s = (position_ticks - p0) * self.nominal_tick_period_s;
        let y_s = (host_ns as f64 - h0 as f64) * 1e-9 - x_s;
        self.add_point(x_s, y_s);
        let drift = self.line.map_or(0.0, |l| l.drift);
        let target_y_s = self
            .line
            .map_or(self.envelope_min_y_s, |l| l.offset_s + l.drift * x_s);
        let target_ns = h0 as f64 + (x_s + target_y_s) * 1e9;
        let spacing_ns = spacing_ticks.max(0.0) * self.nominal_tick_period_s * 1e9 * (1.0 + drift);
        let stamp = match self.last_stamp_ns {
            // The session's first sample after another session: only keep the order.
            Some(last) if spacing_ns <= 0.0 => target_ns.max(last as f64),
            Some(last) => {
                let natural = last as f64 + spacing_ns;
                let error = target_ns - natural;
                let limit = if error.abs() > FAR_OFF_S * 1e9 {
                    0.5
                } else {
                    MAX_SLEW
                } * spacing_ns;
                natural + error.clamp(-limit, limit)
            }
            None => target_ns,
        };
        let stamp = (stamp.max(0.0) as u64).max(
            self.last_stamp_ns
                .map_or(0, |l| l.saturating_add(MIN_SPACING_NS)),
        );
        self.last_stamp_ns = Some(stamp);
        stamp
    }

    /// Keeps the lowest point of each bucket; refits when a bucket closes.
    fn add_point(&mut self, x_s: f64, y_s: f64) {
        self.envelope_min_y_s = self.envelope_min_y_s.min(y_s);
        let bucket = (x_s / BUCKET_S).floor() as i64;
        match &mut self.current {
            Some(m) if m.bucket == bucket => {
                if y_s < m.y_s {
                    *m = Minimum { bucket, x_s, y_s };
                }
            }
            Some(m) => {
                let closed = *m;
                self.current = Some(Minimum { bucket, x_s, y_s });
                self.minima[self.next] = closed;
                self.next = (self.next + 1) % BUCKETS;
                self.n_minima = (self.n_minima + 1).min(BUCKETS);
                self.refit();
            }
            None => self.current = Some(Minimum { bucket, x_s, y_s }),
        }
    }

    /// Least squares through the kept minima, rejecting those far above the line and fitting
    /// again (a stall lifts whole buckets; nothing can arrive before it was sent).
    fn refit(&mut self) {
        let points = &self.minima[..self.n_minima];
        let oldest = if self.n_minima == BUCKETS {
            self.next
        } else {
            0
        };
        let Some((offset_s, drift)) = lower_hull_line(points, oldest) else {
            self.line = None;
            return;
        };
        // Distances above the envelope: a stall lifts whole buckets far above it, the link's
        // own latency noise only a little; the first are left out of the final fit.
        let mut distances = [0.0f64; BUCKETS];
        for (d, p) in distances.iter_mut().zip(points) {
            *d = p.y_s - offset_s - drift * p.x_s;
        }
        let n = points.len();
        let mut sorted = distances;
        let (_, median, _) = sorted[..n].select_nth_unstable_by(n / 2, f64::total_cmp);
        let limit = (REJECT_SIGMAS * 1.4826 * *median).max(REJECT_FLOOR_S);
        let mut keep = [false; BUCKETS];
        for (k, d) in keep.iter_mut().zip(&distances[..n]) {
            *k = *d <= limit;
        }
        self.line = least_squares(points, &keep);
    }

    /// Host seconds per tick from the fit, once trusted.
    pub fn tick_period_s(&self) -> Option<f64> {
        self.line
            .map(|l| self.nominal_tick_period_s * (1.0 + l.drift))
    }

    /// Device clock rate error against the host, ppm (positive: the device runs fast).
    pub fn drift_ppm(&self) -> Option<f64> {
        self.line.map(|l| (1.0 / (1.0 + l.drift) - 1.0) * 1e6)
    }

    /// Host monotonic time, s, at which the device's position was 0 ticks, from the fit (so a
    /// sample at `p` ticks was taken at about `offset + p * tick_period_s`, plus the least
    /// latency of the link).
    pub fn offset_s(&self) -> Option<f64> {
        let (l, (h0, p0)) = (self.line?, self.origin?);
        let x0_s = -p0 * self.nominal_tick_period_s;
        Some(h0 as f64 * 1e-9 + x0_s * (1.0 + l.drift) + l.offset_s)
    }

    /// RMS distance of the accepted minima from the fitted line, s.
    pub fn residual_s(&self) -> Option<f64> {
        self.line.map(|l| l.residual_s)
    }
}

/// The line under all points that is highest at their mean time (the lower convex hull's edge
/// there: the line below every point with the least total distance to them), as (offset, drift).
///
/// `oldest` is the index of the earliest point: the ring holds them in time order from there, so
/// only a sort that is already done is skipped.
fn lower_hull_line(points: &[Minimum], oldest: usize) -> Option<(f64, f64)> {
    let mut sorted = [(0.0f64, 0.0f64); BUCKETS];
    let (newer, older) = points.split_at(oldest.min(points.len()));
    for (s, p) in sorted.iter_mut().zip(older.iter().chain(newer)) {
        *s = (p.x_s, p.y_s);
    }
    let sorted = &mut sorted[..points.len()];
    if !sorted.is_sorted_by(|a, b| a.0 <= b.0) {
        sorted.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
    }
    let mut hull = [(0.0f64, 0.0f64); BUCKETS];
    let mut h = 0;
    for &p in sorted.iter() {
        while h >= 2 {
            let (o, a) = (hull[h - 2], hull[h - 1]);
            let cross = (a.0 - o.0) * (p.1 - o.1) - (a.1 - o.1) * (p.0 - o.0);
            if cross > 0.0 {
                break;
            }
            h -= 1;
        }
        hull[h] = p;
        h += 1;
    }
    let mean_x = sorted.iter().map(|p| p.0).sum::<f64>() / sorted.len().max(1) as f64;
    let edge = hull[..h]
        .windows(2)
        .find(|w| w[0].0 <= mean_x && mean_x <= w[1].0)?;
    let (a, b) = (edge[0], edge[1]);
    if b.0 <= a.0 {
        return None;
    }
    let drift = (b.1 - a.1) / (b.0 - a.0);
    Some((a.1 - drift * a.0, drift))
}

/// The straight line through the kept points, with the RMS of their residuals; `None` with too
/// few points or too short a baseline.
fn least_squares(points: &[Minimum], keep: &[bool]) -> Option<Line> {
    // One pass for the sums (relative to the first point, so they stay exact), one for the
    // residuals.
    let (x0, y0) = points.first().map(|p| (p.x_s, p.y_s))?;
    let (mut n, mut sx, mut sy, mut sxx, mut sxy) = (0usize, 0.0, 0.0, 0.0, 0.0);
    for (p, _) in points.iter().zip(keep).filter(|(_, k)| **k) {
        let (x, y) = (p.x_s - x0, p.y_s - y0);
        n += 1;
        sx += x;
        sy += y;
        sxx += x * x;
        sxy += x * y;
    }
    if n < MIN_BUCKETS {
        return None;
    }
    let nf = n as f64;
    let var_x = sxx - sx * sx / nf;
    if var_x < (2.0 * BUCKET_S).powi(2) {
        return None;
    }
    let drift = (sxy - sx * sy / nf) / var_x;
    let offset_s = y0 + (sy - drift * sx) / nf - drift * x0;
    let ss: f64 = points
        .iter()
        .zip(keep)
        .filter(|(_, k)| **k)
        .map(|(p, _)| (p.y_s - offset_s - drift * p.x_s).powi(2))
        .sum();
    Some(Line {
        offset_s,
        drift,
        residual_s: (ss / nf).sqrt(),
    })
}

/// Wall-clock stamps of samples: the monotonic stamp plus the host's wall-minus-monotonic
/// offset, which is followed at the same bounded slew (a wall-clock step, e.g. by NTP, is
/// spread over the following samples), so wall stamps are strictly increasing too.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct WallStamps {
    offset_ns: Option<f64>,
    last: Option<(u64, u64)>,
}

impl WallStamps {
    /// The wall-clock stamp of a sample stamped `t_sample_ns` (monotonic) that was read when
    /// the clocks showed `t_mono_ns` and `t_wall_ns`.
    pub fn stamp(&mut self, t_sample_ns: u64, t_mono_ns: u64, t_wall_ns: u64) -> u64 {
        let measured = t_wall_ns as f64 - t_mono_ns as f64;
        let offset = match (self.offset_ns, self.last) {
            (Some(o), Some((last_sample, _))) => {
                let spacing = t_sample_ns.saturating_sub(last_sample) as f64;
                let error = measured - o;
                let limit = if error.abs() > FAR_OFF_S * 1e9 {
                    0.5
                } else {
                    MAX_SLEW
                } * spacing;
                o + error.clamp(-limit, limit)
            }
            _ => measured,
        };
        self.offset_ns = Some(offset);
        let stamp = ((t_sample_ns as f64 + offset).max(0.0) as u64).max(
            self.last
                .map_or(0, |(_, w)| w.saturating_add(MIN_SPACING_NS)),
        );
        self.last = Some((t_sample_ns, stamp));
        stamp
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator.
    struct Lcg(u64);
    impl Lcg {
        fn unit(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// Runs `n` samples at 100 Hz on 6.5536 ms ticks through the fit: the device runs
    /// `drift_ppm` fast, arrivals carry 2 ms latency plus up to `jitter_s`, and the host stalls
    /// for `stall_s` every `stall_every` samples. Returns the fit and the stamps.
    fn simulate(
        drift_ppm: f64,
        jitter_s: f64,
        stall_s: f64,
        stall_every: u64,
        n: u64,
    ) -> (ClockFit, Vec<u64>, Vec<f64>) {
        let period = 6.5536e-3;
        let step = 0.01 / period;
        let mut fit = ClockFit::new(period);
        let mut rng = Lcg(3);
        let (mut stamps, mut truth) = (Vec::new(), Vec::new());
        let mut stall_until = 0.0f64;
        for k in 0..n {
            // True host time of the sample: the device's 10 ms are shorter when it runs fast.
            let t_true = 100.0 + k as f64 * 0.01 / (1.0 + drift_ppm * 1e-6);
            if stall_every > 0 && k % stall_every == stall_every / 2 {
                stall_until = t_true + stall_s;
            }
            let arrival = (t_true + 0.002 + jitter_s * rng.unit()).max(stall_until);
            let spacing = if k == 0 { 0.0 } else { step };
            stamps.push(fit.update(k as f64 * step + 12.3, spacing, (arrival * 1e9) as u64));
            truth.push(t_true);
        }
        (fit, stamps, truth)
    }

    #[test]
    fn stalls_of_a_second_bend_neither_stamps_nor_drift() {
        let (fit, stamps, truth) = simulate(150.0, 0.02, 1.0, 1500, 60_000);
        assert!(
            stamps.windows(2).all(|w| w[1] > w[0]),
            "strictly increasing"
        );
        let drift = fit.drift_ppm().unwrap();
        assert!((drift - 150.0).abs() < 100.0, "drift {drift} ppm");
        // After the first minute stamps are the true times plus the least latency (2 ms),
        // within a millisecond, stalls or not.
        for (s, t) in stamps.iter().zip(&truth).skip(6000) {
            let err = *s as f64 * 1e-9 - t - 0.002;
            assert!(err.abs() < 1e-3, "stamp error {err}");
        }
        assert!(fit.residual_s().unwrap() < 1e-3);
        let period = fit.tick_period_s().unwrap();
        assert!((period / (6.5536e-3 / (1.0 + 150e-6)) - 1.0).abs() < 100e-6);
    }

    #[test]
    fn spacing_follows_the_device_clock_through_host_jitter() {
        let (fit, stamps, _) = simulate(0.0, 0.02, 0.0, 0, 20_000);
        assert!(fit.drift_ppm().unwrap().abs() < 10.0);
        // Past the start-up, every spacing is 10 ms within the slew limit.
        for w in stamps[2000..].windows(2) {
            let dt = (w[1] - w[0]) as f64 * 1e-9;
            // (The fitted rate and whole nanoseconds add a little to the slew limit.)
            assert!(
                (dt - 0.01).abs() <= 0.01 * MAX_SLEW * 1.01 + 2e-9,
                "spacing {dt}"
            );
        }
    }

    #[test]
    fn wall_stamps_absorb_a_wall_clock_step_back() {
        let mut w = WallStamps::default();
        let wall0 = 1_700_000_000_000_000_000u64;
        let mut last = 0;
        for k in 0..3000u64 {
            let mono = 1_000_000_000 + k * 10_000_000;
            // The wall clock steps back by 2 s at sample 1000.
            let wall = wall0 + k * 10_000_000 - if k >= 1000 { 2_000_000_000 } else { 0 };
            let s = w.stamp(mono, mono + 300_000, wall + 300_000);
            assert!(s > last, "sample {k}");
            last = s;
        }
        // Caught up with the stepped clock again (half the spacing per sample while far off).
        let expected = wall0 + 2999 * 10_000_000 - 2_000_000_000;
        assert!(last.abs_diff(expected) < 1_000_000, "{last} vs {expected}");
    }

    #[test]
    fn reset_keeps_stamps_increasing() {
        let mut fit = ClockFit::new(0.01);
        let a = fit.update(100.0, 0.0, 5_000_000_000);
        fit.reset();
        // The new session's host times start earlier than the last stamp (a slewed fit).
        let b = fit.update(3.0, 0.0, 4_999_000_000);
        assert!(b > a);
        assert!(fit.drift_ppm().is_none());
    }
}
