//! Reading recordings back: file names and times, every record in order, the whole recording.

use super::*;

/// `YYYYMMDDTHHMMSSZ` of a wall-clock time, UTC.
pub fn utc_stamp(t: SystemTime) -> String {
    let secs = t
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0);
    let (y, m, d, hh, mm, ss) = civil_time(secs);
    format!("{y:04}{m:02}{d:02}T{hh:02}{mm:02}{ss:02}Z")
}

/// ISO 8601 `YYYY-MM-DDTHH:MM:SS.nnnnnnnnnZ` of a Unix-epoch time in ns, UTC (what a
/// recording's start is said as to programs: Python's `datetime.fromisoformat` reads it).
pub fn utc_iso8601_ns(t_ns: u64) -> String {
    let (y, m, d, hh, mm, ss) = civil_time(t_ns / 1_000_000_000);
    let ns = t_ns % 1_000_000_000;
    format!("{y:04}-{m:02}-{d:02}T{hh:02}:{mm:02}:{ss:02}.{ns:09}Z")
}

/// Date and time of day (year, month, day, hour, minute, second) of Unix-epoch seconds, UTC.
fn civil_time(secs: u64) -> (i64, u32, u32, u64, u64, u64) {
    let (y, m, d) = civil_from_days((secs / 86_400) as i64);
    let s = secs % 86_400;
    (y, m, d, s / 3600, s % 3600 / 60, s % 60)
}

/// Proleptic Gregorian date of a day count since 1970-01-01 (H. Hinnant's algorithm).
pub(super) fn civil_from_days(days: i64) -> (i64, u32, u32) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let y = yoe + era * 400 + i64::from(m <= 2);
    (y, m, d)
}

/// The recording files of `prefix` in `dir`, sorted by name (start time, then index).
pub fn list_recordings(dir: &Path, prefix: &str) -> io::Result<Vec<PathBuf>> {
    let start = format!("{prefix}-");
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with(&start) && n.ends_with(".mcap"))
        })
        .collect();
    files.sort();
    Ok(files)
}

/// One `/imu/raw_frame` message.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct RecordedFrame {
    /// Host wall clock when the bytes were read, ns.
    pub t_host_wall_ns: u64,
    /// Host monotonic clock when the bytes were read, ns.
    pub t_host_monotonic_ns: u64,
    /// Offset of the first byte in the device byte stream.
    pub stream_offset: u64,
    /// True for a frame with a good checksum.
    pub accepted: bool,
    /// Why the bytes were rejected (`None` when accepted).
    pub reject_reason: Option<String>,
    /// The bytes.
    pub bytes: Vec<u8>,
}

/// One `/imud/calibration` message.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct RecordedCalibration {
    /// Host wall clock when it took effect, ns.
    pub t_wall_ns: u64,
    /// Content id.
    pub id: String,
    /// The calibration file text.
    pub toml: String,
}

/// One message of a recording, decoded.
#[derive(Debug, Clone, PartialEq)]
pub enum RecordedMessage {
    /// `/imu/data`.
    Imu(Imu),
    /// `/imu/mag`.
    MagneticField(MagneticField),
    /// `/imu/temperature`.
    Temperature(Temperature),
    /// `/imu/raw`.
    Raw(RawSample),
    /// `/imu/raw_frame`.
    Frame(RecordedFrame),
    /// `/imud/status`.
    Status {
        /// Host wall clock of the status (its header stamp), ns.
        t_wall_ns: u64,
        /// The counters.
        status: DaemonStatus,
    },
    /// `/imud/calibration`.
    Calibration(RecordedCalibration),
    /// `/imud/health`.
    Health(CalibrationHealth),
    /// `/imu/device_compensated`.
    DeviceCompensated(Imu),
}

pub(super) fn decode<M: RosMessage>(
    channel: &mcap_read::ChannelInfo,
    data: &[u8],
) -> Result<M, String> {
    let expected = M::DEFINITION.type_name;
    if channel.schema_name != expected || channel.message_encoding != "cdr" {
        return Err(format!(
            "schema {:?} with encoding {:?}; expected {expected} in cdr",
            channel.schema_name, channel.message_encoding
        ));
    }
    M::from_cdr(data).map_err(|e| format!("{expected}: {e}"))
}

/// Reads a recording front to back, handing each message of a known topic to `on_message`
/// (unknown topics are skipped), in file order. Memory stays bounded whatever the file size; a
/// truncated file (killed writer) is read up to its last complete chunk and the report says
/// where it stopped.
pub fn for_each_record(
    path: &Path,
    mut on_message: impl FnMut(RecordedMessage),
) -> Result<ReadReport, McapReadError> {
    mcap_read::for_each_message(path, |channel, _header, data| {
        let msg = match channel.topic.as_str() {
            IMU_TOPIC => RecordedMessage::Imu(decode(channel, data)?),
            DEVICE_COMPENSATED_TOPIC => RecordedMessage::DeviceCompensated(decode(channel, data)?),
            MAG_TOPIC => RecordedMessage::MagneticField(decode(channel, data)?),
            TEMPERATURE_TOPIC => RecordedMessage::Temperature(decode(channel, data)?),
            RAW_TOPIC => RecordedMessage::Raw(decode::<RawSampleMsg>(channel, data)?.sample),
            RAW_FRAME_TOPIC => {
                let m: RawFrameMsg = decode(channel, data)?;
                RecordedMessage::Frame(RecordedFrame {
                    t_host_wall_ns: m.header.stamp.to_ns(),
                    t_host_monotonic_ns: m.t_host_monotonic_ns,
                    stream_offset: m.stream_offset,
                    accepted: m.accepted,
                    reject_reason: Some(m.reject_reason).filter(|r| !r.is_empty()),
                    bytes: m.data,
                })
            }
            STATUS_TOPIC => {
                let m: DaemonStatusMsg = decode(channel, data)?;
                RecordedMessage::Status {
                    t_wall_ns: m.header.stamp.to_ns(),
                    status: m.status,
                }
            }
            HEALTH_TOPIC => {
                RecordedMessage::Health(decode::<CalibrationHealthMsg>(channel, data)?.health)
            }
            CALIBRATION_TOPIC => {
                let m: CalibrationMsg = decode(channel, data)?;
                RecordedMessage::Calibration(RecordedCalibration {
                    t_wall_ns: m.header.stamp.to_ns(),
                    id: m.id,
                    toml: m.toml,
                })
            }
            _ => return Ok(()),
        };
        on_message(msg);
        Ok(())
    })
}

/// A whole recording file in memory (see [`for_each_record`] for long ones).
#[derive(Debug, Clone, Default)]
pub struct Recording {
    /// `/imu/raw`, in order: the authoritative sample record.
    pub raw: Vec<RawSample>,
    /// `/imu/data`, in order.
    pub imu: Vec<Imu>,
    /// `/imu/mag`, in order.
    pub mag: Vec<MagneticField>,
    /// `/imu/temperature` as (host wall clock ns, deg C).
    pub temperatures: Vec<(u64, f64)>,
    /// `/imu/raw_frame`, in order.
    pub frames: Vec<RecordedFrame>,
    /// `/imud/status` as (host wall clock ns, counters).
    pub statuses: Vec<(u64, DaemonStatus)>,
    /// `/imud/calibration`, in order.
    pub calibrations: Vec<RecordedCalibration>,
    /// `/imud/health`, in order.
    pub health: Vec<CalibrationHealth>,
    /// `/imu/device_compensated`, in order (empty for a unit that sends none).
    pub device_compensated: Vec<Imu>,
    /// Metadata records by name (the last of each name).
    pub metadata: BTreeMap<String, BTreeMap<String, String>>,
    /// `Some(reason)` when the file ended before its footer (killed writer, damage).
    pub stopped_early: Option<String>,
}

/// Reads a whole recording file into memory.
pub fn read_recording(path: &Path) -> Result<Recording, McapReadError> {
    let mut rec = Recording::default();
    let report = for_each_record(path, |m| match m {
        RecordedMessage::Imu(m) => rec.imu.push(m),
        RecordedMessage::MagneticField(m) => rec.mag.push(m),
        RecordedMessage::Temperature(m) => rec
            .temperatures
            .push((m.header.stamp.to_ns(), m.temperature)),
        RecordedMessage::Raw(s) => rec.raw.push(s),
        RecordedMessage::Frame(f) => rec.frames.push(f),
        RecordedMessage::Status { t_wall_ns, status } => rec.statuses.push((t_wall_ns, status)),
        RecordedMessage::Calibration(c) => rec.calibrations.push(c),
        RecordedMessage::Health(h) => rec.health.push(h),
        RecordedMessage::DeviceCompensated(m) => rec.device_compensated.push(m),
    })?;
    rec.metadata = report.metadata;
    rec.stopped_early = report.stopped_early;
    Ok(rec)
}
