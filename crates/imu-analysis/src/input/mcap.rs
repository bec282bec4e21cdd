//! MCAP recordings: imud's own (corrected `/imu/data`, or the raw stream: the device's own SI
//! reading a v2 `RawSample` carries, or a v1 record's counts through the recorded GainScales)
//! and any file with `sensor_msgs/msg/Imu` channels (rosbag2 from other drivers),
//! read front to back in bounded memory besides the series itself, into the shared
//! `collect.rs`.

use std::path::Path;

use imu_rec::mcap_read::{self, ReadReport};
use imu_rec::ros2::{Imu, RawSampleMsg, RosMessage, Temperature};

use super::collect::{Collector, ReadEnd};
use super::{ImuSeries, InputError, Source};

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
    let mut collect = Collector::new(source, topic);
    let report = mcap_read::for_each_message_with_progress(path, on_progress, |ch, _h, data| {
        cdr_message(&mut collect, &ch.schema_name, &ch.topic, data)
    })?;
    for ch in report.channels.values() {
        if ch.schema_name == IMU_SCHEMA {
            collect.imu_topic(&ch.topic);
        }
    }
    let end = ReadEnd {
        stopped_early: report.stopped_early.clone(),
        unfinished: report.unfinished.clone(),
        imud_file: imud_file(&report),
        calibration: calibration_in_force(path, &report),
    };
    collect.finish(path, report.metadata.get("imud.device"), end)
}

/// One CDR message (MCAP or rosbag2 sqlite3), by its type.
pub(super) fn cdr_message(
    collect: &mut Collector,
    msg_type: &str,
    topic: &str,
    data: &[u8],
) -> Result<(), String> {
    match msg_type {
        IMU_SCHEMA => collect.imu(topic, || {
            Imu::from_cdr(data).map_err(|e| format!("{IMU_SCHEMA}: {e}"))
        }),
        "imud_msgs/msg/RawSample" if collect.wants_raw() => {
            let m = RawSampleMsg::from_cdr(data)
                .map_err(|e| format!("imud_msgs/msg/RawSample: {e}"))?;
            collect.raw(m);
            Ok(())
        }
        "sensor_msgs/msg/Temperature" => {
            let m = Temperature::from_cdr(data)
                .map_err(|e| format!("sensor_msgs/msg/Temperature: {e}"))?;
            collect.temperature(m.header.stamp.to_ns(), m.temperature);
            Ok(())
        }
        _ => Ok(()),
    }
}

/// The session place of an imud recording file (`None` for other MCAP files).
fn imud_file(report: &ReadReport) -> Option<super::ImudFile> {
    let rec = report
        .metadata
        .get(imu_rec::recording::RECORDING_METADATA)?;
    Some(super::ImudFile {
        prefix: rec.get("prefix")?.clone(),
        file_index: rec.get("file-index")?.parse().ok()?,
    })
}

/// The calibration in force in an imud recording file (the last `imud.calibration` record
/// read: the reader keeps the latest of each name); `None` without one, or with a record that
/// lacks its id or text.
fn calibration_in_force(path: &Path, report: &ReadReport) -> Option<super::CalibrationInForce> {
    let cal = report
        .metadata
        .get(imu_rec::recording::CALIBRATION_METADATA)?;
    Some(super::CalibrationInForce {
        id: cal.get("id")?.clone(),
        toml: cal.get("toml")?.clone(),
        file: path.to_path_buf(),
    })
}
