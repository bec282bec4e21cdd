//! Bounded-memory overlapping Allan deviation at octave taus, for multi-day recordings.

use super::{DevCurve, DevPoint, Kind, NoiseType, confidence_interval, edf_oadev};

/// Bounded-memory overlapping Allan deviation at octave taus, fed one rate sample at a time.
///
/// Keeps a ring of the last `2 m_max + 1` phase values and, per octave m = 2^k <= `m_max`, the
/// running sum of squared second differences; memory is O(m_max), independent of the recording
/// length, and the cost is O(log m_max) per sample. Results equal
/// [`deviation`](super::deviation) with [`Kind::Oadev`] and
/// [`TauSet::Octave`](super::TauSet::Octave) (same phase integration, same summation order, up
/// to the batch's four-way accumulator split).
#[derive(Debug, Clone)]
pub struct StreamingOadev {
    tau0_s: f64,
    ring: Vec<f64>,
    mask: usize,
    n_phase: usize,
    rate_sum: f64,
    sums: Vec<f64>,
    counts: Vec<usize>,
}

impl StreamingOadev {
    /// A new accumulator for rate data at period `tau0_s`, with octave taus up to
    /// `max_m` samples (rounded down to a power of two; at least 1).
    pub fn new(tau0_s: f64, max_m: usize) -> Self {
        let levels = usize::BITS - max_m.max(1).leading_zeros();
        let size = (2usize << (levels - 1)) * 2;
        let mut ring = vec![0.0; size];
        ring[0] = 0.0;
        StreamingOadev {
            tau0_s,
            ring,
            mask: size - 1,
            n_phase: 1,
            rate_sum: 0.0,
            sums: vec![0.0; levels as usize],
            counts: vec![0; levels as usize],
        }
    }

    /// Adds one rate sample.
    pub fn push(&mut self, y: f64) {
        self.rate_sum += y;
        let x = self.rate_sum * self.tau0_s;
        let n = self.n_phase;
        self.ring[n & self.mask] = x;
        self.n_phase += 1;
        for (k, (sum, count)) in self.sums.iter_mut().zip(&mut self.counts).enumerate() {
            let m = 1usize << k;
            if n < 2 * m {
                break;
            }
            let d = x - 2.0 * self.ring[(n - m) & self.mask] + self.ring[(n - 2 * m) & self.mask];
            *sum += d * d;
            *count += 1;
        }
    }

    /// Adds many rate samples.
    pub fn extend(&mut self, ys: &[f64]) {
        for &y in ys {
            self.push(y);
        }
    }

    /// Rate samples seen so far.
    pub fn n_samples(&self) -> usize {
        self.n_phase - 1
    }

    /// The OADEV curve so far (taus with at least one term), with EDF and intervals as in
    /// [`deviation`](super::deviation) using `noise` (or the local slope if `None`).
    pub fn curve(&self, confidence: f64, noise: Option<NoiseType>) -> DevCurve {
        let mut points: Vec<DevPoint> = self
            .sums
            .iter()
            .zip(&self.counts)
            .enumerate()
            .filter(|(_, (_, c))| **c > 0)
            .map(|(k, (s, &c))| {
                let m = 1usize << k;
                let tau = m as f64 * self.tau0_s;
                DevPoint {
                    m,
                    tau_s: tau,
                    dev: (s / (2.0 * c as f64 * tau * tau)).sqrt(),
                    n_terms: c,
                    edf: 0.0,
                    dev_lo: 0.0,
                    dev_hi: 0.0,
                }
            })
            .collect();
        let devs: Vec<(f64, f64)> = points.iter().map(|p| (p.tau_s, p.dev)).collect();
        for (i, p) in points.iter_mut().enumerate() {
            let noise = noise.unwrap_or_else(|| {
                let (a, b) = (i.saturating_sub(1), (i + 1).min(devs.len() - 1));
                let slope = if a == b {
                    -0.5
                } else {
                    (devs[b].1 / devs[a].1).ln() / (devs[b].0 / devs[a].0).ln()
                };
                NoiseType::from_adev_slope(slope)
            });
            p.edf = edf_oadev(self.n_phase, p.m, noise);
            (p.dev_lo, p.dev_hi) = confidence_interval(p.dev, p.edf, confidence);
        }
        DevCurve {
            kind: Kind::Oadev,
            tau0_s: self.tau0_s,
            confidence,
            points,
        }
    }
}
