//! Losses on a fine device clock (many ticks a sample: a stamp is exact to a small fraction of
//! an interval, up to the device's own stamping jitter): each spacing rounded to whole sample
//! intervals of a period measured over the whole session.

use super::coarse::GapStep;

/// Intervals measured before a fine clock's sample period is trusted.
const FINE_LEARN_INTERVALS: usize = 32;

/// Losses of a stream on a fine clock: each spacing in whole periods, the period the
/// session's span over the intervals counted so far (so it follows the device's oscillator,
/// not the nominal rate).
#[derive(Debug, Clone, Default)]
pub struct FineGapTracker {
    /// The session's first stamp and the previous one, ticks.
    first: Option<u64>,
    last: u64,
    /// Sample intervals since the first stamp, losses included (once learned).
    intervals: u64,
    /// Spacings of the first intervals, ticks (learning).
    learning: Vec<u64>,
    period_ticks: Option<f64>,
}

impl FineGapTracker {
    /// Feeds the next sample's stamp, ticks.
    pub fn push(&mut self, ticks: u64) -> GapStep {
        let quiet = |spacing: u64| GapStep {
            lost_before: 0,
            lost_earlier: 0,
            position_ticks: ticks as f64,
            spacing_ticks: spacing as f64,
            learned: false,
        };
        let Some(first) = self.first.filter(|_| ticks > self.last) else {
            // The first sample, or the clock went back (a device reset): start again.
            *self = Self {
                first: Some(ticks),
                last: ticks,
                ..Self::default()
            };
            return quiet(0);
        };
        let spacing = ticks - self.last;
        self.last = ticks;
        let Some(period) = self.period_ticks else {
            self.learning.push(spacing);
            if self.learning.len() < FINE_LEARN_INTERVALS {
                return quiet(spacing);
            }
            // The median spacing is one interval (fewer than half of them hold a loss); the
            // learned spacings' losses are reported now.
            let mut sorted = self.learning.clone();
            sorted.sort_unstable();
            let median = sorted[sorted.len() / 2] as f64;
            self.intervals = self
                .learning
                .iter()
                .map(|&d| whole_intervals(d as f64, median))
                .sum();
            self.period_ticks = Some((ticks - first) as f64 / self.intervals as f64);
            let lost_earlier = self.intervals - self.learning.len() as u64;
            self.learning = Vec::new();
            return GapStep {
                lost_earlier,
                ..quiet(spacing)
            };
        };
        let n = whole_intervals(spacing as f64, period);
        self.intervals += n;
        self.period_ticks = Some((ticks - first) as f64 / self.intervals as f64);
        GapStep {
            lost_before: n - 1,
            ..quiet(spacing)
        }
    }
}

/// Whole sample intervals in a spacing, at least one (a stamp early by jitter is no loss).
fn whole_intervals(spacing: f64, period: f64) -> u64 {
    (spacing / period).round().max(1.0) as u64
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 1 kHz stream stamped in ns by an oscillator 80 ppm fast, with +-20 us of stamping
    /// jitter, and losses: single, a burst, and one among the learning samples.
    #[test]
    fn fine_stamps_count_every_loss_through_jitter_and_drift() {
        let mut t = FineGapTracker::default();
        let lost = [5u64, 600, 601, 602, 603, 9000];
        let (mut counted, mut flagged) = (0, 0);
        let mut rng = 12345u64;
        for k in 0..20_000u64 {
            rng = rng
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let jitter_ns = ((rng >> 33) % 40_001) as i64 - 20_000;
            if lost.contains(&k) {
                continue;
            }
            let t_ns = (5_000_000_000.0 + k as f64 * 1e6 * (1.0 - 80e-6)) as i64 + jitter_ns;
            let step = t.push(t_ns as u64);
            counted += step.lost_before + step.lost_earlier;
            flagged += u64::from(step.lost_before > 0);
        }
        assert_eq!(counted, lost.len() as u64);
        // The burst is one gap; the loss among the learning samples is counted, not flagged.
        assert_eq!(flagged, 2);
        let period = t.period_ticks.unwrap();
        // The span's end points carry the jitter: at most 2 x 20 us over 20000 intervals.
        assert!((period - 1e6 * (1.0 - 80e-6)).abs() < 2.0, "{period}");
    }

    #[test]
    fn a_fine_clock_that_goes_back_starts_again_without_counting_a_loss() {
        let mut t = FineGapTracker::default();
        let mut counted = 0;
        for k in 0..100u64 {
            counted += t.push(1_000_000_000 + k * 10_000_000).lost_before;
        }
        for k in 0..100u64 {
            let step = t.push(2_000 + k * 10_000_000);
            counted += step.lost_before + step.lost_earlier;
        }
        assert_eq!(counted, 0);
    }
}
