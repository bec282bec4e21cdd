//! The daemon's MCAP log: every frame, sample, temperature, status and calibration, written by a
//! thread behind a bounded queue, in ROS 2 form (profile `ros2`, `ros2msg` schemas, CDR
//! messages), with size/time rotation, crash-safe periodic flushing and recovery from write
//! errors; and the reader for those files.
//!
//! Topics (see the `*_TOPIC` constants): `/imu/data` (`sensor_msgs/msg/Imu`), `/imu/mag`
//! (`sensor_msgs/msg/MagneticField`, tesla), `/imu/temperature` (`sensor_msgs/msg/Temperature`),
//! `/imu/raw` (`imud_msgs/msg/RawSample`), `/imu/raw_frame` (`imud_msgs/msg/RawFrame`: every
//! byte received, accepted or rejected), `/imud/status` (`imud_msgs/msg/DaemonStatus`) and
//! `/imud/calibration` (`imud_msgs/msg/Calibration`), `/imud/health` (`imud_msgs/msg/CalibrationHealth`),
//! and, for a unit that sends its own compensated outputs beside the raw ones (Xsens),
//! `/imu/device_compensated` (`sensor_msgs/msg/Imu`, at the sample's stamp). Message log times and header stamps are
//! host wall-clock nanoseconds; `/imu/raw` is the authoritative per-sample record (it carries the
//! sequence number and every timestamp).
//!
//! The producer side ([`Recorder::log`]) never blocks: a full queue drops the record and counts
//! it. The writer thread ends the current chunk and flushes it to the OS at least every
//! [`RecordingConfig::flush_interval`], so a file whose process was killed is readable up to
//! that point by a truncation-tolerant reader ([`for_each_record`], Python `mcap`'s streaming
//! reader). On a write error (disk full) it stops logging loudly, keeps counting what it drops,
//! and tries a new file every [`RecordingConfig::retry_interval`].

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::fs::File;
use std::io::{self, BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use mcap::records::MessageHeader;

use crate::mcap_read::{self, McapReadError, ReadReport};
use crate::ros2::{
    self, CalibrationHealthMsg, CalibrationMsg, DaemonStatusMsg, Header, Imu, MagneticField,
    MsgDefinition, Quaternion, RawFrameMsg, RawSampleMsg, RosMessage, Temperature, Time,
};
use crate::sample::{CalibrationHealth, CorrectedSample, DaemonStatus, RawSample};

mod messages;
mod read;
mod writer;

pub use messages::*;
pub use read::*;
use writer::*;

/// Corrected samples as `sensor_msgs/msg/Imu`.
pub const IMU_TOPIC: &str = "/imu/data";
/// Corrected magnetic field as `sensor_msgs/msg/MagneticField` (tesla).
pub const MAG_TOPIC: &str = "/imu/mag";
/// Device temperature readings as `sensor_msgs/msg/Temperature`.
pub const TEMPERATURE_TOPIC: &str = "/imu/temperature";
/// Raw samples as `imud_msgs/msg/RawSample` (authoritative for sequence numbers and times).
pub const RAW_TOPIC: &str = "/imu/raw";
/// Every run of bytes from the device, accepted or rejected, as `imud_msgs/msg/RawFrame`.
pub const RAW_FRAME_TOPIC: &str = "/imu/raw_frame";
/// The unit's own compensated outputs (its factory calibration and bias estimates applied),
/// when it sends them beside the raw reading, as `sensor_msgs/msg/Imu` stamped like the
/// sample's `/imu/data`; never corrected by imud.
pub const DEVICE_COMPENSATED_TOPIC: &str = "/imu/device_compensated";
/// Daemon health counters as `imud_msgs/msg/DaemonStatus`.
pub const STATUS_TOPIC: &str = "/imud/status";
/// Each calibration put in force, as `imud_msgs/msg/Calibration`.
pub const CALIBRATION_TOPIC: &str = "/imud/calibration";
/// The calibration held against physics after every still window, as
/// `imud_msgs/msg/CalibrationHealth`.
pub const HEALTH_TOPIC: &str = "/imud/health";

/// Metadata record the recorder adds to every file: `file-index`, `prefix`, `started-utc`,
/// `frame-id`, `library`.
pub const RECORDING_METADATA: &str = "imud.recording";
/// Metadata record holding the calibration in force (`id`, `toml`), repeated in every file
/// started after it was put in force.
pub const CALIBRATION_METADATA: &str = "imud.calibration";

/// Tesla per gauss.
pub const TESLA_PER_GAUSS: f64 = 1e-4;

/// Every channel of a recording: topic and message type, in channel-id order.
pub const CHANNELS: [(&str, &MsgDefinition); 9] = [
    (IMU_TOPIC, &ros2::IMU_DEF),
    (MAG_TOPIC, &ros2::MAGNETIC_FIELD_DEF),
    (TEMPERATURE_TOPIC, &ros2::TEMPERATURE_DEF),
    (RAW_TOPIC, &ros2::RAW_SAMPLE_DEF),
    (RAW_FRAME_TOPIC, &ros2::RAW_FRAME_DEF),
    (STATUS_TOPIC, &ros2::DAEMON_STATUS_DEF),
    (CALIBRATION_TOPIC, &ros2::CALIBRATION_DEF),
    (HEALTH_TOPIC, &ros2::CALIBRATION_HEALTH_DEF),
    (DEVICE_COMPENSATED_TOPIC, &ros2::IMU_DEF),
];
const CH_IMU: usize = 0;
const CH_MAG: usize = 1;
const CH_TEMPERATURE: usize = 2;
const CH_RAW: usize = 3;
const CH_FRAME: usize = 4;
const CH_STATUS: usize = 5;
const CH_CALIBRATION: usize = 6;
const CH_HEALTH: usize = 7;
const CH_DEVICE_COMPENSATED: usize = 8;

/// Noise variances of the corrected outputs, used as the diagonal covariances of `/imu/data`
/// and `/imu/mag`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ImuNoiseVariances {
    /// Accelerometer variance per axis, (m/s^2)^2.
    pub accel_var_m2_s4: [f64; 3],
    /// Gyro variance per axis, (rad/s)^2.
    pub gyro_var_rad2_s2: [f64; 3],
    /// Magnetometer variance per axis, T^2.
    pub mag_var_t2: [f64; 3],
}

/// Bytes of a frame kept inline up to this many (a 3DM-GX1 reply, 23 bytes at most, or a MIP
/// IMU packet of the fields imud configures, 72 bytes), so logging a frame does not allocate.
pub const FRAME_INLINE_BYTES: usize = 80;

/// Device bytes in a log record: inline up to [`FRAME_INLINE_BYTES`], on the heap beyond (a long
/// run of rejected bytes, a large MIP reply).
pub type FrameData = smallvec::SmallVec<[u8; FRAME_INLINE_BYTES]>;

/// The accepted frame a [`LogRecord::Sample`] was decoded from; its host times are the raw
/// sample's (`t_host_wall_ns`, `t_host_monotonic_ns`: the read that completed it).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SampleFrame {
    /// Offset of the frame's first byte in the device byte stream.
    pub stream_offset: u64,
    /// The frame, header to checksum.
    pub bytes: FrameData,
}

/// A unit's own compensated reading of one sample (`/imu/device_compensated`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DeviceCompensated {
    /// Compensated specific force, m/s^2.
    pub accel_m_s2: [f64; 3],
    /// Compensated angular rate, rad/s.
    pub gyro_rad_s: [f64; 3],
}

/// One thing to log. Times are host clock nanoseconds (`_wall_ns`: Unix epoch).
#[derive(Debug, Clone, PartialEq)]
// `allow`, not `expect`: whether the lint fires depends on how much larger the sample is than
// the next largest record (the status), which changes with their layouts.
#[allow(
    clippy::large_enum_variant,
    reason = "records travel by value through the writer's queue: boxing the per-frame \
              `Sample` would put an allocation back on the data path it was made to spare"
)]
pub enum LogRecord {
    /// Bytes from the device: a frame with a good checksum, or a run of rejected bytes.
    RawFrame {
        /// Host wall clock when the bytes were read, ns.
        t_host_wall_ns: u64,
        /// Host monotonic clock when the bytes were read, ns.
        t_host_monotonic_ns: u64,
        /// Offset of the first byte in the device byte stream.
        stream_offset: u64,
        /// True for a frame with a good checksum.
        accepted: bool,
        /// Why the bytes were rejected (`bad-checksum`, `malformed`, `truncated`, `garbage`);
        /// `None` when accepted.
        reject_reason: Option<Cow<'static, str>>,
        /// The bytes.
        bytes: FrameData,
    },
    /// A data sample with the accepted frame it was decoded from: the per-frame path's one
    /// record (one hand-off to the writer per frame instead of three). Written as the frame
    /// (`/imu/raw_frame`, at the raw sample's host times), then `/imu/raw`, `/imu/data` and
    /// `/imu/mag`: the same messages as a [`LogRecord::RawFrame`], a [`LogRecord::Raw`] and a
    /// [`LogRecord::Corrected`] in that order; then the unit's compensated reading, if any
    /// (`/imu/device_compensated`).
    Sample {
        /// The frame (`None`: a sample without one, or whose frame was logged already).
        frame: Option<SampleFrame>,
        /// The raw sample.
        raw: RawSample,
        /// The corrected sample.
        corrected: CorrectedSample,
        /// The unit's own compensated reading of the sample, when it sends one.
        compensated: Option<DeviceCompensated>,
    },
    /// A decoded data frame (`/imu/raw`, stamped with its `t_host_wall_ns`).
    Raw(RawSample),
    /// A corrected sample (`/imu/data` and `/imu/mag`, stamped with its `t_wall_ns`).
    Corrected(CorrectedSample),
    /// A temperature reading.
    Temperature {
        /// Host wall clock of the reading, ns.
        t_wall_ns: u64,
        /// Temperature, deg C.
        temp_c: f64,
    },
    /// Daemon health counters.
    Status {
        /// Host wall clock of the status, ns.
        t_wall_ns: u64,
        /// The counters.
        status: DaemonStatus,
    },
    /// The calibration held against physics over a still window.
    Health(CalibrationHealth),
    /// A calibration put in force.
    Calibration {
        /// Host wall clock when it took effect, ns.
        t_wall_ns: u64,
        /// Content id.
        id: String,
        /// The calibration file text.
        toml: String,
        /// Noise of the corrected outputs under this calibration; `None`: unknown, so
        /// `/imu/data` and `/imu/mag` covariances are all zeros from here on.
        noise: Option<ImuNoiseVariances>,
    },
}

impl LogRecord {
    /// The record's host wall-clock time, Unix epoch ns.
    pub fn t_wall_ns(&self) -> u64 {
        match self {
            LogRecord::RawFrame { t_host_wall_ns, .. } => *t_host_wall_ns,
            LogRecord::Sample { raw, .. } | LogRecord::Raw(raw) => raw.t_host_wall_ns,
            LogRecord::Corrected(c) => c.t_wall_ns,
            LogRecord::Temperature { t_wall_ns, .. }
            | LogRecord::Status { t_wall_ns, .. }
            | LogRecord::Calibration { t_wall_ns, .. } => *t_wall_ns,
            LogRecord::Health(h) => h.t_wall_ns,
        }
    }
}

/// How and where the recorder writes.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordingConfig {
    /// Directory of the MCAP files (created if missing).
    pub dir: PathBuf,
    /// File name prefix: files are `<prefix>-<UTC YYYYMMDDTHHMMSSZ>-<NNNN>.mcap`.
    pub prefix: String,
    /// Start a new file once the current one reaches this size (0: never). The open chunk
    /// counts uncompressed, so files end up somewhat smaller than this.
    pub rotate_size_bytes: u64,
    /// Start a new file once the current one is this old, seconds (0: never). Checked when a
    /// record arrives, so an idle recorder makes no empty files.
    pub rotate_interval_s: f64,
    /// Records queued for the writer thread; beyond it [`Recorder::log`] drops and counts. The
    /// queue's slots (one [`LogRecord`] each, about 400 bytes) are allocated at start.
    pub queue_capacity: usize,
    /// The longest a logged record waits before it reaches the OS; at most 1 s, so a killed
    /// daemon loses at most that much.
    pub flush_interval: Duration,
    /// After a write error, how often to try starting a new file.
    pub retry_interval: Duration,
    /// `header.frame_id` of the sensor messages.
    pub frame_id: String,
    /// zstd level of the chunks (0: zstd's default, 3). The default is 1: the writer thread
    /// keeps up with 58 kHz of frames on a shared 2-core machine at level 1, not at 3 (measured
    /// with `cargo bench -p imud --bench link`, BENCHMARKS.md), for files 2.3 % larger.
    pub compression_level: u32,
    /// `None` (live): files are named and `started-utc` stamped by the system clock.
    /// `Some(ns)`: the records' host clock is synthetic (an offline simulation dated by its
    /// scenario): the first file starts at this Unix-epoch time, ns, and a later file (rotation,
    /// retry) at the host wall time of the last record logged before it, so names and
    /// `started-utc` follow the records' own dates.
    pub synthetic_start_wall_ns: Option<u64>,
}

impl Default for RecordingConfig {
    fn default() -> Self {
        Self {
            dir: PathBuf::from("imud-logs"),
            prefix: "imud".into(),
            rotate_size_bytes: 512 * 1024 * 1024,
            rotate_interval_s: 3600.0,
            queue_capacity: 32_768,
            flush_interval: Duration::from_millis(500),
            retry_interval: Duration::from_secs(5),
            frame_id: "imu_link".into(),
            compression_level: 1,
            synthetic_start_wall_ns: None,
        }
    }
}

/// The longest allowed [`RecordingConfig::flush_interval`].
pub const MAX_FLUSH_INTERVAL: Duration = Duration::from_secs(1);

impl RecordingConfig {
    /// Checks the values a recorder cannot work with.
    pub fn validate(&self) -> Result<(), RecordingError> {
        let bad = |what: String| Err(RecordingError::Config { what });
        if self.flush_interval.is_zero() || self.flush_interval > MAX_FLUSH_INTERVAL {
            return bad(format!(
                "flush interval {:?} must be above 0 and at most {MAX_FLUSH_INTERVAL:?} (a killed \
                 daemon loses up to one interval of log)",
                self.flush_interval
            ));
        }
        if self.retry_interval.is_zero() {
            return bad("retry interval must be above 0".into());
        }
        if self.queue_capacity == 0 {
            return bad("queue capacity must be at least 1".into());
        }
        if !(self.rotate_interval_s.is_finite() && self.rotate_interval_s >= 0.0) {
            return bad(format!(
                "rotate interval {} s must be 0 (never) or positive",
                self.rotate_interval_s
            ));
        }
        if self.prefix.is_empty() || self.prefix.contains(['/', '\\']) {
            return bad(format!(
                "file prefix {:?} must be a non-empty file name part",
                self.prefix
            ));
        }
        Ok(())
    }
}

/// Errors of the recorder. Write errors after start are not returned from [`Recorder::log`]
/// (which never fails); they stop logging and show in [`RecorderStats::last_error`].
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    /// The configuration cannot work.
    #[error("recording config: {what}")]
    Config {
        /// What is wrong.
        what: String,
    },
    /// A recording file could not be created.
    #[error("{path}: cannot create recording file")]
    Create {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: io::Error,
    },
    /// Writing a recording file failed.
    #[error("{path}: cannot write recording")]
    Write {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: mcap::McapError,
    },
    /// Flushing the last bytes of a finished file failed.
    #[error("{path}: cannot close recording")]
    Close {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: io::Error,
    },
    /// The writer thread could not be started.
    #[error("cannot start the recording writer thread")]
    Spawn(#[source] io::Error),
    /// The writer thread panicked (a bug).
    #[error("the recording writer thread panicked")]
    WriterPanicked,
}

/// Counters of a [`Recorder`]. Every record passed to [`Recorder::log`] ends up in exactly one
/// of `written`, `dropped_queue_full` and `dropped_not_logging` (once the queue has drained).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RecorderStats {
    /// Records written into a file (a corrected sample counts once though it makes two
    /// messages). Records lost with an unflushed chunk on a write error move to
    /// `dropped_not_logging`.
    pub written: u64,
    /// Of `written`, records known to have reached the OS (finished chunk, flushed).
    pub flushed: u64,
    /// Records dropped by [`Recorder::log`] because the queue was full.
    pub dropped_queue_full: u64,
    /// Records dropped because no file was open (after a write error) or lost with a file.
    pub dropped_not_logging: u64,
    /// Files started.
    pub files_started: u64,
    /// Bytes in all files written.
    pub bytes_written: u64,
    /// True while a file is open for writing.
    pub logging: bool,
    /// The latest write error, with its causes.
    pub last_error: Option<String>,
    /// The file being written.
    pub current_file: Option<PathBuf>,
}

/// Anything the recorder can write a file to: a [`File`] normally, a test double in tests.
pub trait RecordingSink: Write + Seek + Send {}
impl<T: Write + Seek + Send> RecordingSink for T {}

/// Creates the sink for a new file path; must fail with [`io::ErrorKind::AlreadyExists`] when
/// the path is taken (the recorder then picks the next index).
pub type SinkOpener = Box<dyn FnMut(&Path) -> io::Result<Box<dyn RecordingSink>> + Send>;

/// The normal [`SinkOpener`]: creates the directory if needed and a new file (never
/// overwrites).
pub fn file_sink_opener() -> SinkOpener {
    Box::new(|path: &Path| {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)?;
        }
        let file = File::options().write(true).create_new(true).open(path)?;
        // An advisory lock for as long as the file is open: a repair at start-up
        // (`recover::recover_dir`) skips a file some live process is still writing. A file
        // system without locks only loses that protection.
        if let Err(e) = file.try_lock() {
            tracing::debug!(path = %path.display(), error = %e, "cannot lock the recording");
        }
        Ok(Box::new(file) as Box<dyn RecordingSink>)
    })
}

#[derive(Default)]
struct MetadataState {
    /// Every record, in first-given order, latest contents: written at the start of each file.
    all: Vec<(String, BTreeMap<String, String>)>,
    /// Updates not yet written to the current file.
    pending: Vec<(String, BTreeMap<String, String>)>,
}

#[derive(Default)]
struct Shared {
    written: AtomicU64,
    flushed: AtomicU64,
    dropped_queue_full: AtomicU64,
    dropped_not_logging: AtomicU64,
    files_started: AtomicU64,
    bytes_written: AtomicU64,
    logging: AtomicBool,
    last_error: Mutex<Option<String>>,
    current_file: Mutex<Option<PathBuf>>,
    metadata: Mutex<MetadataState>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // A panic elsewhere while holding the lock leaves plain data behind; keep using it.
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The daemon's MCAP logger: a writer thread behind a bounded queue.
///
/// Dropping it does what [`Recorder::finish`] does, ignoring errors.
pub struct Recorder {
    tx: Option<SyncSender<LogRecord>>,
    shared: Arc<Shared>,
    thread: Option<JoinHandle<Result<(), RecordingError>>>,
}

impl Recorder {
    /// Starts recording into files under `config.dir`, each beginning with `metadata` (device
    /// identity, gains, firmware, daemon config, ...).
    ///
    /// Fails only on an unusable configuration: if the first file cannot be created (directory
    /// missing and not creatable, disk full), the recorder starts without logging, reports it
    /// in [`Recorder::stats`], and retries every [`RecordingConfig::retry_interval`].
    pub fn start(
        config: RecordingConfig,
        metadata: Vec<(String, BTreeMap<String, String>)>,
    ) -> Result<Recorder, RecordingError> {
        Self::start_with_sink(config, metadata, file_sink_opener())
    }

    /// [`Recorder::start`] writing through `open` instead of the file system (for tests that
    /// need a slow or failing disk).
    pub fn start_with_sink(
        config: RecordingConfig,
        metadata: Vec<(String, BTreeMap<String, String>)>,
        open: SinkOpener,
    ) -> Result<Recorder, RecordingError> {
        config.validate()?;
        let shared = Arc::new(Shared::default());
        {
            let mut meta = lock(&shared.metadata);
            for (name, map) in metadata {
                upsert(&mut meta.all, name, map);
            }
        }
        let (tx, rx) = std::sync::mpsc::sync_channel(config.queue_capacity);
        let mut writer = WriterThread {
            config,
            shared: shared.clone(),
            open,
            file: None,
            next_index: 0,
            retry_at: None,
            noise: None,
            calibration: None,
            last_wall_ns: None,
            scratch: Vec::with_capacity(1024),
        };
        // The first file is started before returning, so stats() is meaningful at once.
        writer.start_file();
        let thread = std::thread::Builder::new()
            .name("imud-recorder".into())
            .spawn(move || writer.run(rx))
            .map_err(RecordingError::Spawn)?;
        Ok(Recorder {
            tx: Some(tx),
            shared,
            thread: Some(thread),
        })
    }

    /// Queues one record; never blocks. Returns false when it was dropped because the queue
    /// is full (counted in [`RecorderStats::dropped_queue_full`]) or the writer is gone.
    pub fn log(&self, record: LogRecord) -> bool {
        let Some(tx) = &self.tx else {
            return false;
        };
        match tx.try_send(record) {
            Ok(()) => true,
            Err(TrySendError::Full(_)) => {
                self.shared
                    .dropped_queue_full
                    .fetch_add(1, Ordering::Relaxed);
                false
            }
            Err(TrySendError::Disconnected(_)) => {
                self.shared
                    .dropped_not_logging
                    .fetch_add(1, Ordering::Relaxed);
                false
            }
        }
    }

    /// Sets metadata record `name` (replacing an earlier one of that name): written to the
    /// current file within about one flush interval, and at the start of every later file.
    /// Never blocks on the writer.
    pub fn update_metadata(&self, name: impl Into<String>, metadata: BTreeMap<String, String>) {
        let name = name.into();
        let mut meta = lock(&self.shared.metadata);
        upsert(&mut meta.all, name.clone(), metadata.clone());
        upsert(&mut meta.pending, name, metadata);
    }

    /// The counters now.
    pub fn stats(&self) -> RecorderStats {
        stats_of(&self.shared)
    }

    /// Writes everything queued, ends the current file with its summary and index, and stops
    /// the writer (what SIGTERM does). Fails if the last file could not be finished.
    pub fn finish(mut self) -> Result<RecorderStats, RecordingError> {
        self.shutdown()?;
        Ok(self.stats())
    }

    fn shutdown(&mut self) -> Result<(), RecordingError> {
        // Dropping the sender lets the thread drain the queue and then see the disconnect.
        drop(self.tx.take());
        match self.thread.take() {
            Some(thread) => thread.join().map_err(|_| RecordingError::WriterPanicked)?,
            None => Ok(()),
        }
    }
}

impl Drop for Recorder {
    fn drop(&mut self) {
        if let Err(e) = self.shutdown() {
            tracing::error!(error = %error_chain(&e), "recording not finished cleanly");
        }
    }
}

#[cfg(test)]
mod tests;
