//! What a series says about itself: length, data rate, temperature at a time, and whether the
//! sensor moved (the noise tools' warning).

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

    /// Data rate from the median sample interval, Hz (NaN with fewer than two samples).
    pub fn sample_rate_hz(&self) -> f64 {
        if self.t_s.len() < 2 {
            return f64::NAN;
        }
        let mut dt: Vec<f64> = self.t_s.windows(2).map(|w| w[1] - w[0]).collect();
        let mid = dt.len() / 2;
        let (_, m, _) = dt.select_nth_unstable_by(mid, f64::total_cmp);
        1.0 / *m
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
}
