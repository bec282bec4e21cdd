//! Loss accounting, the one home of it: the device's sample clock tells how many samples fell
//! between two that arrived; losses are logged in bursts.
//!
//! Two kinds of device clock need two trackers. A coarse counter (one or two ticks a sample)
//! quantises every stamp by up to a sample interval, so [`GapTracker`] (`coarse.rs`) places
//! samples by set membership on the exact tick line (its search is as fine as the tick line
//! needs, so it is not for clocks of thousands of ticks a sample). A fine clock (ns, or tens of
//! kHz: at least 60 ticks a sample) quantises by a small fraction of an interval and may jitter
//! by the device's own latency, which that exact fit would not tolerate: [`FineGapTracker`]
//! (`fine.rs`) rounds each spacing to whole sample intervals of a period measured over the
//! whole session. A polled session counts no losses: its intervals are the host's.

pub mod coarse;
pub mod fine;

use tracing::warn;

pub use coarse::{GapStep, GapTracker};
pub use fine::FineGapTracker;

use super::reading::Acquisition;

/// How the device's sample clock compares with the sample interval.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TickKind {
    /// About one tick a sample: ticks floor the true time by up to an interval.
    #[default]
    Coarse,
    /// Many ticks a sample: a stamp is exact to a small fraction of an interval, up to the
    /// device's stamping jitter.
    Fine,
}

/// The tracker a session's samples go through.
#[derive(Debug, Clone)]
enum Tracker {
    /// Polls: no losses; the previous sample's ticks, for each sample's spacing.
    Polled { last_ticks: Option<u64> },
    /// A streaming session on a coarse clock.
    Coarse(Box<GapTracker>),
    /// A streaming session on a fine clock.
    Fine(FineGapTracker),
}

/// Loss accounting of a session: the tracker its acquisition and clock call for, and the log
/// of loss bursts.
#[derive(Debug, Clone)]
pub(super) struct GapAccounting {
    tracker: Tracker,
    burst: Option<LossBurst>,
}

impl Default for GapAccounting {
    /// Polled (no losses) until a session says otherwise.
    fn default() -> Self {
        Self::new(Acquisition::Polled { rate_hz: 0.0 }, TickKind::Coarse)
    }
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
    /// Fresh accounting for a session of `acquisition` on a clock of `kind`.
    pub(super) fn new(acquisition: Acquisition, kind: TickKind) -> Self {
        let tracker = match (acquisition, kind) {
            (Acquisition::Polled { .. }, _) => Tracker::Polled { last_ticks: None },
            (Acquisition::Streaming, TickKind::Coarse) => Tracker::Coarse(Box::default()),
            (Acquisition::Streaming, TickKind::Fine) => Tracker::Fine(FineGapTracker::default()),
        };
        Self {
            tracker,
            burst: None,
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
        let step = match &mut self.tracker {
            Tracker::Polled { last_ticks } => {
                // Polls: each sample's own tick interval, no losses to count.
                let spacing_ticks =
                    last_ticks.map_or(0.0, |l| ticks_unwrapped.saturating_sub(l) as f64);
                *last_ticks = Some(ticks_unwrapped);
                return GapStep {
                    lost_before: 0,
                    lost_earlier: 0,
                    position_ticks: ticks_unwrapped as f64 + 0.5,
                    spacing_ticks,
                    learned: false,
                };
            }
            Tracker::Coarse(t) => t.push(ticks_unwrapped),
            Tracker::Fine(t) => t.push(ticks_unwrapped),
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
