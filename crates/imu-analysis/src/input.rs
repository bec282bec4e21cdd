//! Reading IMU time series for the offline tools: imud recordings, any MCAP carrying
//! `sensor_msgs/msg/Imu` (rosbag2 recordings from other drivers), and CSV files.
//!
//! Everything becomes an [`ImuSeries`] in SI units with times in seconds from the first sample.
//! MCAP is read front to back (bounded memory besides the series itself; a truncated file is read
//! up to its last good record and says so).

use std::path::{Path, PathBuf};

use imu_bus::McapReadError;
use imu_bus::mcap_read;
use imu_bus::ros2::{Imu, RawSampleMsg, RosMessage, Temperature};
use imu_bus::sample::raw_flags;
use imu_proto::scale;

const G0: f64 = imu_model::units::STANDARD_GRAVITY_M_S2;

/// Which values to read from an imud recording.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Source {
    /// The corrected stream (`/imu/data`, or any `sensor_msgs/msg/Imu` channel).
    #[default]
    Corrected,
    /// The raw counts (`/imu/raw`) converted with the recording's GainScales only: the
    /// uncalibrated measurement, which is what calibration fits need.
    Raw,
}

/// Errors reading an input.
#[derive(Debug, thiserror::Error)]
pub enum InputError {
    /// The MCAP file could not be read.
    #[error(transparent)]
    Mcap(#[from] McapReadError),
    /// The file could not be read.
    #[error("{path}: cannot read")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The file has no usable IMU data.
    #[error("{path}: {message}")]
    NoData {
        /// The file.
        path: PathBuf,
        /// What is missing and what to do.
        message: String,
    },
    /// A CSV line is malformed.
    #[error("{path}:{line}: {message}")]
    Csv {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// What is wrong.
        message: String,
    },
}

/// An IMU time series in SI units.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ImuSeries {
    /// Sample times, seconds from the first sample.
    pub t_s: Vec<f64>,
    /// Specific force, sensor frame, m/s^2.
    pub accel_m_s2: Vec<[f64; 3]>,
    /// Angular rate, sensor frame, rad/s.
    pub gyro_rad_s: Vec<[f64; 3]>,
    /// Temperature readings `(t_s, deg C)` on the same time base (may be empty).
    pub temp: Vec<(f64, f64)>,
    /// Absolute time of `t_s = 0` (Unix epoch ns; 0 if unknown).
    pub t0_ns: u64,
    /// Where the data came from (file and topic), for reports.
    pub origin: String,
    /// `Some(reason)` if the input ended early (truncated recording).
    pub stopped_early: Option<String>,
}

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

fn vec3(v: &imu_bus::ros2::Vector3) -> [f64; 3] {
    [v.x, v.y, v.z]
}

/// Reads an MCAP recording: imud's own, or any file with a `sensor_msgs/msg/Imu` channel.
/// `topic` picks a channel when several carry IMU data.
pub fn read_mcap(
    path: &Path,
    source: Source,
    topic: Option<&str>,
) -> Result<ImuSeries, InputError> {
    read_mcap_with_progress(path, source, topic, &mut |_, _| {})
}

/// [`read_mcap`], reporting `(bytes read, file size)` as the file is read (monotone, ending at
/// the file size when the whole file was read).
pub fn read_mcap_with_progress(
    path: &Path,
    source: Source,
    topic: Option<&str>,
    on_progress: &mut dyn FnMut(u64, u64),
) -> Result<ImuSeries, InputError> {
    let mut series = ImuSeries::default();
    let mut abs_ns: Vec<u64> = Vec::new();
    let mut temps_ns: Vec<(u64, f64)> = Vec::new();
    // Raw samples are kept as their counts (in the series' own arrays, converted in place once
    // the GainScales are known: the metadata holding them is written when the file is closed)
    // and whether they are scaled-vector counts: 57 bytes a sample instead of a RawSample's 112.
    let mut scaled_counts: Vec<bool> = Vec::new();
    let mut chosen: Option<String> = topic.map(str::to_string);
    let report = mcap_read::for_each_message_with_progress(path, on_progress, |ch, _h, data| {
        match ch.schema_name.as_str() {
            "sensor_msgs/msg/Imu" if source == Source::Corrected => {
                let pick = chosen.get_or_insert_with(|| ch.topic.clone());
                if *pick != ch.topic {
                    return Ok(());
                }
                let m = Imu::from_cdr(data).map_err(|e| format!("sensor_msgs/msg/Imu: {e}"))?;
                abs_ns.push(m.header.stamp.to_ns());
                series.accel_m_s2.push(vec3(&m.linear_acceleration));
                series.gyro_rad_s.push(vec3(&m.angular_velocity));
            }
            "imud_msgs/msg/RawSample" if source == Source::Raw => {
                let s = RawSampleMsg::from_cdr(data)
                    .map_err(|e| format!("imud_msgs/msg/RawSample: {e}"))?
                    .sample;
                // Temperatures are stamped on the wall clock, raw samples carry both clocks.
                abs_ns.push(
                    s.t_host_wall_ns
                        .saturating_sub(s.t_host_monotonic_ns.saturating_sub(s.t_sample_ns)),
                );
                series.accel_m_s2.push(s.accel_counts.map(f64::from));
                series.gyro_rad_s.push(s.gyro_counts.map(f64::from));
                scaled_counts.push(s.flags & raw_flags::SCALED_COUNTS != 0);
            }
            "sensor_msgs/msg/Temperature" => {
                let m = Temperature::from_cdr(data)
                    .map_err(|e| format!("sensor_msgs/msg/Temperature: {e}"))?;
                temps_ns.push((m.header.stamp.to_ns(), m.temperature));
            }
            _ => {}
        }
        Ok(())
    })?;
    series.stopped_early = report.stopped_early.clone();
    if source == Source::Raw {
        let dev = report.metadata.get("imud.device");
        let gain = |key: &str| -> Result<u16, InputError> {
            dev.and_then(|m| m.get(key))
                .and_then(|v| v.parse().ok())
                .ok_or_else(|| InputError::NoData {
                    path: path.to_path_buf(),
                    message: format!("the recording's metadata `imud.device` lacks `{key}`; raw counts cannot be converted (read the corrected stream instead)"),
                })
        };
        let (ga, gg) = (gain("gain-scale-accel")?, gain("gain-scale-gyro")?);
        // The counts were stored as f64 (exact for any i32).
        let to_units = |c: f64, g: u16, scaled: bool| {
            if scaled {
                scale::scaled_to_units(c as i16, g)
            } else {
                scale::raw_bits_to_units(c as u16, g)
            }
        };
        for ((a, w), &scaled) in series
            .accel_m_s2
            .iter_mut()
            .zip(&mut series.gyro_rad_s)
            .zip(&scaled_counts)
        {
            *a = a.map(|c| to_units(c, ga, scaled) * G0);
            *w = w.map(|c| to_units(c, gg, scaled));
        }
        chosen = Some(imu_bus::recording::RAW_TOPIC.to_string());
    }
    let Some(&t0) = abs_ns.first() else {
        return Err(InputError::NoData {
            path: path.to_path_buf(),
            message: match source {
                Source::Corrected => {
                    "no sensor_msgs/msg/Imu messages (is this an IMU recording?)".into()
                }
                Source::Raw => {
                    "no /imu/raw messages (only imud recordings carry raw counts)".into()
                }
            },
        });
    };
    series.t0_ns = t0;
    series.t_s = abs_ns
        .iter()
        .map(|&t| (t as i128 - t0 as i128) as f64 * 1e-9)
        .collect();
    series.temp = temps_ns
        .iter()
        .map(|&(t, c)| ((t as i128 - t0 as i128) as f64 * 1e-9, c))
        .collect();
    series.origin = format!("{} ({})", path.display(), chosen.unwrap_or_default());
    Ok(series)
}

/// Units of CSV accelerometer columns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AccelUnit {
    /// m/s^2.
    MetersPerSecond2,
    /// Standard gravities.
    G,
    /// Counts times a scale in m/s^2 per count.
    Counts(f64),
}

/// Units of CSV gyro columns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GyroUnit {
    /// rad/s.
    RadPerSecond,
    /// deg/s.
    DegPerSecond,
    /// Counts times a scale in rad/s per count.
    Counts(f64),
}

/// How to read a CSV file: `time, ax, ay, az, gx, gy, gz` (a header line is skipped).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CsvOptions {
    /// Seconds per unit of the time column (1 for s, 1e-9 for ns).
    pub time_scale_s: f64,
    /// Accelerometer unit.
    pub accel: AccelUnit,
    /// Gyro unit.
    pub gyro: GyroUnit,
}

impl Default for CsvOptions {
    fn default() -> Self {
        Self {
            time_scale_s: 1.0,
            accel: AccelUnit::MetersPerSecond2,
            gyro: GyroUnit::RadPerSecond,
        }
    }
}

/// Reads a CSV file of time plus accelerometer and gyro axes.
pub fn read_csv(path: &Path, options: &CsvOptions) -> Result<ImuSeries, InputError> {
    let text = std::fs::read_to_string(path).map_err(|source| InputError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mut series = ImuSeries {
        origin: path.display().to_string(),
        ..ImuSeries::default()
    };
    let mut t_first = None;
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = line.split([',', ';', '\t']).map(str::trim).collect();
        let parsed: Result<Vec<f64>, _> = fields.iter().map(|f| f.parse::<f64>()).collect();
        let Ok(v) = parsed else {
            if series.t_s.is_empty() && t_first.is_none() {
                continue; // the header line
            }
            return Err(InputError::Csv {
                path: path.to_path_buf(),
                line: i + 1,
                message: format!("expected 7 numbers (time, ax, ay, az, gx, gy, gz), got `{line}`"),
            });
        };
        if v.len() < 7 {
            return Err(InputError::Csv {
                path: path.to_path_buf(),
                line: i + 1,
                message: format!(
                    "expected 7 columns (time, ax, ay, az, gx, gy, gz), got {}",
                    v.len()
                ),
            });
        }
        let t = v[0] * options.time_scale_s;
        let t0 = *t_first.get_or_insert(t);
        series.t_s.push(t - t0);
        let a = |x: f64| match options.accel {
            AccelUnit::MetersPerSecond2 => x,
            AccelUnit::G => x * G0,
            AccelUnit::Counts(k) => x * k,
        };
        let g = |x: f64| match options.gyro {
            GyroUnit::RadPerSecond => x,
            GyroUnit::DegPerSecond => x.to_radians(),
            GyroUnit::Counts(k) => x * k,
        };
        series.accel_m_s2.push([a(v[1]), a(v[2]), a(v[3])]);
        series.gyro_rad_s.push([g(v[4]), g(v[5]), g(v[6])]);
    }
    if series.is_empty() {
        return Err(InputError::NoData {
            path: path.to_path_buf(),
            message: "no data lines".into(),
        });
    }
    Ok(series)
}

/// Reads any supported input by its extension (`.mcap` or `.csv`).
pub fn read_any(path: &Path, source: Source, csv: &CsvOptions) -> Result<ImuSeries, InputError> {
    read_any_with_progress(path, source, csv, &mut |_, _| {})
}

/// [`read_any`], reporting `(bytes read, file size)` as the file is read: monotone, from
/// `(0, size)` to `(size, size)` when the whole file was read (a CSV file is read at once).
/// This is what the clients' progress bars (module `progress`, feature `progress`) follow.
pub fn read_any_with_progress(
    path: &Path,
    source: Source,
    csv: &CsvOptions,
    on_progress: &mut dyn FnMut(u64, u64),
) -> Result<ImuSeries, InputError> {
    match path.extension().and_then(|e| e.to_str()) {
        Some("csv") | Some("txt") => {
            let size = std::fs::metadata(path).map_or(0, |m| m.len());
            on_progress(0, size);
            let series = read_csv(path, csv)?;
            on_progress(size, size);
            Ok(series)
        }
        _ => read_mcap_with_progress(path, source, None, on_progress),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_with_header_units_and_errors() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.csv");
        std::fs::write(
            &p,
            "t,ax,ay,az,gx,gy,gz\n10.0,0,0,1,0,0,90\n10.01,0,0,1,0,0,-90\n",
        )
        .unwrap();
        let s = read_csv(
            &p,
            &CsvOptions {
                time_scale_s: 1.0,
                accel: AccelUnit::G,
                gyro: GyroUnit::DegPerSecond,
            },
        )
        .unwrap();
        assert_eq!(s.len(), 2);
        assert!((s.t_s[1] - 0.01).abs() < 1e-12);
        assert!((s.accel_m_s2[0][2] - G0).abs() < 1e-12);
        assert!((s.gyro_rad_s[1][2] + std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!((s.sample_rate_hz() - 100.0).abs() < 1e-6);
        std::fs::write(&p, "t,ax,ay,az,gx,gy,gz\n1,2,3,4,5,6,7\n1,2,x,4,5,6,7\n").unwrap();
        let e = read_csv(&p, &CsvOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("a.csv:3:"), "{e}");
    }

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
