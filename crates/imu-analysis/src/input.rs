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
    /// The same as data for an MCAP input: footer missing, messages and last log time read.
    pub unfinished: Option<imu_bus::Unfinished>,
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
    series.unfinished = report.unfinished.clone();
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

/// `counts:SCALE` -> SCALE (finite, non-zero).
fn counts_scale(s: &str, unit: &str) -> Option<Result<f64, String>> {
    let v = s.strip_prefix("counts:")?;
    Some(match v.trim().parse::<f64>() {
        Ok(k) if k.is_finite() && k != 0.0 => Ok(k),
        _ => Err(format!(
            "`{s}`: write counts:SCALE with SCALE the {unit} per count, e.g. counts:0.00119"
        )),
    })
}

impl std::str::FromStr for AccelUnit {
    type Err = String;
    /// `m/s2` (or `m_s2`), `g`, or `counts:SCALE` (SCALE in m/s^2 per count).
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim() {
            "m/s2" | "m/s^2" | "m_s2" => Ok(AccelUnit::MetersPerSecond2),
            "g" => Ok(AccelUnit::G),
            t => match counts_scale(t, "m/s^2") {
                Some(k) => k.map(AccelUnit::Counts),
                None => Err(format!(
                    "unknown accel unit `{t}`: use m/s2, g or counts:SCALE (m/s^2 per count)"
                )),
            },
        }
    }
}

impl std::str::FromStr for GyroUnit {
    type Err = String;
    /// `rad/s` (or `rad_s`), `deg/s` (or `deg_s`), or `counts:SCALE` (SCALE in rad/s per
    /// count).
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim() {
            "rad/s" | "rad_s" => Ok(GyroUnit::RadPerSecond),
            "deg/s" | "deg_s" => Ok(GyroUnit::DegPerSecond),
            t => match counts_scale(t, "rad/s") {
                Some(k) => k.map(GyroUnit::Counts),
                None => Err(format!(
                    "unknown gyro unit `{t}`: use rad/s, deg/s or counts:SCALE (rad/s per count)"
                )),
            },
        }
    }
}

impl AccelUnit {
    fn to_m_s2(self, x: f64) -> f64 {
        match self {
            AccelUnit::MetersPerSecond2 => x,
            AccelUnit::G => x * G0,
            AccelUnit::Counts(k) => x * k,
        }
    }
}

impl GyroUnit {
    fn to_rad_s(self, x: f64) -> f64 {
        match self {
            GyroUnit::RadPerSecond => x,
            GyroUnit::DegPerSecond => x.to_radians(),
            GyroUnit::Counts(k) => x * k,
        }
    }
}

/// How to read a CSV file: `time, ax, ay, az, gx, gy, gz` (a header line is skipped), or the
/// accelerometer's `time, ax, ay, az` with the gyro's `time, gx, gy, gz` in a second file.
#[derive(Debug, Clone, PartialEq)]
pub struct CsvOptions {
    /// Seconds per unit of the time column (1 for s, 1e-9 for ns).
    pub time_scale_s: f64,
    /// Accelerometer unit.
    pub accel: AccelUnit,
    /// Gyro unit.
    pub gyro: GyroUnit,
    /// The gyro's own file (`time, gx, gy, gz`, same clock) when the recording's CSV holds
    /// only the accelerometer (`time, ax, ay, az`): the gyro is interpolated linearly to the
    /// accelerometer's times.
    pub gyro_file: Option<PathBuf>,
}

impl Default for CsvOptions {
    fn default() -> Self {
        Self {
            time_scale_s: 1.0,
            accel: AccelUnit::MetersPerSecond2,
            gyro: GyroUnit::RadPerSecond,
            gyro_file: None,
        }
    }
}

/// The rows of a CSV file of time plus `N` value columns, streamed line by line: (time in
/// s as written times `time_scale_s`, values as written). A first line that is not numbers
/// is the header; `#` lines and blank lines are skipped; further columns are ignored.
fn csv_rows<const N: usize>(
    path: &Path,
    time_scale_s: f64,
    columns: &str,
) -> Result<(Vec<f64>, Vec<[f64; N]>), InputError> {
    use std::io::BufRead;
    let io = |source| InputError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let (mut t, mut rows) = (Vec::new(), Vec::new());
    let mut header_allowed = true;
    let mut line = String::new();
    let mut reader = std::io::BufReader::with_capacity(1 << 20, file);
    let mut number = 0;
    loop {
        line.clear();
        if reader.read_line(&mut line).map_err(io)? == 0 {
            break;
        }
        number += 1;
        let text = line.trim();
        if text.is_empty() || text.starts_with('#') {
            continue;
        }
        let err = |message: String| InputError::Csv {
            path: path.to_path_buf(),
            line: number,
            message,
        };
        let mut fields = text.split([',', ';', '\t']).map(str::trim);
        let mut v = [0.0; 8];
        let mut n = 0;
        let mut bad = None;
        for f in fields.by_ref().take(N + 1) {
            match f.parse::<f64>() {
                Ok(x) => v[n] = x,
                Err(_) => bad = bad.or(Some(n)),
            }
            n += 1;
        }
        if let Some(i) = bad {
            if header_allowed {
                header_allowed = false;
                continue; // the header line
            }
            return Err(err(format!(
                "column {} is not a number in `{text}` (expected {columns})",
                i + 1
            )));
        }
        if n < N + 1 {
            return Err(err(format!(
                "expected {} columns ({columns}), got {n}",
                N + 1
            )));
        }
        header_allowed = false;
        if !v[..=N].iter().all(|x| x.is_finite()) {
            return Err(err(format!("a value is not finite in `{text}`")));
        }
        if let Some(&last) = t.last()
            && v[0] * time_scale_s <= last
        {
            return Err(err(format!(
                "time {} does not increase (the line before: {last} s)",
                v[0]
            )));
        }
        t.push(v[0] * time_scale_s);
        rows.push(std::array::from_fn(|i| v[i + 1]));
    }
    if t.is_empty() {
        return Err(InputError::NoData {
            path: path.to_path_buf(),
            message: "no data lines".into(),
        });
    }
    Ok((t, rows))
}

/// Reads a CSV file of time plus accelerometer and gyro axes (streamed line by line), or,
/// with `options.gyro_file`, the accelerometer's file and the gyro's file.
pub fn read_csv(path: &Path, options: &CsvOptions) -> Result<ImuSeries, InputError> {
    let mut series = ImuSeries {
        origin: path.display().to_string(),
        ..ImuSeries::default()
    };
    let (t, accel, gyro): (Vec<f64>, Vec<[f64; 3]>, Vec<[f64; 3]>) = match &options.gyro_file {
        None => {
            let (t, rows) =
                csv_rows::<6>(path, options.time_scale_s, "time, ax, ay, az, gx, gy, gz")?;
            let (a, g) = rows
                .iter()
                .map(|r| ([r[0], r[1], r[2]], [r[3], r[4], r[5]]))
                .unzip();
            (t, a, g)
        }
        Some(gyro_path) => {
            let (t, a) = csv_rows::<3>(path, options.time_scale_s, "time, ax, ay, az")?;
            let (tg, g) = csv_rows::<3>(gyro_path, options.time_scale_s, "time, gx, gy, gz")?;
            series.origin = format!("{} + {}", path.display(), gyro_path.display());
            // The gyro at the accelerometer's times (same clock), linear between its samples;
            // accelerometer samples outside the gyro's span are dropped.
            let (mut t_out, mut a_out, mut g_out) = (Vec::new(), Vec::new(), Vec::new());
            let mut j = 0;
            for (ti, ai) in t.iter().zip(&a) {
                while j + 1 < tg.len() && tg[j + 1] < *ti {
                    j += 1;
                }
                if *ti < tg[0] || *ti > tg[tg.len() - 1] {
                    continue;
                }
                let gi = if j + 1 < tg.len() {
                    let w = ((ti - tg[j]) / (tg[j + 1] - tg[j])).clamp(0.0, 1.0);
                    std::array::from_fn(|k| g[j][k] + w * (g[j + 1][k] - g[j][k]))
                } else {
                    g[j]
                };
                t_out.push(*ti);
                a_out.push(*ai);
                g_out.push(gi);
            }
            if t_out.is_empty() {
                return Err(InputError::NoData {
                    path: gyro_path.clone(),
                    message: format!(
                        "the gyro's times ({:.3}-{:.3} s) do not overlap the accelerometer's \
                         ({:.3}-{:.3} s) in {}: both files must be on one clock",
                        tg[0],
                        tg[tg.len() - 1],
                        t[0],
                        t[t.len() - 1],
                        path.display()
                    ),
                });
            }
            (t_out, a_out, g_out)
        }
    };
    let t0 = t[0];
    series.t_s = t.iter().map(|x| x - t0).collect();
    series.accel_m_s2 = accel
        .iter()
        .map(|r| r.map(|x| options.accel.to_m_s2(x)))
        .collect();
    series.gyro_rad_s = gyro
        .iter()
        .map(|r| r.map(|x| options.gyro.to_rad_s(x)))
        .collect();
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
                gyro_file: None,
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
        assert!(e.contains("column 3 is not a number"), "{e}");
        std::fs::write(&p, "1,2,3,4,5,6,7\n0.5,2,3,4,5,6,7\n").unwrap();
        let e = read_csv(&p, &CsvOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("a.csv:2:") && e.contains("does not increase"),
            "{e}"
        );
        std::fs::write(&p, "t,ax,ay,az\n1,2,3,4\n").unwrap();
        let e = read_csv(&p, &CsvOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("a.csv:2:") && e.contains("expected 7 columns"),
            "{e}"
        );
    }

    /// Raw counts with a scale, and the accelerometer and gyro in two files on one clock (the
    /// gyro at its own, offset times, interpolated to the accelerometer's; accelerometer
    /// samples outside the gyro's span dropped).
    #[test]
    fn csv_counts_and_two_files() {
        assert_eq!("g".parse::<AccelUnit>(), Ok(AccelUnit::G));
        assert_eq!("counts:0.5".parse::<GyroUnit>(), Ok(GyroUnit::Counts(0.5)));
        assert!(
            "counts:x"
                .parse::<AccelUnit>()
                .unwrap_err()
                .contains("counts:SCALE")
        );
        assert!("furlongs".parse::<GyroUnit>().is_err());
        let dir = tempfile::tempdir().unwrap();
        let (a, g) = (dir.path().join("acc.csv"), dir.path().join("gyr.csv"));
        let mut at = String::from("time_ns,ax,ay,az\n");
        for k in 0..10 {
            at += &format!("{},{},0,100\n", 1_000_000_000 + k * 10_000_000, k);
        }
        std::fs::write(&a, at).unwrap();
        // Gyro at 5 ms after each accel sample, starting one accel sample later: z = 2 t.
        let mut gt = String::from("time_ns,gx,gy,gz\n");
        for k in 1..12 {
            let t = 1_000_000_000 + k * 10_000_000 + 5_000_000;
            gt += &format!("{t},0,0,{}\n", 2 * (t - 1_000_000_000) / 1_000_000);
        }
        std::fs::write(&g, gt).unwrap();
        let s = read_csv(
            &a,
            &CsvOptions {
                time_scale_s: 1e-9,
                accel: AccelUnit::Counts(0.01),
                gyro: GyroUnit::Counts(1e-3),
                gyro_file: Some(g.clone()),
            },
        )
        .unwrap();
        // Accel samples 0 and 1 precede the gyro's first (15 ms): dropped.
        assert_eq!(s.len(), 8, "{:?}", s.t_s);
        assert!((s.accel_m_s2[0][0] - 0.02).abs() < 1e-12);
        assert!((s.accel_m_s2[0][2] - 1.0).abs() < 1e-12);
        for (k, w) in s.gyro_rad_s.iter().enumerate() {
            // Accel sample k + 2 at (k + 2) x 10 ms: gyro z = 2 x ms x 1e-3.
            let want = 2.0 * (10.0 * (k + 2) as f64) * 1e-3;
            assert!((w[2] - want).abs() < 1e-9, "{k}: {} vs {want}", w[2]);
        }
        assert!(s.origin.contains("acc.csv + "), "{}", s.origin);
        // Files on different clocks do not overlap: a clear error naming the gyro file.
        std::fs::write(&g, "0,0,0,0\n0.5,0,0,0\n").unwrap();
        let e = read_csv(
            &a,
            &CsvOptions {
                time_scale_s: 1e-9,
                gyro_file: Some(g.clone()),
                ..CsvOptions::default()
            },
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("gyr.csv") && e.contains("one clock"), "{e}");
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
