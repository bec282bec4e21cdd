//! What every recording format's reader feeds (MCAP, ROS 1 bag, rosbag2 sqlite3): IMU,
//! raw-sample and temperature messages in file order become one [`ImuSeries`], with the one
//! topic rule (the `--topic` asked for must exist; several IMU topics and none asked for are an
//! error listing them) and the one raw-stream rule, whatever the file's format.
//!
//! Raw stream: imud's own raw samples when the file has them (the device's SI reading, or v1
//! counts converted with the recorded GainScales); a file without any (another driver's log,
//! converted or not) has only its `sensor_msgs/Imu` topics, which are then that driver's
//! measurement and are read as the corrected stream is.

use std::collections::BTreeMap;
use std::path::Path;

use imu_proto::scale;
use imu_rec::Unfinished;
use imu_rec::ros2::{Imu, RawSampleMsg};
use imu_rec::sample::raw_flags;

use super::{
    CalibrationInForce, G0, IMU_SCHEMA, ImuSeries, ImudFile, InputError, InputInfo, Source,
};

/// What a read has gathered so far.
#[derive(Default)]
pub(super) struct Collector {
    source: Source,
    /// The topic asked for (`--topic`).
    requested: Option<String>,
    /// The IMU topic read: the one asked for, else the first seen.
    chosen: Option<String>,
    /// Messages per IMU topic, read or not.
    imu_topics: BTreeMap<String, u64>,
    /// A raw read has met an imud raw sample (IMU messages read before it are dropped).
    raw_seen: bool,
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

fn vec3(v: &imu_rec::ros2::Vector3) -> [f64; 3] {
    [v.x, v.y, v.z]
}

/// How a read ended, from the format's reader.
pub(super) struct ReadEnd {
    /// Why the read stopped early, if it did.
    pub stopped_early: Option<String>,
    /// The same as data.
    pub unfinished: Option<Unfinished>,
    /// An imud recording's place in its session.
    pub imud_file: Option<ImudFile>,
    /// The calibration an imud recording says was in force.
    pub calibration: Option<CalibrationInForce>,
}

impl Collector {
    pub(super) fn new(source: Source, topic: Option<&str>) -> Self {
        Self {
            source,
            requested: topic.map(str::to_string),
            ..Self::default()
        }
    }

    /// True while IMU messages are read: always for the corrected stream, and for the raw
    /// one until an imud raw sample shows the file has its own.
    fn wants_imu(&self) -> bool {
        self.source == Source::Corrected || !self.raw_seen
    }

    /// Announces an IMU topic the file declares (a channel, connection or topics row), so a
    /// topic without messages is still listed.
    pub(super) fn imu_topic(&mut self, topic: &str) {
        if !self.imu_topics.contains_key(topic) {
            self.imu_topics.insert(topic.to_string(), 0);
        }
    }

    /// An IMU message on `topic`, decoded by `decode` only when it is the one read.
    pub(super) fn imu(
        &mut self,
        topic: &str,
        decode: impl FnOnce() -> Result<Imu, String>,
    ) -> Result<(), String> {
        match self.imu_topics.get_mut(topic) {
            Some(n) => *n += 1,
            None => {
                self.imu_topics.insert(topic.to_string(), 1);
            }
        }
        if !self.wants_imu() || self.not_by_default(topic) {
            return Ok(());
        }
        let pick = match &self.requested {
            Some(t) => t,
            None => self.chosen.get_or_insert_with(|| topic.to_string()),
        };
        if pick != topic {
            return Ok(());
        }
        let m = decode()?;
        self.abs_ns.push(m.header.stamp.to_ns());
        self.series.accel_m_s2.push(vec3(&m.linear_acceleration));
        self.series.gyro_rad_s.push(vec3(&m.angular_velocity));
        Ok(())
    }

    /// An imud recording's `/imu/device_compensated` (a unit's own compensated outputs) is read
    /// only when asked for by name: without a topic, a recording's IMU stream is `/imu/data`.
    fn not_by_default(&self, topic: &str) -> bool {
        self.requested.is_none() && topic == imu_rec::recording::DEVICE_COMPENSATED_TOPIC
    }

    /// True if a raw read takes imud raw samples (a corrected read does not decode them).
    pub(super) fn wants_raw(&self) -> bool {
        self.source == Source::Raw
    }

    /// One of imud's raw samples (raw reads only).
    pub(super) fn raw(&mut self, m: RawSampleMsg) {
        if !self.raw_seen {
            // The file has imud's raw stream: IMU messages read before it are not the raw read.
            self.raw_seen = true;
            self.abs_ns.clear();
            self.series.accel_m_s2.clear();
            self.series.gyro_rad_s.clear();
        }
        let s = m.sample;
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

    /// A temperature reading stamped `t_ns`.
    pub(super) fn temperature(&mut self, t_ns: u64, c: f64) {
        self.temps_ns.push((t_ns, c));
    }

    /// The series: the topic checked, raw counts converted with `device` (the recording's
    /// `imud.device` metadata, which the series keeps), times from the first sample.
    pub(super) fn finish(
        mut self,
        path: &Path,
        device: Option<&BTreeMap<String, String>>,
        end: ReadEnd,
    ) -> Result<ImuSeries, InputError> {
        if self.source == Source::Raw && self.raw_seen {
            self.convert_raw(path, device)?;
        } else {
            self.check_topic(path)?;
        }
        self.into_series(path, device, end)
    }

    /// The IMU topic read is named: the one asked for must exist, and several IMU topics
    /// without one asked for are an error listing them.
    fn check_topic(&mut self, path: &Path) -> Result<(), InputError> {
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
            None if self
                .imu_topics
                .iter()
                .filter(|(t, n)| **n > 0 && !self.not_by_default(t))
                .count()
                > 1 =>
            {
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
    fn convert_raw(
        &mut self,
        path: &Path,
        dev: Option<&BTreeMap<String, String>>,
    ) -> Result<(), InputError> {
        self.chosen = Some(imu_rec::recording::RAW_TOPIC.to_string());
        if self.raw_units.iter().all(|u| *u == RawUnits::Si) {
            return Ok(());
        }
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
    fn into_series(
        self,
        path: &Path,
        device: Option<&BTreeMap<String, String>>,
        end: ReadEnd,
    ) -> Result<ImuSeries, InputError> {
        let mut series = self.series;
        let mut abs_ns = self.abs_ns;
        // Samples holding a NaN or infinity are skipped, in one pass that keeps the others in
        // place.
        let mut kept = 0;
        for i in 0..abs_ns.len() {
            let (a, g) = (series.accel_m_s2[i], series.gyro_rad_s[i]);
            if a.iter().chain(&g).all(|v| v.is_finite()) {
                abs_ns[kept] = abs_ns[i];
                series.accel_m_s2[kept] = a;
                series.gyro_rad_s[kept] = g;
                kept += 1;
            }
        }
        let non_finite_samples = (abs_ns.len() - kept) as u64;
        abs_ns.truncate(kept);
        series.accel_m_s2.truncate(kept);
        series.gyro_rad_s.truncate(kept);
        let Some(&t0) = abs_ns.first() else {
            return Err(InputError::NoData {
                path: path.to_path_buf(),
                message: if non_finite_samples > 0 {
                    format!("all {non_finite_samples} IMU samples hold a NaN or infinite value")
                } else {
                    format!("no {IMU_SCHEMA} messages (is this an IMU recording?)")
                },
            });
        };
        let rel_s = |t: u64| (t as i128 - t0 as i128) as f64 * 1e-9;
        series.t0_ns = t0;
        series.t_s = abs_ns.iter().map(|&t| rel_s(t)).collect();
        series.temp = self.temps_ns.iter().map(|&(t, c)| (rel_s(t), c)).collect();
        let topic = self.chosen.unwrap_or_default();
        series.origin = format!("{} ({topic})", path.display());
        series.stopped_early = end.stopped_early;
        series.unfinished = end.unfinished;
        series.input = InputInfo {
            files: vec![path.to_path_buf()],
            topic: Some(topic),
            gaps: Vec::new(),
            non_finite_samples,
            unfinished_file: series.unfinished.as_ref().map(|_| path.to_path_buf()),
            imud_file: end.imud_file,
            device: device.cloned().unwrap_or_default(),
            calibration: end.calibration,
        };
        Ok(series)
    }
}
