//! Reading IMU time series for the offline tools: imud recordings, any MCAP carrying
//! `sensor_msgs/msg/Imu` (rosbag2 recordings from other drivers, rosbag2 directories), ROS 1
//! bags, rosbag2 sqlite3 files, and text files in any layout; one file or the several files of
//! one session.
//!
//! Everything becomes an [`ImuSeries`] in SI units with times in seconds from the first sample.
//! Formats are told by content (MCAP magic bytes, `#ROSBAG V2.0`, SQLite's magic, a zstd frame,
//! else text), never by extension. Recordings are read front to back (bounded memory besides the
//! series itself; a truncated file is read up to its last good record and says so). Invariant:
//! errors name the file, line and column.
//!
//! Files: `collect.rs` (what every recording format feeds: topic choice, raw stream, series),
//! `mcap.rs` (MCAP, and the CDR messages sqlite3 shares), `ros1.rs` (ROS 1 bags), `db3.rs`
//! (rosbag2 sqlite3), `text/` (layouts, columns, labels, two files), `units.rs` (text units, raw
//! counts with offsets), `session.rs` (several files as one, each told by content),
//! `series.rs` (what a series says about itself).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use imu_rec::McapReadError;
use imu_rec::ros1::bag::Ros1BagError;
use imu_rec::ros2::bag::BagError;
use imu_rec::ros2::sqlite::Db3Error;

mod collect;
mod db3;
mod mcap;
mod ros1;
mod series;
mod session;
mod text;
mod units;

pub use db3::read_db3_with_progress;
pub use mcap::{IMU_SCHEMA, read_mcap, read_mcap_with_progress};
pub use ros1::read_ros1_bag_with_progress;
pub use session::{InputOptions, SessionGap, group_sessions, read_input, session_files};
pub use text::{ColumnRef, Columns, CsvOptions, read_csv, read_text};
pub use units::{AccelUnit, CountsAxes, GyroUnit};

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
    /// A text line is malformed (the message names the column).
    #[error("{path}:{line}: {message}")]
    Csv {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// Several IMU topics and none chosen. (The message names the type without its ROS 2
    /// `msg/` part: the file may be a ROS 1 bag, where it is `sensor_msgs/Imu`.)
    #[error(
        "{path}: several IMU topics (sensor_msgs Imu): {}; choose one with --topic",
        topic_list(topics)
    )]
    AmbiguousTopic {
        /// The file.
        path: PathBuf,
        /// The topics and their message counts.
        topics: Vec<(String, u64)>,
    },
    /// The topic asked for carries no IMU data.
    #[error(
        "{path}: no IMU topic (sensor_msgs Imu) `{topic}`; its IMU topics: {}",
        topic_list(topics)
    )]
    NoSuchTopic {
        /// The file.
        path: PathBuf,
        /// The topic asked for.
        topic: String,
        /// The topics there are and their message counts.
        topics: Vec<(String, u64)>,
    },
    /// A rosbag2 directory could not be read.
    #[error(transparent)]
    Bag(#[from] BagError),
    /// A ROS 1 bag could not be read.
    #[error(transparent)]
    Ros1(#[from] Ros1BagError),
    /// A rosbag2 sqlite3 file could not be read.
    #[error(transparent)]
    Db3(#[from] Db3Error),
    /// The files given are not one session.
    #[error("{message}")]
    Session {
        /// What is wrong and what to do.
        message: String,
    },
}

fn topic_list(topics: &[(String, u64)]) -> String {
    if topics.is_empty() {
        return "none".into();
    }
    topics
        .iter()
        .map(|(t, n)| format!("{t} ({n} messages)"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The label of every sample of a labelled session (a `part` or `label` column).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Labels {
    /// The labels as written, in order of first appearance.
    pub names: Vec<String>,
    /// Per sample, the index of its label in `names`.
    pub per_sample: Vec<u32>,
}

impl Labels {
    /// Appends a sample labelled `name`.
    pub fn push(&mut self, name: &str) {
        let i = match self.names.iter().rposition(|n| n == name) {
            Some(i) => i,
            None => {
                self.names.push(name.to_string());
                self.names.len() - 1
            }
        };
        self.per_sample.push(i as u32);
    }

    /// The label of sample `i`.
    pub fn of(&self, i: usize) -> &str {
        &self.names[self.per_sample[i] as usize]
    }
}

/// Where a series came from: its files in time order, the IMU topic read, the gaps between files.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct InputInfo {
    /// The files read, in time order (a gyro file after its accelerometer file).
    pub files: Vec<PathBuf>,
    /// The topic read (`/imu/raw` for imud's raw stream); `None` for text.
    pub topic: Option<String>,
    /// Time gaps between consecutive files.
    pub gaps: Vec<SessionGap>,
    /// Samples skipped because a value was not finite (NaN or infinite: what a unit sends for
    /// a reading it does not have, or a writer for a failed one). They leave a time gap, so
    /// they count among the series' missing samples too.
    pub non_finite_samples: u64,
    /// The file read without its footer, if one was (the series' `unfinished` is its report).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unfinished_file: Option<PathBuf>,
    /// Which imud session a single imud recording file belongs to (its metadata), for telling
    /// the files of one session from separate recordings ([`group_sessions`]).
    #[serde(skip)]
    pub imud_file: Option<ImudFile>,
    /// The device an imud recording says it recorded: its whole `imud.device` metadata (model,
    /// serial number, firmware, gains...; the latest file's of a session); empty for other
    /// inputs. (Said at the top of a series' description, not under `input`.)
    #[serde(skip)]
    pub device: BTreeMap<String, String>,
    /// The calibration an imud recording says was in force (`imud.calibration` metadata; the
    /// one put in force last, in the latest file holding one); `None` when none was.
    #[serde(skip)]
    pub calibration: Option<CalibrationInForce>,
}

/// An imud recording file's place in its session, from its metadata: the recorder's file
/// prefix and index (`imud.recording`: 0 at each start of imud, one more at each rotation).
/// Files of one session also record the same device ([`InputInfo::device`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ImudFile {
    /// `prefix` of `imud.recording`.
    pub prefix: String,
    /// `file-index` of `imud.recording`.
    pub file_index: u32,
}

/// The calibration in force in an imud recording: its `imud.calibration` metadata record,
/// which the recorder rewrites whenever a calibration is put in force and repeats in every
/// file started after that.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct CalibrationInForce {
    /// The calibration's content id (`imu_model::Calibration::content_id`).
    pub id: String,
    /// The calibration file's text.
    pub toml: String,
    /// The recording file it was read from.
    pub file: PathBuf,
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
    /// Absolute time of `t_s = 0`: Unix epoch ns for MCAP; for text, the time column's own
    /// origin when it is not negative (0 if unknown).
    pub t0_ns: u64,
    /// Where the data came from (file and topic), for reports.
    pub origin: String,
    /// `Some(reason)` if the input ended early (truncated recording).
    pub stopped_early: Option<String>,
    /// The same as data for an MCAP input: footer missing, messages and last log time read.
    pub unfinished: Option<imu_rec::Unfinished>,
    /// The label of each sample when the input has a `part`/`label` column.
    pub labels: Option<Labels>,
    /// Files, topic and gaps.
    pub input: InputInfo,
}

/// Reads any supported input, told by content: MCAP (magic bytes), a ROS 1 bag, a rosbag2
/// sqlite3 file, a rosbag2 or imud session directory, or text.
pub fn read_any(path: &Path, source: Source, csv: &CsvOptions) -> Result<ImuSeries, InputError> {
    read_any_with_progress(path, source, csv, &mut |_, _| {})
}

/// [`read_any`], reporting `(bytes read, file size)` as the file is read: monotone, from
/// `(0, size)` to `(size, size)` when the whole file was read (a text file is read at once).
/// This is what the clients' progress bars (module `progress`, feature `progress`) follow.
pub fn read_any_with_progress(
    path: &Path,
    source: Source,
    csv: &CsvOptions,
    on_progress: &mut dyn FnMut(u64, u64),
) -> Result<ImuSeries, InputError> {
    let options = InputOptions {
        source,
        csv: csv.clone(),
        ..InputOptions::default()
    };
    read_input(&[path.to_path_buf()], &options, on_progress)
}
