//! Online fit of the device clock against the host clock.
//!
//! The device stamps each sample with a 16-bit tick counter whose period is disputed (6.5536 ms
//! on most units, 10 ms on reprogrammed ones) and whose oscillator drifts. The host knows when
//! each frame's last byte arrived. A sliding-window least-squares line `host = a + b * ticks`
//! gives every sample a host-timebase time free of the host's read jitter, plus an estimate of
//! the real tick period and the drift in ppm, which the daemon reports.

use std::collections::VecDeque;

/// Points kept in the sliding window.
const WINDOW: usize = 4096;
/// The fit is trusted once the window spans this many seconds of host time.
const MIN_SPAN_S: f64 = 2.0;

/// The fit's state.
#[derive(Debug, Clone)]
pub struct ClockFit {
    nominal_tick_period_s: f64,
    points: VecDeque<(f64, f64)>,
    origin: Option<(u64, u64)>,
    sx: f64,
    sy: f64,
    sxx: f64,
    sxy: f64,
}

impl ClockFit {
    /// A fit that starts from the nominal tick period.
    pub fn new(nominal_tick_period_s: f64) -> Self {
        Self {
            nominal_tick_period_s,
            points: VecDeque::with_capacity(WINDOW),
            origin: None,
            sx: 0.0,
            sy: 0.0,
            sxx: 0.0,
            sxy: 0.0,
        }
    }

    /// Forgets everything (after a reconnect the device may have been power-cycled).
    pub fn reset(&mut self) {
        *self = Self::new(self.nominal_tick_period_s);
    }

    /// Adds a sample (unwrapped ticks, host monotonic receive time) and returns its fitted host
    /// time in ns.
    pub fn update(&mut self, ticks_unwrapped: u64, host_ns: u64) -> u64 {
        let (t0, h0) = *self.origin.get_or_insert((ticks_unwrapped, host_ns));
        let x = ticks_unwrapped as f64 - t0 as f64;
        let y = (host_ns as f64 - h0 as f64) * 1e-9;
        if self.points.len() == WINDOW
            && let Some((ox, oy)) = self.points.pop_front()
        {
            self.sx -= ox;
            self.sy -= oy;
            self.sxx -= ox * ox;
            self.sxy -= ox * oy;
        }
        self.points.push_back((x, y));
        self.sx += x;
        self.sy += y;
        self.sxx += x * x;
        self.sxy += x * y;
        let fitted_s = match self.line() {
            Some((a, b)) => a + b * x,
            // Until the fit is trusted: nominal period, anchored at the earliest-arriving point
            // (the one with the least latency).
            None => {
                let offset = self
                    .points
                    .iter()
                    .map(|&(px, py)| py - px * self.nominal_tick_period_s)
                    .fold(f64::INFINITY, f64::min);
                offset + x * self.nominal_tick_period_s
            }
        };
        (h0 as f64 + fitted_s * 1e9).max(0.0) as u64
    }

    fn line(&self) -> Option<(f64, f64)> {
        let n = self.points.len() as f64;
        let span = self.points.back()?.1 - self.points.front()?.1;
        if self.points.len() < 20 || span < MIN_SPAN_S {
            return None;
        }
        let var = self.sxx - self.sx * self.sx / n;
        if var <= 0.0 {
            return None;
        }
        let b = (self.sxy - self.sx * self.sy / n) / var;
        let a = (self.sy - b * self.sx) / n;
        Some((a, b))
    }

    /// Estimated tick period in host seconds, once the fit is trusted.
    pub fn tick_period_s(&self) -> Option<f64> {
        self.line().map(|(_, b)| b)
    }

    /// Device clock rate error against the host, ppm (positive: the device runs fast).
    pub fn drift_ppm(&self) -> Option<f64> {
        self.tick_period_s()
            .map(|b| (self.nominal_tick_period_s / b - 1.0) * 1e6)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_period_and_drift_through_jitter_and_quantization() {
        let nominal = 6.5536e-3;
        let drift_ppm = 150.0;
        let mut fit = ClockFit::new(nominal);
        let mut jitter = 0u64;
        for k in 0..3000u64 {
            let t_true = k as f64 * 0.01;
            let ticks = (t_true * (1.0 + drift_ppm * 1e-6) / nominal).floor() as u64 + 777;
            // Host receive time: 3 ms latency plus up to 2 ms of pseudo-random jitter.
            jitter = (jitter * 1_103_515_245 + 12_345) % 2_000_000;
            let host_ns = 5_000_000_000 + (t_true * 1e9) as u64 + 3_000_000 + jitter;
            fit.update(ticks, host_ns);
        }
        let period = fit.tick_period_s().unwrap();
        let expected = nominal / (1.0 + drift_ppm * 1e-6);
        assert!((period / expected - 1.0).abs() < 20e-6, "period {period}");
        assert!((fit.drift_ppm().unwrap() - drift_ppm).abs() < 20.0);
    }

    #[test]
    fn nominal_until_trusted() {
        let mut fit = ClockFit::new(0.01);
        assert_eq!(fit.update(100, 1_000_000_000), 1_000_000_000);
        assert_eq!(fit.update(110, 1_100_000_000), 1_100_000_000);
        assert!(fit.tick_period_s().is_none());
    }
}
