//! The daemon's MCAP log: every frame, sample, temperature, status and calibration, written by a
//! thread behind a bounded queue, in ROS 2 form (profile `ros2`, `ros2msg` schemas, CDR
//! messages), with size/time rotation, crash-safe periodic flushing and recovery from write
//! errors; and the reader for those files.
//!
//! Topics (see the `*_TOPIC` constants): `/imu/data` (`sensor_msgs/msg/Imu`), `/imu/mag`
//! (`sensor_msgs/msg/MagneticField`, tesla), `/imu/temperature` (`sensor_msgs/msg/Temperature`),
//! `/imu/raw` (`imud_msgs/msg/RawSample`), `/imu/raw_frame` (`imud_msgs/msg/RawFrame`: every
//! byte received, accepted or rejected), `/imud/status` (`imud_msgs/msg/DaemonStatus`) and
//! `/imud/calibration` (`imud_msgs/msg/Calibration`). Message log times and header stamps are
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
    self, CalibrationMsg, DaemonStatusMsg, Header, Imu, MagneticField, MsgDefinition, Quaternion,
    RawFrameMsg, RawSampleMsg, RosMessage, Temperature, Time,
};
use crate::sample::{CorrectedSample, DaemonStatus, RawSample};

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
/// Daemon health counters as `imud_msgs/msg/DaemonStatus`.
pub const STATUS_TOPIC: &str = "/imud/status";
/// Each calibration put in force, as `imud_msgs/msg/Calibration`.
pub const CALIBRATION_TOPIC: &str = "/imud/calibration";

/// Metadata record the recorder adds to every file: `file-index`, `prefix`, `started-utc`,
/// `frame-id`, `library`.
pub const RECORDING_METADATA: &str = "imud.recording";
/// Metadata record holding the calibration in force (`id`, `toml`), repeated in every file
/// started after it was put in force.
pub const CALIBRATION_METADATA: &str = "imud.calibration";

/// Tesla per gauss.
pub const TESLA_PER_GAUSS: f64 = 1e-4;

/// Every channel of a recording: topic and message type, in channel-id order.
pub const CHANNELS: [(&str, &MsgDefinition); 7] = [
    (IMU_TOPIC, &ros2::IMU_DEF),
    (MAG_TOPIC, &ros2::MAGNETIC_FIELD_DEF),
    (TEMPERATURE_TOPIC, &ros2::TEMPERATURE_DEF),
    (RAW_TOPIC, &ros2::RAW_SAMPLE_DEF),
    (RAW_FRAME_TOPIC, &ros2::RAW_FRAME_DEF),
    (STATUS_TOPIC, &ros2::DAEMON_STATUS_DEF),
    (CALIBRATION_TOPIC, &ros2::CALIBRATION_DEF),
];
const CH_IMU: usize = 0;
const CH_MAG: usize = 1;
const CH_TEMPERATURE: usize = 2;
const CH_RAW: usize = 3;
const CH_FRAME: usize = 4;
const CH_STATUS: usize = 5;
const CH_CALIBRATION: usize = 6;

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

/// One thing to log. Times are host clock nanoseconds (`_wall_ns`: Unix epoch).
#[derive(Debug, Clone, PartialEq)]
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
        bytes: Vec<u8>,
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
    /// Records queued for the writer thread; beyond it [`Recorder::log`] drops and counts.
    pub queue_capacity: usize,
    /// The longest a logged record waits before it reaches the OS; at most 1 s, so a killed
    /// daemon loses at most that much.
    pub flush_interval: Duration,
    /// After a write error, how often to try starting a new file.
    pub retry_interval: Duration,
    /// `header.frame_id` of the sensor messages.
    pub frame_id: String,
    /// zstd level of the chunks (0: zstd's default, 3).
    pub compression_level: u32,
}

impl Default for RecordingConfig {
    fn default() -> Self {
        Self {
            dir: PathBuf::from("imud-logs"),
            prefix: "imud".into(),
            rotate_size_bytes: 512 * 1024 * 1024,
            rotate_interval_s: 3600.0,
            queue_capacity: 65_536,
            flush_interval: Duration::from_millis(500),
            retry_interval: Duration::from_secs(5),
            frame_id: "imu_link".into(),
            compression_level: 0,
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

fn stats_of(shared: &Shared) -> RecorderStats {
    let load = |a: &AtomicU64| a.load(Ordering::Relaxed);
    RecorderStats {
        written: load(&shared.written),
        flushed: load(&shared.flushed),
        dropped_queue_full: load(&shared.dropped_queue_full),
        dropped_not_logging: load(&shared.dropped_not_logging),
        files_started: load(&shared.files_started),
        bytes_written: load(&shared.bytes_written),
        logging: shared.logging.load(Ordering::Relaxed),
        last_error: lock(&shared.last_error).clone(),
        current_file: lock(&shared.current_file).clone(),
    }
}

fn upsert(
    list: &mut Vec<(String, BTreeMap<String, String>)>,
    name: String,
    map: BTreeMap<String, String>,
) {
    match list.iter_mut().find(|(n, _)| *n == name) {
        Some(entry) => entry.1 = map,
        None => list.push((name, map)),
    }
}

/// An error and its causes on one line (`a: b: c`).
fn error_chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        s.push_str(": ");
        s.push_str(&c.to_string());
        cause = c.source();
    }
    s
}

/// Counts what reaches the sink: the file size is the furthest byte written.
struct CountingSink {
    inner: Box<dyn RecordingSink>,
    pos: u64,
    size: u64,
    shared: Arc<Shared>,
    file_size: Arc<AtomicU64>,
}

impl Write for CountingSink {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.pos += n as u64;
        if self.pos > self.size {
            self.shared
                .bytes_written
                .fetch_add(self.pos - self.size, Ordering::Relaxed);
            self.size = self.pos;
            self.file_size.store(self.size, Ordering::Relaxed);
        }
        Ok(n)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}

impl Seek for CountingSink {
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        self.pos = self.inner.seek(pos)?;
        Ok(self.pos)
    }
}

type McapWriter = mcap::Writer<BufWriter<CountingSink>>;

/// The file being written.
struct OpenFile {
    path: PathBuf,
    mcap: McapWriter,
    channel_ids: [u16; CHANNELS.len()],
    sequences: [u32; CHANNELS.len()],
    file_size: Arc<AtomicU64>,
    opened: Instant,
    records: u64,
    /// Records written since the last flush.
    unflushed_records: u64,
    /// Uncompressed bytes written since the last flush (the open chunk, for size rotation).
    unflushed_bytes: u64,
    /// When the oldest unflushed write happened.
    dirty_since: Option<Instant>,
}

impl OpenFile {
    fn mcap_err(&self, source: mcap::McapError) -> RecordingError {
        RecordingError::Write {
            path: self.path.clone(),
            source,
        }
    }

    fn mark_dirty(&mut self) {
        self.dirty_since.get_or_insert_with(Instant::now);
    }

    fn write_msg<M: RosMessage>(
        &mut self,
        channel: usize,
        log_time_ns: u64,
        msg: &M,
        scratch: &mut Vec<u8>,
    ) -> Result<(), RecordingError> {
        scratch.clear();
        msg.encode_into(scratch);
        self.sequences[channel] = self.sequences[channel].wrapping_add(1);
        let header = MessageHeader {
            channel_id: self.channel_ids[channel],
            sequence: self.sequences[channel],
            log_time: log_time_ns,
            publish_time: log_time_ns,
        };
        self.mark_dirty();
        // Message record overhead: opcode, length, header fields.
        self.unflushed_bytes += scratch.len() as u64 + 31;
        self.mcap
            .write_to_known_channel(&header, scratch)
            .map_err(|e| self.mcap_err(e))
    }

    fn write_metadata(
        &mut self,
        name: &str,
        map: &BTreeMap<String, String>,
    ) -> Result<(), RecordingError> {
        self.mark_dirty();
        self.mcap
            .write_metadata(&mcap::records::Metadata {
                name: name.to_string(),
                metadata: map.clone(),
            })
            .map_err(|e| self.mcap_err(e))
    }

    fn flush(&mut self) -> Result<(), RecordingError> {
        self.mcap.flush().map_err(|e| self.mcap_err(e))?;
        self.dirty_since = None;
        self.unflushed_bytes = 0;
        Ok(())
    }

    fn size_estimate(&self) -> u64 {
        self.file_size.load(Ordering::Relaxed) + self.unflushed_bytes
    }

    /// Writes the summary and index and flushes the file to the OS.
    fn finish(mut self) -> Result<(), RecordingError> {
        self.mcap.finish().map_err(|e| self.mcap_err(e))?;
        let path = self.path.clone();
        let mut sink = self.mcap.into_inner();
        sink.flush()
            .map_err(|source| RecordingError::Close { path, source })
    }
}

fn header(t_ns: u64, frame_id: &str) -> Header {
    Header {
        stamp: Time::from_ns(t_ns),
        frame_id: frame_id.to_string(),
    }
}

/// The `/imu/data` message of a corrected sample: no orientation estimate (covariance element
/// 0 = -1, identity quaternion), rates and accelerations with diagonal covariances from `noise`
/// (all zeros, "unknown", without).
pub fn imu_message(
    sample: &CorrectedSample,
    frame_id: &str,
    noise: Option<&ImuNoiseVariances>,
) -> Imu {
    let diag = |v: Option<[f64; 3]>| v.map(ros2::diagonal_covariance).unwrap_or([0.0; 9]);
    Imu {
        header: header(sample.t_wall_ns, frame_id),
        orientation: Quaternion::default(),
        orientation_covariance: ros2::NOT_PROVIDED_COVARIANCE,
        angular_velocity: sample.gyro_rad_s.into(),
        angular_velocity_covariance: diag(noise.map(|n| n.gyro_var_rad2_s2)),
        linear_acceleration: sample.accel_m_s2.into(),
        linear_acceleration_covariance: diag(noise.map(|n| n.accel_var_m2_s4)),
    }
}

/// The `/imu/mag` message of a corrected sample (gauss converted to tesla).
pub fn magnetic_field_message(
    sample: &CorrectedSample,
    frame_id: &str,
    noise: Option<&ImuNoiseVariances>,
) -> MagneticField {
    MagneticField {
        header: header(sample.t_wall_ns, frame_id),
        magnetic_field: sample.mag_gauss.map(|g| g * TESLA_PER_GAUSS).into(),
        magnetic_field_covariance: noise
            .map(|n| ros2::diagonal_covariance(n.mag_var_t2))
            .unwrap_or([0.0; 9]),
    }
}

/// The writer thread's state.
struct WriterThread {
    config: RecordingConfig,
    shared: Arc<Shared>,
    open: SinkOpener,
    file: Option<OpenFile>,
    /// Index of the next file name.
    next_index: u32,
    /// When not logging: when to try a new file.
    retry_at: Option<Instant>,
    noise: Option<ImuNoiseVariances>,
    /// The calibration in force, as metadata for every new file.
    calibration: Option<BTreeMap<String, String>>,
    scratch: Vec<u8>,
}

impl WriterThread {
    fn run(mut self, rx: Receiver<LogRecord>) -> Result<(), RecordingError> {
        loop {
            match rx.recv_timeout(self.next_wakeup()) {
                Ok(record) => self.handle(record),
                Err(RecvTimeoutError::Timeout) => {}
                // Every queued record has been received: the recorder is finishing.
                Err(RecvTimeoutError::Disconnected) => break,
            }
            self.housekeeping();
        }
        self.write_pending_metadata();
        let result = match self.file.take() {
            Some(file) => {
                let path = file.path.clone();
                let unflushed = file.unflushed_records;
                let result = file.finish();
                match &result {
                    Ok(()) => {
                        self.shared.flushed.fetch_add(unflushed, Ordering::Relaxed);
                        tracing::info!(path = %path.display(), "recording finished");
                    }
                    Err(e) => {
                        self.count_lost(unflushed);
                        self.report_error(e);
                    }
                }
                result
            }
            None => Ok(()),
        };
        self.shared.logging.store(false, Ordering::Relaxed);
        *lock(&self.shared.current_file) = None;
        result
    }

    fn next_wakeup(&self) -> Duration {
        let now = Instant::now();
        let mut wait = self.config.flush_interval;
        if let Some(since) = self.file.as_ref().and_then(|f| f.dirty_since) {
            wait = wait.min((since + self.config.flush_interval).saturating_duration_since(now));
        }
        if let Some(at) = self.retry_at {
            wait = wait.min(at.saturating_duration_since(now));
        }
        wait
    }

    fn housekeeping(&mut self) {
        self.write_pending_metadata();
        let now = Instant::now();
        if let Some(file) = &mut self.file {
            if file
                .dirty_since
                .is_some_and(|since| now.duration_since(since) >= self.config.flush_interval)
            {
                let records = file.unflushed_records;
                match file.flush() {
                    Ok(()) => {
                        file.unflushed_records = 0;
                        self.shared.flushed.fetch_add(records, Ordering::Relaxed);
                    }
                    Err(e) => self.fail(e),
                }
            }
        } else if self.retry_at.is_some_and(|at| now >= at) {
            self.start_file();
        }
    }

    fn write_pending_metadata(&mut self) {
        let pending = std::mem::take(&mut lock(&self.shared.metadata).pending);
        let Some(file) = &mut self.file else {
            // The next file starts with the full, updated set.
            return;
        };
        for (name, map) in &pending {
            if let Err(e) = file.write_metadata(name, map) {
                self.fail(e);
                return;
            }
        }
    }

    fn handle(&mut self, record: LogRecord) {
        if let LogRecord::Calibration {
            id, toml, noise, ..
        } = &record
        {
            self.noise = *noise;
            let meta = BTreeMap::from([
                ("id".to_string(), id.clone()),
                ("toml".to_string(), toml.clone()),
            ]);
            if let Some(file) = &mut self.file
                && let Err(e) = file.write_metadata(CALIBRATION_METADATA, &meta)
            {
                self.fail(e);
            }
            self.calibration = Some(meta);
        }
        if self.file.as_ref().is_some_and(|f| self.rotation_due(f)) {
            self.rotate();
        }
        let Some(file) = &mut self.file else {
            self.shared
                .dropped_not_logging
                .fetch_add(1, Ordering::Relaxed);
            return;
        };
        match write_record(
            file,
            record,
            &self.config.frame_id,
            self.noise.as_ref(),
            &mut self.scratch,
        ) {
            Ok(()) => {
                file.records += 1;
                file.unflushed_records += 1;
                self.shared.written.fetch_add(1, Ordering::Relaxed);
            }
            Err(e) => {
                self.shared
                    .dropped_not_logging
                    .fetch_add(1, Ordering::Relaxed);
                self.fail(e);
            }
        }
    }

    fn rotation_due(&self, file: &OpenFile) -> bool {
        if file.records == 0 {
            return false;
        }
        let by_size = self.config.rotate_size_bytes > 0
            && file.size_estimate() >= self.config.rotate_size_bytes;
        let by_time = self.config.rotate_interval_s > 0.0
            && file.opened.elapsed().as_secs_f64() >= self.config.rotate_interval_s;
        by_size || by_time
    }

    fn rotate(&mut self) {
        if let Some(file) = self.file.take() {
            let unflushed = file.unflushed_records;
            match file.finish() {
                Ok(()) => {
                    self.shared.flushed.fetch_add(unflushed, Ordering::Relaxed);
                }
                Err(e) => {
                    self.count_lost(unflushed);
                    self.enter_not_logging(&e);
                    return;
                }
            }
        }
        self.start_file();
    }

    /// Records written since the last flush are gone with a failed file.
    fn count_lost(&self, records: u64) {
        self.shared.written.fetch_sub(records, Ordering::Relaxed);
        self.shared
            .dropped_not_logging
            .fetch_add(records, Ordering::Relaxed);
    }

    fn fail(&mut self, e: RecordingError) {
        if let Some(file) = self.file.take() {
            self.count_lost(file.unflushed_records);
            // Dropping the writer may try to write the summary; it fails quietly on a dead disk.
            drop(file);
        }
        self.enter_not_logging(&e);
    }

    fn report_error(&self, e: &RecordingError) {
        let message = error_chain(e);
        tracing::error!(error = %message, "MCAP logging stopped");
        *lock(&self.shared.last_error) = Some(message);
    }

    fn enter_not_logging(&mut self, e: &RecordingError) {
        self.report_error(e);
        self.shared.logging.store(false, Ordering::Relaxed);
        *lock(&self.shared.current_file) = None;
        self.retry_at = Some(Instant::now() + self.config.retry_interval);
        tracing::warn!(
            retry_interval = ?self.config.retry_interval,
            "records are dropped until a new recording file can be started"
        );
    }

    /// Starts the next file; on failure, stays (or goes) not logging and schedules a retry.
    fn start_file(&mut self) {
        let was_retrying = self.retry_at.is_some();
        match self.open_file() {
            Ok(file) => {
                tracing::info!(path = %file.path.display(), "recording to a new file");
                if was_retrying {
                    tracing::info!("MCAP logging resumed");
                }
                *lock(&self.shared.current_file) = Some(file.path.clone());
                self.shared.files_started.fetch_add(1, Ordering::Relaxed);
                self.shared.logging.store(true, Ordering::Relaxed);
                self.retry_at = None;
                self.file = Some(file);
            }
            Err(e) if was_retrying => {
                // Still failing: say so once per attempt, quietly, with the same detail.
                let message = error_chain(&e);
                tracing::debug!(error = %message, "recording retry failed");
                *lock(&self.shared.last_error) = Some(message);
                self.retry_at = Some(Instant::now() + self.config.retry_interval);
            }
            Err(e) => self.enter_not_logging(&e),
        }
    }

    fn open_file(&mut self) -> Result<OpenFile, RecordingError> {
        let started = SystemTime::now();
        let stamp = utc_stamp(started);
        let mut index = self.next_index;
        let (path, sink) = loop {
            let path = self
                .config
                .dir
                .join(format!("{}-{stamp}-{index:04}.mcap", self.config.prefix));
            match (self.open)(&path) {
                Ok(sink) => break (path, sink),
                // The name is taken (a restart within the same second): take the next index.
                // AlreadyExists also comes from a directory path that is a file, so check.
                Err(e)
                    if e.kind() == io::ErrorKind::AlreadyExists
                        && std::fs::symlink_metadata(&path).is_ok()
                        && index < self.next_index.saturating_add(10_000) =>
                {
                    index += 1;
                }
                Err(source) => return Err(RecordingError::Create { path, source }),
            }
        };
        let file_size = Arc::new(AtomicU64::new(0));
        let counting = CountingSink {
            inner: sink,
            pos: 0,
            size: 0,
            shared: self.shared.clone(),
            file_size: file_size.clone(),
        };
        match self.begin_file(&path, counting, file_size, index, started) {
            Ok(file) => {
                self.next_index = index.saturating_add(1);
                Ok(file)
            }
            Err(e) => {
                // A file that never got its schemas and metadata is only clutter (and on a full
                // disk, retries would leave one every few seconds).
                if let Err(rm) = std::fs::remove_file(&path)
                    && rm.kind() != io::ErrorKind::NotFound
                {
                    tracing::warn!(
                        path = %path.display(),
                        error = %rm,
                        "cannot remove a failed recording file"
                    );
                }
                Err(e)
            }
        }
    }

    fn begin_file(
        &mut self,
        path: &Path,
        sink: CountingSink,
        file_size: Arc<AtomicU64>,
        index: u32,
        started: SystemTime,
    ) -> Result<OpenFile, RecordingError> {
        let mcap_err = |source| RecordingError::Write {
            path: path.to_path_buf(),
            source,
        };
        let options = mcap::WriteOptions::new()
            .profile("ros2")
            .library(concat!("imu-bus ", env!("CARGO_PKG_VERSION")))
            .compression(Some(mcap::Compression::Zstd))
            .compression_level(self.config.compression_level)
            // One core is plenty for a few hundred messages a second; leave the rest to the
            // daemon and its subscribers.
            .compression_threads(0)
            .chunk_size(Some(1024 * 1024));
        let mut mcap = options
            .create(BufWriter::with_capacity(64 * 1024, sink))
            .map_err(mcap_err)?;
        let mut channel_ids = [0u16; CHANNELS.len()];
        let no_meta = BTreeMap::new();
        for (id, (topic, def)) in channel_ids.iter_mut().zip(CHANNELS) {
            let schema = mcap
                .add_schema(def.type_name, "ros2msg", def.schema_text().as_bytes())
                .map_err(mcap_err)?;
            *id = mcap
                .add_channel(schema, topic, "cdr", &no_meta)
                .map_err(mcap_err)?;
        }
        let mut file = OpenFile {
            path: path.to_path_buf(),
            mcap,
            channel_ids,
            sequences: [0; CHANNELS.len()],
            file_size,
            opened: Instant::now(),
            records: 0,
            unflushed_records: 0,
            unflushed_bytes: 0,
            dirty_since: None,
        };
        let all = {
            let mut meta = lock(&self.shared.metadata);
            meta.pending.clear();
            meta.all.clone()
        };
        for (name, map) in &all {
            file.write_metadata(name, map)?;
        }
        let recording = BTreeMap::from([
            ("file-index".to_string(), index.to_string()),
            ("prefix".to_string(), self.config.prefix.clone()),
            ("started-utc".to_string(), utc_stamp(started)),
            ("frame-id".to_string(), self.config.frame_id.clone()),
            (
                "library".to_string(),
                concat!("imu-bus ", env!("CARGO_PKG_VERSION")).to_string(),
            ),
        ]);
        file.write_metadata(RECORDING_METADATA, &recording)?;
        if let Some(calibration) = &self.calibration {
            file.write_metadata(CALIBRATION_METADATA, calibration)?;
        }
        // A new file is readable (schemas, channels, metadata) at once.
        file.flush()?;
        Ok(file)
    }
}

fn write_record(
    file: &mut OpenFile,
    record: LogRecord,
    frame_id: &str,
    noise: Option<&ImuNoiseVariances>,
    scratch: &mut Vec<u8>,
) -> Result<(), RecordingError> {
    match record {
        LogRecord::RawFrame {
            t_host_wall_ns,
            t_host_monotonic_ns,
            stream_offset,
            accepted,
            reject_reason,
            bytes,
        } => {
            let msg = RawFrameMsg {
                header: header(t_host_wall_ns, frame_id),
                t_host_monotonic_ns,
                stream_offset,
                accepted,
                reject_reason: reject_reason.map(Cow::into_owned).unwrap_or_default(),
                data: bytes,
            };
            file.write_msg(CH_FRAME, t_host_wall_ns, &msg, scratch)
        }
        LogRecord::Raw(sample) => {
            let msg = RawSampleMsg {
                header: header(sample.t_host_wall_ns, frame_id),
                sample,
            };
            file.write_msg(CH_RAW, sample.t_host_wall_ns, &msg, scratch)
        }
        LogRecord::Corrected(sample) => {
            let imu = imu_message(&sample, frame_id, noise);
            file.write_msg(CH_IMU, sample.t_wall_ns, &imu, scratch)?;
            let mag = magnetic_field_message(&sample, frame_id, noise);
            file.write_msg(CH_MAG, sample.t_wall_ns, &mag, scratch)
        }
        LogRecord::Temperature { t_wall_ns, temp_c } => {
            let msg = Temperature {
                header: header(t_wall_ns, frame_id),
                temperature: temp_c,
                variance: 0.0,
            };
            file.write_msg(CH_TEMPERATURE, t_wall_ns, &msg, scratch)
        }
        LogRecord::Status { t_wall_ns, status } => {
            let msg = DaemonStatusMsg {
                header: header(t_wall_ns, ""),
                status,
            };
            file.write_msg(CH_STATUS, t_wall_ns, &msg, scratch)
        }
        LogRecord::Calibration {
            t_wall_ns,
            id,
            toml,
            ..
        } => {
            let msg = CalibrationMsg {
                header: header(t_wall_ns, ""),
                id,
                toml,
            };
            file.write_msg(CH_CALIBRATION, t_wall_ns, &msg, scratch)
        }
    }
}

/// `YYYYMMDDTHHMMSSZ` of a wall-clock time, UTC.
pub fn utc_stamp(t: SystemTime) -> String {
    let secs = t
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0);
    let (y, m, d) = civil_from_days((secs / 86_400) as i64);
    let s = secs % 86_400;
    format!(
        "{y:04}{m:02}{d:02}T{:02}{:02}{:02}Z",
        s / 3600,
        s % 3600 / 60,
        s % 60
    )
}

/// Proleptic Gregorian date of a day count since 1970-01-01 (H. Hinnant's algorithm).
fn civil_from_days(days: i64) -> (i64, u32, u32) {
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
}

fn decode<M: RosMessage>(channel: &mcap_read::ChannelInfo, data: &[u8]) -> Result<M, String> {
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
    })?;
    rec.metadata = report.metadata;
    rec.stopped_early = report.stopped_early;
    Ok(rec)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_recorder_can_be_shared_between_threads() {
        fn send_sync<T: Send + Sync>() {}
        send_sync::<Recorder>();
        send_sync::<LogRecord>();
    }

    #[test]
    fn utc_stamps() {
        let at = |s: u64| utc_stamp(UNIX_EPOCH + Duration::from_secs(s));
        assert_eq!(at(0), "19700101T000000Z");
        assert_eq!(at(951_782_400), "20000229T000000Z");
        assert_eq!(at(1_700_000_000), "20231114T221320Z");
        assert_eq!(at(4_102_444_799), "20991231T235959Z");
    }

    #[test]
    fn bad_configs_are_refused_with_the_reason() {
        let cases = [
            RecordingConfig {
                flush_interval: Duration::from_secs(2),
                ..RecordingConfig::default()
            },
            RecordingConfig {
                queue_capacity: 0,
                ..RecordingConfig::default()
            },
            RecordingConfig {
                rotate_interval_s: f64::NAN,
                ..RecordingConfig::default()
            },
            RecordingConfig {
                prefix: "a/b".into(),
                ..RecordingConfig::default()
            },
        ];
        for config in cases {
            let err = Recorder::start(config.clone(), Vec::new())
                .err()
                .unwrap_or_else(|| panic!("{config:?} accepted"));
            assert!(err.to_string().starts_with("recording config: "), "{err}");
        }
        assert!(RecordingConfig::default().validate().is_ok());
    }

    #[test]
    fn imu_and_mag_messages_follow_the_conventions() {
        let s = CorrectedSample {
            t_wall_ns: 1_700_000_000_000_000_001,
            accel_m_s2: [0.1, 0.2, -9.8],
            gyro_rad_s: [0.01, 0.02, 0.03],
            mag_gauss: [0.2, -0.4, 0.5],
            ..CorrectedSample::default()
        };
        let imu = imu_message(&s, "f", None);
        assert_eq!(imu.orientation_covariance[0], -1.0);
        assert_eq!(imu.orientation, Quaternion::default());
        assert_eq!(imu.angular_velocity_covariance, [0.0; 9]);
        assert_eq!(imu.header.stamp.to_ns(), s.t_wall_ns);
        let noise = ImuNoiseVariances {
            accel_var_m2_s4: [1.0, 2.0, 3.0],
            gyro_var_rad2_s2: [4.0, 5.0, 6.0],
            mag_var_t2: [7.0, 8.0, 9.0],
        };
        let imu = imu_message(&s, "f", Some(&noise));
        assert_eq!(
            imu.linear_acceleration_covariance,
            [1.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 3.0]
        );
        assert_eq!(imu.angular_velocity_covariance[8], 6.0);
        let mag = magnetic_field_message(&s, "f", Some(&noise));
        assert_eq!(
            <[f64; 3]>::from(mag.magnetic_field),
            [0.2 * 1e-4, -0.4 * 1e-4, 0.5 * 1e-4]
        );
        assert_eq!(mag.magnetic_field_covariance[4], 8.0);
    }
}
