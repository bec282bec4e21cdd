//! Recordings of several files read as one: imud's rotated files of a session (given one by one
//! or as their directory), a rosbag2 directory (the files its `metadata.yaml` lists), or any
//! single file. Each file's format is told by content (MCAP magic bytes, `#ROSBAG V2.0`,
//! SQLite's magic, a zstd frame holding an SQLite file, else text); the parts are put in time
//! order, their times joined on one base, and the gaps between them reported.

use std::io::Read;
use std::path::{Path, PathBuf};

use imu_rec::McapReadError;
use imu_rec::mcap_read::has_mcap_magic;
use imu_rec::ros1::bag::has_rosbag_magic;
use imu_rec::ros2::bag;
use imu_rec::ros2::sqlite::{ZSTD_MAGIC, has_sqlite_magic, starts_with};

use super::{
    Columns, CsvOptions, ImuSeries, InputError, InputInfo, Labels, Source, read_db3_with_progress,
    read_mcap_with_progress, read_ros1_bag_with_progress, read_text,
};

/// How to read a recording of one or more files.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct InputOptions {
    /// Which stream of an imud recording.
    pub source: Source,
    /// Units of text files, and the gyro's own file.
    pub csv: CsvOptions,
    /// Columns of text files.
    pub columns: Columns,
    /// The `sensor_msgs/msg/Imu` topic to read when a file has several.
    pub topic: Option<String>,
}

/// Time between two consecutive files of a session beyond one sample interval: samples that
/// no file holds.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SessionGap {
    /// The file before the gap.
    pub after: PathBuf,
    /// The file after it.
    pub before: PathBuf,
    /// Where the gap starts, s on the session's time base.
    pub at_s: f64,
    /// From the last sample before to the first after, s.
    pub gap_s: f64,
    /// Samples missing at the session's median interval.
    pub missing_samples: u64,
}

/// A gap is a step between files longer than this many median sample intervals.
const GAP_INTERVALS: f64 = 1.5;

/// The files `paths` stand for, in the order given: a rosbag2 directory is the files its
/// metadata lists, any other directory its MCAP files (told by their magic bytes) by name, a
/// file itself.
pub fn session_files(paths: &[PathBuf]) -> Result<Vec<PathBuf>, InputError> {
    let mut out = Vec::new();
    for p in paths {
        if bag::is_bag_dir(p) {
            out.extend(bag::bag_files(p)?.files);
        } else if p.is_dir() {
            out.extend(mcap_files_in(p)?);
        } else {
            out.push(p.clone());
        }
    }
    Ok(out)
}

fn mcap_files_in(dir: &Path) -> Result<Vec<PathBuf>, InputError> {
    let io = |source| InputError::Io {
        path: dir.to_path_buf(),
        source,
    };
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io)? {
        let p = entry.map_err(io)?.path();
        if p.is_file() && has_mcap_magic(&p).unwrap_or(false) {
            files.push(p);
        }
    }
    files.sort();
    if files.is_empty() {
        return Err(InputError::NoData {
            path: dir.to_path_buf(),
            message: "a directory without MCAP files or a rosbag2 metadata.yaml: give the \
                      recording's files"
                .into(),
        });
    }
    Ok(files)
}

/// Reads the recording `paths` stand for ([`session_files`]) as one series, reporting
/// `(bytes read, total bytes)` over all its files.
pub fn read_input(
    paths: &[PathBuf],
    options: &InputOptions,
    on_progress: &mut dyn FnMut(u64, u64),
) -> Result<ImuSeries, InputError> {
    let files = session_files(paths)?;
    if files.len() > 1 && options.csv.gyro_file.is_some() {
        return Err(InputError::Session {
            message: format!(
                "a gyro file (--gyro-csv) goes with one accelerometer file, got {} files",
                files.len()
            ),
        });
    }
    let sizes: Vec<u64> = files
        .iter()
        .map(|f| std::fs::metadata(f).map_or(0, |m| m.len()))
        .collect();
    let total: u64 = sizes.iter().sum();
    let mut parts = Vec::with_capacity(files.len());
    let mut done = 0;
    for (f, size) in files.iter().zip(&sizes) {
        parts.push(read_file(f, options, &mut |d, _| {
            on_progress(done + d, total)
        })?);
        done += size;
    }
    if parts.len() == 1 {
        return Ok(parts.pop().expect("one part"));
    }
    join(parts)
}

/// Recordings read one path each (in command-line order) grouped into sessions: files of one
/// imud session (same recorder prefix and device metadata, consecutive file indices, each
/// starting after the one before ends) become one series, joined as [`read_input`] joins a
/// session's files; every other file stays a recording of its own. Returns each recording with
/// the indices of its paths (ascending), ordered by the first of them.
pub fn group_sessions(parts: Vec<ImuSeries>) -> Result<Vec<(Vec<usize>, ImuSeries)>, InputError> {
    let mut order: Vec<usize> = (0..parts.len()).collect();
    order.sort_by_key(|&i| (parts[i].t0_ns, i));
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for i in order {
        let next = groups
            .iter_mut()
            .find(|g| continues(&parts[*g.last().expect("a group has a part")], &parts[i]));
        match next {
            Some(g) => g.push(i),
            None => groups.push(vec![i]),
        }
    }
    for g in &mut groups {
        g.sort_unstable();
    }
    groups.sort_by_key(|g| g[0]);
    let mut slots: Vec<Option<ImuSeries>> = parts.into_iter().map(Some).collect();
    groups
        .into_iter()
        .map(|g| {
            let mut members: Vec<ImuSeries> = g
                .iter()
                .map(|&i| slots[i].take().expect("each part in one group"))
                .collect();
            let series = if members.len() == 1 {
                members.pop().expect("one part")
            } else {
                join(members)?
            };
            Ok((g, series))
        })
        .collect()
}

/// True if `next` is the file imud wrote right after `last` in one session.
fn continues(last: &ImuSeries, next: &ImuSeries) -> bool {
    let (Some(a), Some(b)) = (&last.input.imud_file, &next.input.imud_file) else {
        return false;
    };
    let end_ns = |s: &ImuSeries| s.t0_ns as f64 + s.t_s.last().copied().unwrap_or(0.0) * 1e9;
    a.prefix == b.prefix
        && last.input.device == next.input.device
        && b.file_index == a.file_index.wrapping_add(1)
        && next.t0_ns as f64 > end_ns(last)
}

/// One file, its format told by content.
fn read_file(
    path: &Path,
    options: &InputOptions,
    on_progress: &mut dyn FnMut(u64, u64),
) -> Result<ImuSeries, InputError> {
    let io = |source| InputError::Io {
        path: path.to_path_buf(),
        source,
    };
    if has_mcap_magic(path).map_err(io)? {
        return read_mcap_with_progress(
            path,
            options.source,
            options.topic.as_deref(),
            on_progress,
        );
    }
    let topic = options.topic.as_deref();
    if has_rosbag_magic(path).map_err(io)? {
        return read_ros1_bag_with_progress(path, options.source, topic, on_progress);
    }
    if has_sqlite_magic(path).map_err(io)? {
        return read_db3_with_progress(path, path, options.source, topic, on_progress);
    }
    if starts_with(path, &ZSTD_MAGIC).map_err(io)? {
        // rosbag2's file compression (`x.db3.zstd`): read a decompressed copy under its name.
        let plain = bag::decompress_zstd_file(path)?;
        if !has_sqlite_magic(plain.path()).map_err(io)? {
            return Err(InputError::NoData {
                path: path.to_path_buf(),
                message: "a zstd-compressed file that holds no sqlite3 bag (only rosbag2's \
                          compressed .db3 files are read)"
                    .into(),
            });
        }
        return read_db3_with_progress(plain.path(), path, options.source, topic, on_progress);
    }
    if !looks_like_text(path).map_err(io)? {
        return Err(InputError::Mcap(McapReadError::NotMcap {
            path: path.to_path_buf(),
            message: "no MCAP magic bytes, not a ROS 1 bag or rosbag2 sqlite3 file, and not \
                      text either (binary data)"
                .into(),
        }));
    }
    let size = std::fs::metadata(path).map_or(0, |m| m.len());
    on_progress(0, size);
    let series = read_text(path, &options.csv, &options.columns)?;
    on_progress(size, size);
    Ok(series)
}

/// True if the first 64 KiB hold no NUL byte: text in any 8-bit encoding (a Latin-1 `deg C`
/// in a header is still text), never binary data.
fn looks_like_text(path: &Path) -> std::io::Result<bool> {
    let mut head = Vec::with_capacity(1 << 16);
    std::fs::File::open(path)?
        .take(1 << 16)
        .read_to_end(&mut head)?;
    Ok(!head.contains(&0))
}

/// The parts of one session as one series: time order, one time base, gaps found.
fn join(mut parts: Vec<ImuSeries>) -> Result<ImuSeries, InputError> {
    parts.sort_by_key(|p| p.t0_ns);
    check_topics(&parts)?;
    let interval_s = 1.0 / parts[0].sample_rate_hz();
    let t0 = parts[0].t0_ns;
    let mut out = ImuSeries {
        t0_ns: t0,
        input: InputInfo {
            topic: parts[0].input.topic.clone(),
            ..InputInfo::default()
        },
        ..ImuSeries::default()
    };
    let mut early = Vec::new();
    let mut label_parts = Vec::new();
    for part in parts {
        let offset_s = (part.t0_ns as i128 - t0 as i128) as f64 * 1e-9;
        let first = part.input.files.first().cloned().unwrap_or_default();
        if let (Some(&last), Some(&next)) = (out.t_s.last(), part.t_s.first()) {
            let step_s = offset_s + next - last;
            let before = out.input.files.last().cloned().unwrap_or_default();
            if step_s <= 0.0 {
                return Err(InputError::Session {
                    message: format!(
                        "{} starts {:.3} s before {} ends: files that overlap in time are not \
                         one session",
                        first.display(),
                        -step_s,
                        before.display()
                    ),
                });
            }
            if interval_s.is_finite() && step_s > GAP_INTERVALS * interval_s {
                out.input.gaps.push(SessionGap {
                    after: before,
                    before: first.clone(),
                    at_s: last,
                    gap_s: step_s,
                    missing_samples: (step_s / interval_s).round().max(1.0) as u64 - 1,
                });
            }
        }
        out.t_s.extend(part.t_s.iter().map(|t| t + offset_s));
        out.input.non_finite_samples += part.input.non_finite_samples;
        out.accel_m_s2.extend(part.accel_m_s2);
        out.gyro_rad_s.extend(part.gyro_rad_s);
        out.temp
            .extend(part.temp.iter().map(|&(t, c)| (t + offset_s, c)));
        if let Some(why) = part.stopped_early {
            early.push(format!("{}: {why}", first.display()));
        }
        if part.unfinished.is_some() {
            out.unfinished = part.unfinished;
            out.input.unfinished_file = part.input.unfinished_file;
        }
        label_parts.push(part.labels);
        // What the session says about itself: the latest file's word.
        if !part.input.device.is_empty() {
            out.input.device = part.input.device;
        }
        if part.input.calibration.is_some() {
            out.input.calibration = part.input.calibration;
        }
        out.input.files.extend(part.input.files);
    }
    out.labels = join_labels(label_parts);
    out.stopped_early = (!early.is_empty()).then(|| early.join("; "));
    out.origin = origin(&out.input);
    Ok(out)
}

/// Every file of a corrected session must have been read on the same topic.
fn check_topics(parts: &[ImuSeries]) -> Result<(), InputError> {
    let topic = &parts[0].input.topic;
    if parts.iter().all(|p| p.input.topic == *topic) {
        return Ok(());
    }
    let listed: Vec<String> = parts
        .iter()
        .map(|p| {
            format!(
                "{} ({})",
                p.input
                    .files
                    .first()
                    .map_or(String::new(), |f| f.display().to_string()),
                p.input.topic.as_deref().unwrap_or("text")
            )
        })
        .collect();
    Err(InputError::Session {
        message: format!(
            "the files were read on different topics: {}; choose one with --topic",
            listed.join(", ")
        ),
    })
}

/// Labels of the parts, names merged: `None` unless every part has labels.
fn join_labels(parts: Vec<Option<Labels>>) -> Option<Labels> {
    let mut out = Labels::default();
    for labels in parts {
        let l = labels?;
        for &i in &l.per_sample {
            out.push(&l.names[i as usize]);
        }
    }
    Some(out)
}

/// `a + b + c (topic)`, or the first and last of many files.
fn origin(info: &InputInfo) -> String {
    let topic = info
        .topic
        .as_ref()
        .map_or(String::new(), |t| format!(" ({t})"));
    let names: Vec<String> = info.files.iter().map(|f| f.display().to_string()).collect();
    let listed = match names.as_slice() {
        [first, .., last] if names.len() > 3 => {
            format!("{first} .. {last} ({} files)", names.len())
        }
        _ => names.join(" + "),
    };
    format!("{listed}{topic}")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::ImudFile;

    /// One file of 10 s at 10 Hz starting at `start_s`, written by imud run `prefix` as file
    /// `index` of device `serial`.
    fn file(name: &str, prefix: &str, serial: &str, index: u32, start_s: f64) -> ImuSeries {
        ImuSeries {
            t_s: (0..100).map(|i| i as f64 * 0.1).collect(),
            accel_m_s2: vec![[0.0, 0.0, 9.8]; 100],
            gyro_rad_s: vec![[0.0; 3]; 100],
            t0_ns: (start_s * 1e9) as u64,
            input: InputInfo {
                files: vec![name.into()],
                imud_file: Some(ImudFile {
                    prefix: prefix.into(),
                    file_index: index,
                }),
                device: [("serial".to_string(), serial.to_string())].into(),
                ..InputInfo::default()
            },
            ..ImuSeries::default()
        }
    }

    #[test]
    fn rotated_files_in_any_order_are_one_recording_others_stay_separate() {
        let parts = vec![
            file("b1", "imu", "7", 1, 110.0),     // session b, second file
            file("a0", "imu", "7", 0, 0.0),       // session a
            file("b0", "imu", "7", 0, 100.0),     // session b, first file
            file("a1", "imu", "7", 1, 10.05),     // session a, rotated
            file("other", "imu", "8", 2, 20.1),   // another device
            file("a4", "imu", "7", 4, 30.0),      // file 3 is missing: separate
            file("overlap", "imu", "7", 2, 19.0), // starts before a1 ends
        ];
        let groups = group_sessions(parts).unwrap();
        let indices: Vec<Vec<usize>> = groups.iter().map(|(g, _)| g.clone()).collect();
        assert_eq!(indices, [vec![0, 2], vec![1, 3], vec![4], vec![5], vec![6]]);
        let (_, b) = &groups[0];
        assert_eq!(b.len(), 200);
        assert_eq!(b.input.files, [PathBuf::from("b0"), PathBuf::from("b1")]);
        assert!((b.t_s[100] - 10.0).abs() < 1e-9);
        assert!(b.input.gaps.is_empty());
        let (_, a) = &groups[1];
        assert_eq!(a.input.files, [PathBuf::from("a0"), PathBuf::from("a1")]);
        assert!((a.t_s[199] - 19.95).abs() < 1e-6);
    }

    #[test]
    fn text_files_are_never_joined() {
        let mut a = file("a.txt", "", "", 0, 0.0);
        let mut b = file("b.txt", "", "", 1, 10.1);
        a.input.imud_file = None;
        b.input.imud_file = None;
        assert_eq!(group_sessions(vec![a, b]).unwrap().len(), 2);
    }
}
