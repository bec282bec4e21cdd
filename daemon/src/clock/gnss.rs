//! Wall stamps that follow the unit's GNSS time (`device.time-source = "gnss"`).
//!
//! A unit's GNSS time is UTC but quantised (a receiver's time tag, a time of week in whole
//! milliseconds), while its sample clock is smooth but drifts. So the stamps come from a
//! straight line of `GNSS time - device time` against device time: least squares through
//! per-[`BUCKET_S`] means of the valid GNSS points of the last [`BUCKETS`] buckets, which
//! averages the quantisation away and measures the device clock's rate against GNSS time.
//!
//! While GNSS time is invalid or absent the line is held over (extrapolated on the device
//! clock with its last offset and rate); when it returns the new points join the same line, and
//! a difference that built up in the outage is slewed out at the bounded rate of
//! [`super::WallStamps`] ([`super::MAX_SLEW`], half the spacing while far off), so stamps never
//! step back and never jump. After a device session ends (its clock restarts) there is no line
//! to hold: the stamps are then the host wall stamps plus the last GNSS-minus-wall offset.
//! Stamps are strictly increasing throughout.

use imu_bus::sample::time_sync;
use imu_proto::gnss_time::GnssTime;

use super::{FAR_OFF_S, MAX_SLEW, MIN_SPACING_NS};

/// Device time per bucket of GNSS points, s.
pub const BUCKET_S: f64 = 1.0;
/// Buckets the line is fitted through (its baseline, s, at one bucket per second).
pub const BUCKETS: usize = 64;
/// The rate is fitted once the bucket means span this much device time, s (before: offset
/// only, the rate of the previous line or none).
const RATE_BASELINE_S: f64 = 2.0;
/// Holdover longer than this, s of device time, is reported as `gnss-lost` (the stamps still
/// follow the held line: the device clock's rate wander is what its error then grows with).
pub const HOLDOVER_LIMIT_S: f64 = 60.0;
/// A valid GNSS time this far from the line is a step of the unit's time (a new fix that
/// corrected it): the fit starts again from it, s.
const STEP_S: f64 = 1.0;

/// Where the GNSS stamps stand ([`time_sync`] codes).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum GnssState {
    /// No valid GNSS time seen yet: stamps are the host wall stamps.
    #[default]
    None,
    /// The latest sample carried valid GNSS time and the line follows it.
    Locked,
    /// GNSS time is invalid or absent; stamps follow the held line.
    Holdover,
    /// Held over longer than [`HOLDOVER_LIMIT_S`], or the device session that had the line
    /// ended: stamps follow the held line, or the host wall clock plus the last offset.
    Lost,
}

impl GnssState {
    /// The state's [`time_sync`] code.
    pub fn code(self) -> u8 {
        match self {
            GnssState::None => time_sync::NONE,
            GnssState::Locked => time_sync::GNSS_LOCKED,
            GnssState::Holdover => time_sync::GNSS_HOLDOVER,
            GnssState::Lost => time_sync::GNSS_LOST,
        }
    }
}

/// Sums of the points of one bucket (device time and GNSS-minus-device time, ns from the
/// line's origin).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Bucket {
    key: i64,
    n: f64,
    sum_x_ns: f64,
    sum_y_ns: f64,
}

/// `GNSS time - device time = offset_ns + rate * device time` (ns from the origin).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Line {
    offset_ns: f64,
    rate: f64,
    /// The rate was fitted (not assumed).
    rate_fitted: bool,
}

/// The previous stamp and the times it was made from.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Last {
    device_ns: u64,
    sample_ns: u64,
    stamp_ns: i64,
    /// Made in the current device session.
    this_session: bool,
}

/// The GNSS stamping state for one daemon run (the line is per device session).
#[derive(Debug, Clone)]
pub struct GnssClock {
    /// Device ns and GNSS UTC ns of the line's first point.
    origin: Option<(u64, i64)>,
    buckets: [Bucket; BUCKETS],
    n_buckets: usize,
    next: usize,
    current: Option<Bucket>,
    line: Option<Line>,
    last: Option<Last>,
    /// Device ns of the latest valid GNSS time of this session.
    last_valid_device_ns: Option<u64>,
    /// GNSS stamp minus host wall stamp of the latest sample that had a line, ns.
    minus_wall_ns: Option<f64>,
    valid_now: bool,
    valid_transitions: u64,
    lost_transitions: u64,
    state: GnssState,
}

impl Default for GnssClock {
    fn default() -> Self {
        Self::new()
    }
}

impl GnssClock {
    /// No line, no stamps yet.
    pub fn new() -> Self {
        Self {
            origin: None,
            buckets: [Bucket::default(); BUCKETS],
            n_buckets: 0,
            next: 0,
            current: None,
            line: None,
            last: None,
            last_valid_device_ns: None,
            minus_wall_ns: None,
            valid_now: false,
            valid_transitions: 0,
            lost_transitions: 0,
            state: GnssState::None,
        }
    }

    /// A new device session: its clock restarts, so the line goes; the last stamp, the offset
    /// to the wall clock and the counts stay.
    pub fn reset(&mut self) {
        self.forget_line();
        self.last_valid_device_ns = None;
        if let Some(l) = &mut self.last {
            l.this_session = false;
        }
        if self.valid_now {
            self.valid_now = false;
            self.lost_transitions += 1;
        }
        if self.state != GnssState::None {
            self.state = GnssState::Lost;
        }
    }

    fn forget_line(&mut self) {
        self.origin = None;
        self.n_buckets = 0;
        self.next = 0;
        self.current = None;
        self.line = None;
    }

    /// The wall stamp, UTC ns, of a sample at device time `t_device_ns` (this session's
    /// clock), monotonic stamp `t_sample_ns`, carrying `gnss` (if the unit sent a GNSS time),
    /// whose host wall stamp ([`super::WallStamps`]) is `wall_ns`.
    pub fn stamp(
        &mut self,
        t_device_ns: u64,
        t_sample_ns: u64,
        gnss: Option<GnssTime>,
        wall_ns: u64,
    ) -> u64 {
        let valid = gnss.filter(|g| g.valid);
        if let Some(g) = valid {
            self.add_point(t_device_ns, g.utc_ns);
            self.last_valid_device_ns = Some(t_device_ns);
            if !self.valid_now {
                self.valid_transitions += 1;
            }
        } else if self.valid_now {
            self.lost_transitions += 1;
        }
        self.valid_now = valid.is_some();
        let target_ns = match self.line_at(t_device_ns) {
            Some(t) => t,
            None => wall_ns as i64 + self.minus_wall_ns.map_or(0, |o| o.round() as i64),
        };
        let stamp = match self.last {
            Some(last) => {
                let spacing_ns = if last.this_session && t_device_ns >= last.device_ns {
                    let rate = self.line.map_or(0.0, |l| l.rate);
                    (t_device_ns - last.device_ns) as f64 * (1.0 + rate)
                } else {
                    t_sample_ns.saturating_sub(last.sample_ns) as f64
                };
                let error = (target_ns - last.stamp_ns) as f64 - spacing_ns;
                let limit = if error.abs() > FAR_OFF_S * 1e9 {
                    0.5
                } else {
                    MAX_SLEW
                } * spacing_ns;
                let step = (spacing_ns + error.clamp(-limit, limit)).round() as i64;
                last.stamp_ns + step.max(MIN_SPACING_NS as i64)
            }
            None => target_ns,
        };
        let stamp = stamp.max(0);
        if self.line.is_some() {
            self.minus_wall_ns = Some((target_ns - wall_ns as i64) as f64);
        }
        self.last = Some(Last {
            device_ns: t_device_ns,
            sample_ns: t_sample_ns,
            stamp_ns: stamp,
            this_session: true,
        });
        self.state = self.next_state(t_device_ns);
        stamp as u64
    }

    fn next_state(&self, t_device_ns: u64) -> GnssState {
        match (self.line, self.last_valid_device_ns) {
            (Some(_), Some(_)) if self.valid_now => GnssState::Locked,
            (Some(_), Some(v)) => {
                let held_s = t_device_ns.saturating_sub(v) as f64 * 1e-9;
                if held_s > HOLDOVER_LIMIT_S {
                    GnssState::Lost
                } else {
                    GnssState::Holdover
                }
            }
            _ if self.minus_wall_ns.is_some() => GnssState::Lost,
            _ => GnssState::None,
        }
    }

    /// The line's GNSS time at device time `t_device_ns`, UTC ns.
    fn line_at(&self, t_device_ns: u64) -> Option<i64> {
        let (line, (d0, u0)) = (self.line?, self.origin?);
        let x_ns = t_device_ns as f64 - d0 as f64;
        Some(u0 + (x_ns + line.offset_ns + line.rate * x_ns).round() as i64)
    }

    /// Adds a valid GNSS time to its bucket and refits.
    fn add_point(&mut self, t_device_ns: u64, utc_ns: i64) {
        let stepped = self
            .line_at(t_device_ns)
            .is_some_and(|p| (utc_ns - p).unsigned_abs() as f64 > STEP_S * 1e9);
        if stepped {
            self.forget_line();
        }
        let (d0, u0) = *self.origin.get_or_insert((t_device_ns, utc_ns));
        let x_ns = t_device_ns as f64 - d0 as f64;
        let y_ns = (utc_ns - u0) as f64 - x_ns;
        let key = (x_ns * 1e-9 / BUCKET_S).floor() as i64;
        match &mut self.current {
            Some(b) if b.key == key => {}
            Some(b) => {
                self.buckets[self.next] = *b;
                self.next = (self.next + 1) % BUCKETS;
                self.n_buckets = (self.n_buckets + 1).min(BUCKETS);
                self.current = None;
            }
            None => {}
        }
        let b = self.current.get_or_insert(Bucket {
            key,
            ..Bucket::default()
        });
        b.n += 1.0;
        b.sum_x_ns += x_ns;
        b.sum_y_ns += y_ns;
        self.refit();
    }

    /// Weighted least squares through the bucket means (the open bucket's too), centred so
    /// that hours of device time lose no precision.
    fn refit(&mut self) {
        let buckets = || self.buckets[..self.n_buckets].iter().chain(&self.current);
        let (mut n, mut sx, mut sy) = (0.0, 0.0, 0.0);
        for b in buckets() {
            n += b.n;
            sx += b.sum_x_ns;
            sy += b.sum_y_ns;
        }
        if n == 0.0 {
            return;
        }
        let (mean_x, mean_y) = (sx / n, sy / n);
        let (mut sxx, mut sxy) = (0.0, 0.0);
        for b in buckets() {
            let (dx, dy) = (b.sum_x_ns / b.n - mean_x, b.sum_y_ns / b.n - mean_y);
            sxx += b.n * dx * dx;
            sxy += b.n * dx * dy;
        }
        let spread_s = (sxx / n).sqrt() * 1e-9;
        // Bucket means spread evenly over a baseline L have a deviation of L / sqrt(12).
        let (rate, rate_fitted) = if spread_s * 12f64.sqrt() >= RATE_BASELINE_S {
            (sxy / sxx, true)
        } else {
            (self.line.map_or(0.0, |l| l.rate), false)
        };
        self.line = Some(Line {
            offset_ns: mean_y - rate * mean_x,
            rate,
            rate_fitted,
        });
    }

    /// Where the stamps stand.
    pub fn state(&self) -> GnssState {
        self.state
    }

    /// GNSS time minus host wall time at the latest sample that had a line, s.
    pub fn minus_wall_s(&self) -> Option<f64> {
        self.minus_wall_ns.map(|o| o * 1e-9)
    }

    /// The device clock's rate error against GNSS time, ppm (positive: the device runs fast),
    /// once fitted.
    pub fn drift_ppm(&self) -> Option<f64> {
        self.line
            .filter(|l| l.rate_fitted)
            .map(|l| (1.0 / (1.0 + l.rate) - 1.0) * 1e6)
    }

    /// Times GNSS time became valid, and times it was lost (went invalid or absent, or the
    /// session that had it ended).
    pub fn transitions(&self) -> (u64, u64) {
        (self.valid_transitions, self.lost_transitions)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const EPOCH_UTC_NS: i64 = 1_750_000_000_000_000_000;

    /// Sample period, s: not a whole number of GNSS quanta, so the quantisation error takes
    /// every value over the run.
    const PERIOD_S: f64 = 0.010_037;

    /// A synthetic unit at about 100 Hz whose clock runs `drift_ppm` fast: GNSS time quantised to
    /// `quantum_ns`, invalid while `outage(t_s)`; the host wall clock is `wall_offset_s` off
    /// UTC. Returns (true UTC ns, stamp, state) per sample.
    fn run(
        clock: &mut GnssClock,
        n: u64,
        drift_ppm: f64,
        quantum_ns: i64,
        wall_offset_s: f64,
        outage: impl Fn(f64) -> bool,
    ) -> Vec<(i64, u64, GnssState)> {
        (0..n)
            .map(|k| {
                let t_s = k as f64 * PERIOD_S;
                let true_utc = EPOCH_UTC_NS + (t_s * 1e9).round() as i64;
                let device_ns = (5.0e9 + t_s * 1e9 * (1.0 + drift_ppm * 1e-6)) as u64;
                let sample_ns = (1.0e12 + t_s * 1e9) as u64;
                let wall = (true_utc as f64 + wall_offset_s * 1e9) as u64;
                let gnss = GnssTime {
                    utc_ns: true_utc.div_euclid(quantum_ns) * quantum_ns,
                    valid: !outage(t_s),
                };
                let stamp = clock.stamp(device_ns, sample_ns, Some(gnss), wall);
                (true_utc, stamp, clock.state())
            })
            .collect()
    }

    /// The index of the first sample at or after `t_s`.
    fn at(t_s: f64) -> usize {
        (t_s / PERIOD_S).ceil() as usize
    }

    fn err_s(r: &(i64, u64, GnssState)) -> f64 {
        (r.1 as i64 - r.0) as f64 * 1e-9
    }

    #[test]
    fn locked_stamps_average_the_quantisation_and_measure_the_drift() {
        let mut c = GnssClock::new();
        // 1 ms quantum, 150 ppm, the host 0.3 s off UTC.
        let out = run(&mut c, 12_000, 150.0, 1_000_000, 0.3, |_| false);
        assert!(
            out.windows(2).all(|w| w[1].1 > w[0].1),
            "strictly increasing"
        );
        assert!(out.iter().all(|r| r.2 == GnssState::Locked));
        // After 10 s (the first stamps slew from the first point's quantised time), the
        // stamps are the true times within 100 us: the quantum's mean (0.5 ms) is a bias.
        for r in &out[1000..] {
            let e = err_s(r) + 0.5e-3;
            assert!(e.abs() < 100e-6, "error {e} s");
        }
        let drift = c.drift_ppm().unwrap();
        assert!((drift - 150.0).abs() < 1.0, "drift {drift} ppm");
        let offset = c.minus_wall_s().unwrap();
        assert!((offset + 0.3 + 0.5e-3).abs() < 1e-4, "offset {offset} s");
        assert_eq!(c.transitions(), (1, 0));
    }

    #[test]
    fn holdover_follows_the_held_rate_and_the_return_is_slewed() {
        let mut c = GnssClock::new();
        // Valid for 60 s, out 60-90 s (30 s), back after; the device runs 150 ppm fast.
        let outage = |t: f64| (60.0..90.0).contains(&t);
        let out = run(&mut c, 15_000, 150.0, 1, 0.0, outage);
        assert!(
            out.windows(2).all(|w| w[1].1 > w[0].1),
            "strictly increasing"
        );
        let states: Vec<GnssState> = out.iter().map(|r| r.2).collect();
        assert_eq!(states[at(60.0) - 1], GnssState::Locked);
        assert_eq!(states[at(60.0)], GnssState::Holdover);
        assert_eq!(states[at(90.0) - 1], GnssState::Holdover);
        assert_eq!(states[at(90.0)], GnssState::Locked);
        // Holdover on the fitted rate: far inside drift x outage (150 ppm x 30 s = 4.5 ms).
        for r in &out[3000..] {
            assert!(err_s(r).abs() < 10e-6, "error {} s", err_s(r));
        }
        assert_eq!(c.transitions(), (2, 1));
    }

    #[test]
    fn a_holdover_with_an_unfitted_rate_is_bounded_by_drift_times_outage_and_slews_back() {
        let mut c = GnssClock::new();
        // GNSS valid only for the first second: no rate is fitted, so the holdover runs on the
        // device clock alone and gains 150 ppm x 20 s = 3 ms.
        let outage = |t: f64| (1.0..21.0).contains(&t);
        let out = run(&mut c, 4_000, 150.0, 1, 0.0, outage);
        assert!(
            out.windows(2).all(|w| w[1].1 > w[0].1),
            "strictly increasing"
        );
        for r in &out[100..at(21.0)] {
            let t_s = (r.0 - EPOCH_UTC_NS) as f64 * 1e-9;
            // Offset only (no rate yet): the drift since the first points' mean time.
            let bound = 150e-6 * t_s.max(0.5) + 20e-6;
            assert!(err_s(r).abs() <= bound, "error {} s at {t_s} s", err_s(r));
        }
        assert_eq!(out[at(20.0)].2, GnssState::Holdover);
        // Back at 21 s: the 3 ms are slewed out at 5000 ppm of the spacing (0.6 s), never a
        // step of more than the slew.
        for w in out[at(21.0) - 1..at(23.0)].windows(2) {
            let dt = (w[1].1 - w[0].1) as f64 * 1e-9;
            assert!(
                (dt - PERIOD_S).abs() <= PERIOD_S * (MAX_SLEW + 200e-6),
                "spacing {dt} s"
            );
        }
        for r in &out[at(23.0)..] {
            assert!(err_s(r).abs() < 20e-6, "error {} s", err_s(r));
        }
        assert_eq!(out[3999].2, GnssState::Locked);
    }

    #[test]
    fn without_gnss_the_stamps_are_the_wall_stamps_and_a_long_holdover_is_lost() {
        let mut c = GnssClock::new();
        // Never valid: the wall stamps pass through.
        let out = run(&mut c, 300, 0.0, 1, 0.25, |_| true);
        assert!(out.iter().all(|r| r.2 == GnssState::None));
        assert!(out.iter().all(|r| (err_s(r) - 0.25).abs() < 1e-6));
        assert_eq!(c.transitions(), (0, 0));
        let mut c = GnssClock::new();
        let out = run(&mut c, 8_000, 20.0, 1, 0.0, |t| t >= 10.0);
        assert_eq!(out[at(69.0)].2, GnssState::Holdover);
        assert_eq!(out[7999].2, GnssState::Lost);
        assert!(out.windows(2).all(|w| w[1].1 > w[0].1));
    }

    #[test]
    fn a_step_of_the_units_gnss_time_restarts_the_fit_and_is_slewed_to() {
        let mut c = GnssClock::new();
        // At 20 s the unit's time jumps 2 s ahead (a corrected fix): from then on that is the
        // truth it reports.
        let out = run(&mut c, 3_000, 50.0, 1, 0.0, |_| false);
        let mut last = out.last().unwrap().1;
        let mut utc_at = 0;
        for k in 3_000..4_500u64 {
            let t_s = k as f64 * PERIOD_S;
            utc_at = EPOCH_UTC_NS + (t_s * 1e9).round() as i64 + 2_000_000_000;
            let device_ns = (5.0e9 + t_s * 1e9 * (1.0 + 50e-6)) as u64;
            let gnss = GnssTime {
                utc_ns: utc_at,
                valid: true,
            };
            let s = c.stamp(device_ns, (1.0e12 + t_s * 1e9) as u64, Some(gnss), 0);
            // Forward at most 1.5 spacings a sample (half the spacing of slew while far off).
            assert!(s > last && s - last <= (1.5 * PERIOD_S * 1e9) as u64 + 1_000);
            last = s;
        }
        // 2 s at half a spacing a sample: caught up after 400 samples.
        assert!(
            (last as i64 - utc_at).abs() < 1_000,
            "{}",
            last as i64 - utc_at
        );
        assert_eq!(c.state(), GnssState::Locked);
    }

    #[test]
    fn a_new_session_holds_the_offset_to_the_wall_clock() {
        let mut c = GnssClock::new();
        let first = run(&mut c, 1_000, 0.0, 1, -2.0, |_| false);
        c.reset();
        assert_eq!(c.state(), GnssState::Lost);
        // The next session's device clock starts again; GNSS is absent. Stamps are the wall
        // clock (2 s behind) plus the held offset, so still UTC, and later than the last.
        let t_ns = (1000.0 * PERIOD_S * 1e9) as i64;
        let wall = (EPOCH_UTC_NS + t_ns - 2_000_000_000) as u64;
        let s = c.stamp(1_000, 1_000_000_000_000 + t_ns as u64, None, wall);
        assert!(s > first.last().unwrap().1);
        assert!((s as i64 - (EPOCH_UTC_NS + t_ns)).abs() < 1_000);
        assert_eq!(c.transitions(), (1, 1));
    }
}
