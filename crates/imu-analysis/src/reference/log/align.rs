//! Aligning a reference log with a recording: the clock offset from the cross-correlation of
//! rate magnitudes, with a correlation check.

use super::*;

impl ReferenceLog {
    /// Use a known clock offset (log clock minus recording clock, s) instead of finding it.
    pub fn with_offset(self, offset_s: f64) -> AlignedLog {
        AlignedLog {
            log: self,
            offset_s,
            correlation: None,
        }
    }

    /// Reference rate magnitude at log time `t` (linear interpolation; `None` outside).
    pub(super) fn magnitude_at(&self, mags: &[f64], t: f64, cursor: &mut usize) -> Option<f64> {
        let ts = &self.t_s;
        if t < ts[0] || t > ts[ts.len() - 1] {
            return None;
        }
        while *cursor + 1 < ts.len() && ts[*cursor + 1] < t {
            *cursor += 1;
        }
        while *cursor > 0 && ts[*cursor] > t {
            *cursor -= 1;
        }
        let i = *cursor;
        if i + 1 >= ts.len() {
            return Some(mags[i]);
        }
        let u = (t - ts[i]) / (ts[i + 1] - ts[i]);
        Some(mags[i] + (mags[i + 1] - mags[i]) * u)
    }

    /// Find the clock offset to `series` by cross-correlating rate magnitudes.
    pub fn align(self, series: &ImuSeries) -> Result<AlignedLog, ReferenceLogError> {
        let fail = |message: String| ReferenceLogError::Align {
            file: self.file.clone(),
            message,
        };
        if series.len() < 10 {
            return Err(fail("the recording has fewer than 10 samples".into()));
        }
        let mags = RateMagnitudes::new(series, &self);
        let ref_std = (mags
            .refm
            .iter()
            .map(|m| (m - mags.ref_mean).powi(2))
            .sum::<f64>()
            / mags.refm.len() as f64)
            .sqrt();
        if ref_std < 1f64.to_radians() {
            return Err(fail(format!(
                "the log's rate barely changes (std {:.3} deg/s), so there is nothing to align \
                 on; give the offset by hand (imu-calibrate --reference-offset-s)",
                ref_std.to_degrees()
            )));
        }
        let (coarse_s, dt_c) = self.coarse_offset(series, &mags);
        let offset_s = self.fine_offset(series, &mags, coarse_s, dt_c);
        let (n_pairs, correlation) = self.overlap_correlation(series, &mags, offset_s);
        if n_pairs < 10 || correlation.is_nan() || correlation < MIN_CORRELATION {
            return Err(fail(format!(
                "the best offset ({offset_s:.3} s, log clock minus recording clock) overlaps \
                 {n_pairs} samples with correlation {correlation:.2} (< {MIN_CORRELATION}): the \
                 log does not look like this recording's motion (other run, wrong units or \
                 columns?)"
            )));
        }
        Ok(AlignedLog {
            log: self,
            offset_s,
            correlation: Some(correlation),
        })
    }

    /// Coarse: bin means on a common spacing, zero-padded correlation over every lag. Returns
    /// the offset, s, and the bin spacing, s.
    fn coarse_offset(&self, series: &ImuSeries, mags: &RateMagnitudes) -> (f64, f64) {
        let (t_rec_end, t_ref0) = (series.t_s[series.len() - 1], self.t_s[0]);
        let t_ref_span = self.t_s[self.t_s.len() - 1] - t_ref0;
        let dt_c = (t_rec_end.max(t_ref_span) / 4000.0).max(0.5);
        let bins = |t: &[f64], v: &[f64], t0: f64, m: f64| -> Vec<f64> {
            let n = ((t[t.len() - 1] - t0) / dt_c).floor() as usize + 1;
            let (mut sum, mut count) = (vec![0.0; n], vec![0usize; n]);
            for (ti, vi) in t.iter().zip(v) {
                let k = (((ti - t0) / dt_c).floor() as usize).min(n - 1);
                sum[k] += vi - m;
                count[k] += 1;
            }
            let mut last = 0.0;
            sum.iter()
                .zip(&count)
                .map(|(s, &c)| {
                    if c > 0 {
                        last = s / c as f64;
                    }
                    last
                })
                .collect()
        };
        let a = bins(&series.t_s, &mags.rec, 0.0, mags.rec_mean);
        let b = bins(&self.t_s, &mags.refm, t_ref0, mags.ref_mean);
        let (na, nb) = (a.len() as i64, b.len() as i64);
        let mut best = (f64::NEG_INFINITY, 0i64);
        for k in -(na - 1)..nb {
            let lo = (-k).max(0);
            let hi = na.min(nb - k);
            let c: f64 = (lo..hi).map(|i| a[i as usize] * b[(i + k) as usize]).sum();
            if c > best.0 {
                best = (c, k);
            }
        }
        (t_ref0 + best.1 as f64 * dt_c, dt_c)
    }

    /// Fine: the recording's own samples against the interpolated log, around the coarse lag
    /// (within two coarse bins), refined by a parabola through the best three lags.
    fn fine_offset(
        &self,
        series: &ImuSeries,
        mags: &RateMagnitudes,
        coarse_s: f64,
        dt_c: f64,
    ) -> f64 {
        let dt_f = 1.0 / series.sample_rate_hz();
        let m = (2.0 * dt_c / dt_f).ceil() as i64;
        let corr_at = |tau: f64| -> f64 {
            let mut cursor = 0;
            let mut c = 0.0;
            for (t, r) in series.t_s.iter().zip(&mags.rec) {
                if let Some(v) = self.magnitude_at(&mags.refm, t + tau, &mut cursor) {
                    c += (r - mags.rec_mean) * (v - mags.ref_mean);
                }
            }
            c
        };
        let fine: Vec<(f64, f64)> = (-m..=m)
            .map(|i| {
                let tau = coarse_s + i as f64 * dt_f;
                (tau, corr_at(tau))
            })
            .collect();
        let k = (0..fine.len())
            .max_by(|&i, &j| fine[i].1.total_cmp(&fine[j].1))
            .expect("at least one lag");
        let mut offset_s = fine[k].0;
        if k > 0 && k + 1 < fine.len() {
            let (l, c, r) = (fine[k - 1].1, fine[k].1, fine[k + 1].1);
            let den = l - 2.0 * c + r;
            if den < 0.0 {
                offset_s += (0.5 * (l - r) / den).clamp(-0.5, 0.5) * dt_f;
            }
        }
        offset_s
    }

    /// Pearson correlation over the overlap at `offset_s`, the quality check: (the number of
    /// samples in the overlap, the correlation; NaN when undefined).
    fn overlap_correlation(
        &self,
        series: &ImuSeries,
        mags: &RateMagnitudes,
        offset_s: f64,
    ) -> (usize, f64) {
        let mut cursor = 0;
        let pairs: Vec<(f64, f64)> = series
            .t_s
            .iter()
            .zip(&mags.rec)
            .filter_map(|(t, r)| {
                self.magnitude_at(&mags.refm, t + offset_s, &mut cursor)
                    .map(|v| (*r, v))
            })
            .collect();
        let (rec_side, ref_side): (Vec<f64>, Vec<f64>) = pairs.iter().copied().unzip();
        let correlation =
            imu_stats::descriptive::correlation(&rec_side, &ref_side).unwrap_or(f64::NAN);
        (pairs.len(), correlation)
    }
}

/// The rate magnitudes of the recording and of the log, rad/s, and their means.
struct RateMagnitudes {
    rec: Vec<f64>,
    refm: Vec<f64>,
    rec_mean: f64,
    ref_mean: f64,
}

impl RateMagnitudes {
    fn new(series: &ImuSeries, log: &ReferenceLog) -> Self {
        let rec: Vec<f64> = series
            .gyro_rad_s
            .iter()
            .map(|w| Vec3::from(*w).norm())
            .collect();
        let refm: Vec<f64> = log
            .angular_rate_rad_s
            .iter()
            .map(|w| Vec3::from(*w).norm())
            .collect();
        let mean = imu_stats::descriptive::mean;
        let (rec_mean, ref_mean) = (mean(&rec), mean(&refm));
        RateMagnitudes {
            rec,
            refm,
            rec_mean,
            ref_mean,
        }
    }
}
