//! rosbag2's sqlite3 storage (`.db3`, told by SQLite's magic bytes; a `.db3.zstd` compressed
//! whole is decompressed first): its CDR messages read through `imu_rec::ros2::sqlite` in
//! insertion order and decoded exactly as an MCAP's (`mcap::cdr_message`), into the shared
//! `collect.rs`.

use std::path::Path;

use imu_rec::ros2::sqlite;

use super::collect::{Collector, ReadEnd};
use super::mcap::cdr_message;
use super::{IMU_SCHEMA, ImuSeries, InputError, Source};

/// Reads the `.db3` file `path` as the file `shown` (the one the user gave: a compressed
/// file's decompressed copy is read under its name), reporting `(bytes, file size)`.
pub fn read_db3_with_progress(
    path: &Path,
    shown: &Path,
    source: Source,
    topic: Option<&str>,
    on_progress: &mut dyn FnMut(u64, u64),
) -> Result<ImuSeries, InputError> {
    let mut collect = Collector::new(source, topic);
    let report = sqlite::for_each_message_with_progress(path, shown, on_progress, |t, _, data| {
        if t.serialization_format != "cdr" {
            return Ok(());
        }
        cdr_message(&mut collect, &t.msg_type, &t.name, data)
    })?;
    for t in report.topics.values() {
        if t.msg_type == IMU_SCHEMA {
            collect.imu_topic(&t.name);
        }
    }
    let end = ReadEnd {
        stopped_early: None,
        unfinished: None,
        imud_file: None,
        calibration: None,
    };
    collect.finish(shown, None, end)
}
