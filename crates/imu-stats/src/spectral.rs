//! Spectra: an averaged, Hann-windowed periodogram (Welch without overlap) over blocks of
//! evenly sampled data with `rustfft`, the detection of narrow lines in it against the median
//! of their neighbourhood, and the Lomb-Scargle peak of unevenly sampled data.

use std::sync::Arc;

use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};

use crate::distributions::chi2_sf;

/// Accumulates the one-sided power of Hann-windowed, mean-removed blocks of one length.
pub struct Periodogram {
    len: usize,
    hann: Vec<f64>,
    fft: Arc<dyn Fft<f64>>,
    buffer: Vec<Complex<f64>>,
    power: Vec<f64>,
    blocks: usize,
}

impl Periodogram {
    /// A periodogram of blocks of `len` samples (any length; powers of two are fastest).
    pub fn new(len: usize) -> Periodogram {
        let hann = (0..len)
            .map(|i| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / len as f64).cos())
            .collect();
        Periodogram {
            len,
            hann,
            fft: FftPlanner::new().plan_fft_forward(len),
            buffer: vec![Complex::default(); len],
            power: vec![0.0; len / 2],
            blocks: 0,
        }
    }

    /// Adds every whole block of `len` samples of `y` (a remainder shorter than a block is
    /// left out).
    pub fn add_blocks(&mut self, y: &[f64]) {
        for chunk in y.chunks_exact(self.len) {
            let m = chunk.iter().sum::<f64>() / self.len as f64;
            for ((b, v), w) in self.buffer.iter_mut().zip(chunk).zip(&self.hann) {
                *b = Complex::new((v - m) * w, 0.0);
            }
            self.fft.process(&mut self.buffer);
            for (p, b) in self.power.iter_mut().zip(&self.buffer) {
                *p += b.norm_sqr();
            }
            self.blocks += 1;
        }
    }

    /// Summed power of bins `0..len/2` over the blocks added.
    pub fn power(&self) -> &[f64] {
        &self.power
    }

    /// Blocks added.
    pub fn blocks(&self) -> usize {
        self.blocks
    }

    /// Sum of the window (the amplitude of a sinusoid in bin k is `2 sqrt(P_k / blocks) / sum`).
    pub fn window_sum(&self) -> f64 {
        self.hann.iter().sum()
    }

    /// Narrow lines: bins whose power stands out from the median of their neighbourhood
    /// (8 bins each side, the 2 nearest excluded) at a false-alarm probability below
    /// `false_alarm` over all bins and by a factor over 4, local maxima only. Amplitudes are in
    /// the unit of the data (the main lobe's power less the noise in it).
    pub fn lines(&self, false_alarm: f64) -> Vec<SpectralPeak> {
        let (power, half_len) = (&self.power, self.len / 2);
        let dof = 2.0 * self.blocks as f64;
        let n_bins = half_len as f64;
        let mut out = Vec::new();
        let mut k = 4;
        while k + 1 < half_len {
            let lo = k.saturating_sub(8).max(1);
            let hi = (k + 9).min(half_len);
            let mut neigh: Vec<f64> = (lo..hi)
                .filter(|&j| j.abs_diff(k) > 2)
                .map(|j| power[j])
                .collect();
            if neigh.len() < 4 {
                k += 1;
                continue;
            }
            let mid = neigh.len() / 2;
            let (_, med, _) = neigh.select_nth_unstable_by(mid, f64::total_cmp);
            // The median of a chi2(dof)/dof variable is about 1 - 2/(9 dof).
            let level = *med / (1.0 - 2.0 / (9.0 * dof)).powi(3);
            let ratio = power[k] / level.max(1e-300);
            let p = chi2_sf(ratio * dof, dof);
            let local_max = power[k] >= power[k - 1] && power[k] >= power[k + 1];
            if p * n_bins < false_alarm && ratio > 4.0 && local_max {
                let lobe = power[k - 1] + power[k] + power[k + 1];
                let lobe_noise = 3.0 * level;
                let amplitude = 2.0
                    * ((lobe - lobe_noise).max(0.0) / self.blocks as f64 / 1.5).sqrt()
                    / self.window_sum();
                out.push(SpectralPeak {
                    bin: k,
                    ratio,
                    amplitude,
                });
                k += 3;
                continue;
            }
            k += 1;
        }
        out
    }
}

/// A line found by [`Periodogram::lines`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpectralPeak {
    /// Bin index (frequency `bin * rate / len`).
    pub bin: usize,
    /// Power over the neighbourhood's noise level.
    pub ratio: f64,
    /// Amplitude of the sinusoid, unit of the data.
    pub amplitude: f64,
}

/// The strongest period of unevenly sampled `y(t)` (Lomb-Scargle, 401 log-spaced frequencies
/// from 1/span to the Nyquist rate of the closest samples), with the share of the variance a
/// sinusoid at it explains; None with fewer than 8 points or no spread.
pub fn lomb_scargle_peak(t: &[f64], y: &[f64]) -> Option<(f64, f64)> {
    let n = t.len();
    if n < 8 {
        return None;
    }
    let span = t[n - 1] - t[0];
    if span <= 0.0 {
        return None;
    }
    let mean = y.iter().sum::<f64>() / n as f64;
    let var: f64 = y.iter().map(|v| (v - mean).powi(2)).sum();
    if var <= 0.0 {
        return None;
    }
    let dt_min = t
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 0.0)
        .fold(f64::INFINITY, f64::min);
    let f_max = 0.5 / dt_min.max(1e-9);
    let f_min = 1.0 / span;
    let mut best = (0.0, 0.0);
    let steps = 400;
    for k in 0..=steps {
        let f = f_min * (f_max / f_min).powf(k as f64 / steps as f64);
        let w = 2.0 * std::f64::consts::PI * f;
        let (s2, c2) = t.iter().fold((0.0, 0.0), |(s, c), ti| {
            (s + (2.0 * w * ti).sin(), c + (2.0 * w * ti).cos())
        });
        let tau = s2.atan2(c2) / (2.0 * w);
        let (mut yc, mut ys, mut cc, mut ss) = (0.0, 0.0, 0.0, 0.0);
        for (ti, yi) in t.iter().zip(y) {
            let (s, c) = (w * (ti - tau)).sin_cos();
            yc += (yi - mean) * c;
            ys += (yi - mean) * s;
            cc += c * c;
            ss += s * s;
        }
        let p = yc * yc / cc.max(1e-300) + ys * ys / ss.max(1e-300);
        if p > best.1 {
            best = (1.0 / f, p);
        }
    }
    Some((best.0, (best.1 / var).min(1.0)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn periodogram_matches_a_direct_dft() {
        let n = 16;
        let x: Vec<f64> = (0..n).map(|i| ((i * 7 % 5) as f64).sin()).collect();
        let mut p = Periodogram::new(n);
        p.add_blocks(&x);
        let m = x.iter().sum::<f64>() / n as f64;
        for k in 0..n / 2 {
            let (mut r, mut i) = (0.0, 0.0);
            for (j, v) in x.iter().enumerate() {
                let w = 0.5 - 0.5 * (2.0 * std::f64::consts::PI * j as f64 / n as f64).cos();
                let a = -2.0 * std::f64::consts::PI * (k * j) as f64 / n as f64;
                r += (v - m) * w * a.cos();
                i += (v - m) * w * a.sin();
            }
            assert!((p.power()[k] - (r * r + i * i)).abs() < 1e-9, "bin {k}");
        }
        assert_eq!(p.blocks(), 1);
    }

    #[test]
    fn a_sinusoid_in_noise_is_a_line_at_its_frequency_and_amplitude() {
        // Deterministic pseudo-noise plus a 0.3-amplitude sinusoid in bin 40 of 256.
        let n = 256 * 16;
        let mut state = 12345u64;
        let y: Vec<f64> = (0..n)
            .map(|i| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let u = (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
                u + 0.3 * (2.0 * std::f64::consts::PI * 40.0 * i as f64 / 256.0).sin()
            })
            .collect();
        let mut p = Periodogram::new(256);
        p.add_blocks(&y);
        let lines = p.lines(1e-6);
        assert_eq!(lines.len(), 1, "{lines:?}");
        assert_eq!(lines[0].bin, 40);
        assert!((lines[0].amplitude - 0.3).abs() < 0.05, "{lines:?}");
    }

    #[test]
    fn lomb_scargle_finds_a_period_in_uneven_samples() {
        let t: Vec<f64> = (0..60)
            .map(|i| i as f64 * 33.0 + (i % 3) as f64 * 4.0)
            .collect();
        let y: Vec<f64> = t
            .iter()
            .map(|t| (2.0 * std::f64::consts::PI * t / 400.0).sin())
            .collect();
        let (period, share) = lomb_scargle_peak(&t, &y).unwrap();
        assert!((period - 400.0).abs() < 20.0, "{period}");
        assert!(share > 0.9, "{share}");
    }
}
