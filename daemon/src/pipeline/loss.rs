//! Loss accounting of a continuous stream: the device's sample clock tells how many samples
//! fell between two that arrived; losses are logged in bursts.
//!
//! Two kinds of device clock need two trackers. A coarse counter (the 3DM-GX1's 6.5536 ms
//! ticks, one or two per sample) quantises every stamp by up to a sample interval, so
//! [`GapTracker`] places samples by set membership on the exact tick line (its search is as
//! fine as the tick line needs, so it is not for clocks of thousands of ticks a sample). A fine
//! clock (a MIP unit's reference time in ns, or its 62.5 kHz internal timestamp: at least 60
//! ticks a sample) quantises by a small fraction of an interval and may jitter by the device's
//! own latency, which that exact fit would not tolerate: [`FineGapTracker`] rounds each spacing
//! to whole sample intervals of a period measured over the whole session.

use tracing::warn;

use crate::gaps::{GapStep, GapTracker};

/// How the device's sample clock compares with the sample interval.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TickKind {
    /// About one tick a sample (the 3DM-GX1): ticks floor the true time by up to an interval.
    #[default]
    Coarse,
    /// Many ticks a sample (a MIP unit's ns or 62.5 kHz clocks): a stamp is exact to a small
    /// fraction of an interval, up to the device's stamping jitter.
    Fine,
}

/// Loss accounting of a continuous stream: the tracker and the log of loss bursts.
#[derive(Debug, Clone, Default)]
pub(super) struct GapAccounting {
    /// Only continuous streams are paced by the device; polls are the host's.
    pub(super) enabled: bool,
    pub(super) kind: TickKind,
    tracker: GapTracker,
    fine: FineGapTracker,
    burst: Option<LossBurst>,
    /// The previous sample's ticks (polls only).
    last_ticks: Option<u64>,
}

/// Intervals measured before a fine clock's sample period is trusted.
const FINE_LEARN_INTERVALS: usize = 32;

/// Losses of a stream on a fine clock: each spacing in whole periods, the period the
/// session's span over the intervals counted so far (so it follows the device's oscillator,
/// not the nominal rate).
#[derive(Debug, Clone, Default)]
pub(super) struct FineGapTracker {
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
    pub(super) fn push(&mut self, ticks: u64) -> GapStep {
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

/// Losses close together, logged once when the link has been clean for [`BURST_QUIET_S`].
#[derive(Debug, Clone, Copy, PartialEq)]
struct LossBurst {
    first_seq: u64,
    lost: u64,
    gaps: u64,
    last_gap_ticks: f64,
}

/// A loss burst ends after this much device time without a loss, s.
const BURST_QUIET_S: f64 = 1.0;

impl GapAccounting {
    /// Fresh accounting: on for a continuous stream, on a clock of `kind`.
    pub(super) fn new(enabled: bool, kind: TickKind) -> Self {
        Self {
            enabled,
            kind,
            ..Self::default()
        }
    }

    /// Accounts the sample `seq` at `ticks_unwrapped`: returns the loss step and whether a gap
    /// precedes it.
    pub(super) fn on_sample(
        &mut self,
        seq: u64,
        ticks_unwrapped: u64,
        tick_period_s: f64,
    ) -> GapStep {
        if !self.enabled {
            // Polls: each sample's own tick interval, no losses to count.
            let spacing_ticks = self
                .last_ticks
                .map_or(0.0, |l| ticks_unwrapped.saturating_sub(l) as f64);
            self.last_ticks = Some(ticks_unwrapped);
            return GapStep {
                lost_before: 0,
                lost_earlier: 0,
                position_ticks: ticks_unwrapped as f64 + 0.5,
                spacing_ticks,
                learned: false,
            };
        }
        let step = match self.kind {
            TickKind::Coarse => self.tracker.push(ticks_unwrapped),
            TickKind::Fine => self.fine.push(ticks_unwrapped),
        };
        let lost = step.lost_before + step.lost_earlier;
        if lost > 0 {
            let b = self.burst.get_or_insert(LossBurst {
                first_seq: seq,
                lost: 0,
                gaps: 0,
                last_gap_ticks: step.position_ticks,
            });
            b.lost += lost;
            b.gaps += 1;
            b.last_gap_ticks = step.position_ticks;
        } else if let Some(b) = self.burst
            && (step.position_ticks - b.last_gap_ticks) * tick_period_s > BURST_QUIET_S
        {
            warn!(
                "device link lost {} sample(s) in {} gap(s) from sample {} to {}",
                b.lost,
                b.gaps,
                b.first_seq,
                seq.saturating_sub(1)
            );
            self.burst = None;
        }
        step
    }
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
