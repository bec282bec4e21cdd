//! MCAP recordings: imud's own (corrected `/imu/data`, or the raw stream: the device's own SI
//! reading a v2 `RawSample` carries, or a v1 record's counts through the recorded GainScales)
//! and any file with `sensor_msgs/msg/Imu` channels (rosbag2 from other drivers),
//! read front to back in bounded memory besides the series itself.

use std::collections::BTreeMap;
use std::path::Path;

use imu_bus::mcap_read::{self, ChannelInfo, ReadReport};
use imu_bus::ros2::{Imu, RawSampleMsg, RosMessage, Temperature};
use imu_bus::sample::raw_flags;
use imu_proto::scale;

use super::{G0, ImuSeries, InputError, InputInfo, Source};

/// The schema of the messages a corrected read takes.
pub const IMU_SCHEMA: &str = "sensor_msgs/msg/Imu";

/// Reads an MCAP recording: imud's own, or any file with a `sensor_msgs/msg/Imu` channel.
/// `topic` picks a channel when several carry IMU data; without it, several are an error that
/// lists them (never one picked silently).
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
    let mut collect = Collector {
        source,
        requested: topic.map(str::to_string),
        ..Collector::default()
    };
    let report = mcap_read::for_each_message_with_progress(path, on_progress, |ch, _h, data| {
        collect.message(ch, data)
    })?;
    collect.check_topic(path, &report)?;
    if source == Source::Raw {
        collect.convert_raw(path, &report)?;
    }
    collect.into_series(path, report)
}

/// The session place of an imud recording file (`None` for other MCAP files).
fn imud_file(report: &ReadReport) -> Option<super::ImudFile> {
    let rec = report
        .metadata
        .get(imu_bus::recording::RECORDING_METADATA)?;
    Some(super::ImudFile {
        prefix: rec.get("prefix")?.clone(),
        file_index: rec.get("file-index")?.parse().ok()?,
        device: report
            .metadata
            .get("imud.device")
            .cloned()
            .unwrap_or_default(),
    })
}

/// What a read has gathered so far.
#[derive(Default)]
struct Collector {
    source: Source,
    /// The topic asked for (`--topic`).
    requested: Option<String>,
    /// The IMU topic read: the one asked for, else the first seen.
    chosen: Option<String>,
    /// Messages per `sensor_msgs/msg/Imu` topic, read or not.
    imu_topics: BTreeMap<String, u64>,
    series: ImuSeries,
    abs_ns: Vec<u64>,
    temps_ns: Vec<(u64, f64)>,
    /// What each raw sample's values in the series' own arrays are: SI already (the device's
    /// reading of a v2 record), or counts converted in place once the GainScales are known (the
    /// metadata holding them is written when the file is closed): 49 bytes a sample instead of
    /// a RawSample's 176.
    raw_units: Vec<RawUnits>,
}

/// The units of one raw sample's values as read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum RawUnits {
    /// The device's own reading in SI (a v2 record: every protocol).
    Si,
    /// 3DM-GX1 raw ADC bits (a v1 record).
    RawBits,
    /// 3DM-GX1 scaled i16 vectors (a v1 record).
    ScaledCounts,
}

fn vec3(v: &imu_bus::ros2::Vector3) -> [f64; 3] {
    [v.x, v.y, v.z]
}

impl Collector {
    fn message(&mut self, ch: &ChannelInfo, data: &[u8]) -> Result<(), String> {
        match ch.schema_name.as_str() {
            IMU_SCHEMA if self.source == Source::Corrected => {
                *self.imu_topics.entry(ch.topic.clone()).or_default() += 1;
                let pick = match &self.requested {
                    Some(t) => t,
                    None => self.chosen.get_or_insert_with(|| ch.topic.clone()),
                };
                if *pick != ch.topic {
                    return Ok(());
                }
                let m = Imu::from_cdr(data).map_err(|e| format!("{IMU_SCHEMA}: {e}"))?;
                self.abs_ns.push(m.header.stamp.to_ns());
                self.series.accel_m_s2.push(vec3(&m.linear_acceleration));
                self.series.gyro_rad_s.push(vec3(&m.angular_velocity));
            }
            "imud_msgs/msg/RawSample" if self.source == Source::Raw => {
                let s = RawSampleMsg::from_cdr(data)
                    .map_err(|e| format!("imud_msgs/msg/RawSample: {e}"))?
                    .sample;
                // Temperatures are stamped on the wall clock, raw samples carry both clocks.
                self.abs_ns.push(
                    s.t_host_wall_ns
                        .saturating_sub(s.t_host_monotonic_ns.saturating_sub(s.t_sample_ns)),
                );
                let si = s.accel_device_m_s2.iter().all(|v| v.is_finite())
                    && s.gyro_device_rad_s.iter().all(|v| v.is_finite());
                if si {
                    self.series.accel_m_s2.push(s.accel_device_m_s2);
                    self.series.gyro_rad_s.push(s.gyro_device_rad_s);
                    self.raw_units.push(RawUnits::Si);
                } else {
                    self.series.accel_m_s2.push(s.accel_counts.map(f64::from));
                    self.series.gyro_rad_s.push(s.gyro_counts.map(f64::from));
                    self.raw_units
                        .push(if s.flags & raw_flags::SCALED_COUNTS != 0 {
                            RawUnits::ScaledCounts
                        } else {
                            RawUnits::RawBits
                        });
                }
            }
            "sensor_msgs/msg/Temperature" => {
                let m = Temperature::from_cdr(data)
                    .map_err(|e| format!("sensor_msgs/msg/Temperature: {e}"))?;
                self.temps_ns.push((m.header.stamp.to_ns(), m.temperature));
            }
            _ => {}
        }
        Ok(())
    }

    /// A corrected read names its topic: the one asked for must exist, and several IMU topics
    /// without one asked for are an error listing them.
    fn check_topic(&mut self, path: &Path, report: &ReadReport) -> Result<(), InputError> {
        if self.source != Source::Corrected {
            return Ok(());
        }
        for ch in report.channels.values() {
            if ch.schema_name == IMU_SCHEMA {
                self.imu_topics.entry(ch.topic.clone()).or_default();
            }
        }
        let listed = || {
            self.imu_topics
                .iter()
                .map(|(t, n)| (t.clone(), *n))
                .collect()
        };
        match &self.requested {
            Some(t) if !self.imu_topics.contains_key(t) => Err(InputError::NoSuchTopic {
                path: path.to_path_buf(),
                topic: t.clone(),
                topics: listed(),
            }),
            Some(t) => {
                self.chosen = Some(t.clone());
                Ok(())
            }
            None if self.imu_topics.values().filter(|n| **n > 0).count() > 1 => {
                Err(InputError::AmbiguousTopic {
                    path: path.to_path_buf(),
                    topics: listed(),
                })
            }
            None => Ok(()),
        }
    }

    /// Raw counts to SI with the recording's GainScales (metadata `imud.device`); samples in
    /// SI already need none.
    fn convert_raw(&mut self, path: &Path, report: &ReadReport) -> Result<(), InputError> {
        self.chosen = Some(imu_bus::recording::RAW_TOPIC.to_string());
        if self.raw_units.iter().all(|u| *u == RawUnits::Si) {
            return Ok(());
        }
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
        let to_units = |c: f64, g: u16, units: RawUnits| match units {
            RawUnits::ScaledCounts => scale::scaled_to_units(c as i16, g),
            RawUnits::RawBits => scale::raw_bits_to_units(c as u16, g),
            RawUnits::Si => c,
        };
        for ((a, w), &units) in self
            .series
            .accel_m_s2
            .iter_mut()
            .zip(&mut self.series.gyro_rad_s)
            .zip(&self.raw_units)
        {
            if units != RawUnits::Si {
                *a = a.map(|c| to_units(c, ga, units) * G0);
                *w = w.map(|c| to_units(c, gg, units));
            }
        }
        Ok(())
    }

    /// Times from the first sample, the temperatures on the same base, what was read.
    fn into_series(self, path: &Path, report: ReadReport) -> Result<ImuSeries, InputError> {
        let mut series = self.series;
        let imud_file = imud_file(&report);
        let Some(&t0) = self.abs_ns.first() else {
            return Err(InputError::NoData {
                path: path.to_path_buf(),
                message: match self.source {
                    Source::Corrected => {
                        format!("no {IMU_SCHEMA} messages (is this an IMU recording?)")
                    }
                    Source::Raw => {
                        "no /imu/raw messages (only imud recordings carry raw counts)".into()
                    }
                },
            });
        };
        let rel_s = |t: u64| (t as i128 - t0 as i128) as f64 * 1e-9;
        series.t0_ns = t0;
        series.t_s = self.abs_ns.iter().map(|&t| rel_s(t)).collect();
        series.temp = self.temps_ns.iter().map(|&(t, c)| (rel_s(t), c)).collect();
        let topic = self.chosen.unwrap_or_default();
        series.origin = format!("{} ({topic})", path.display());
        series.stopped_early = report.stopped_early;
        series.unfinished = report.unfinished;
        series.input = InputInfo {
            files: vec![path.to_path_buf()],
            topic: Some(topic),
            gaps: Vec::new(),
            unfinished_file: series.unfinished.as_ref().map(|_| path.to_path_buf()),
            imud_file,
        };
        Ok(series)
    }
}
