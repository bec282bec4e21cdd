//! Other robots' logs, written by Python `rosbags` (an independent writer) with a known truth:
//! ROS 1 bags (chunks uncompressed, bz2 and lz4; cut short; never indexed) and rosbag2 sqlite3
//! bags (split over two files; uncompressed, compressed per file and per message), read by
//! content with the MCAP reader's topic rules.

use std::path::{Path, PathBuf};
use std::process::Command;

use imu_analysis::input::{InputError, InputOptions, Source, read_input};

const T0_NS: u64 = 1_700_000_000_000_000_000;

/// Runs `write_ros_logs.py ARGS`; false when the peer is unavailable and that is allowed
/// (fails under IMUD_REQUIRE_PEERS).
fn python(args: &[&str]) -> bool {
    let script = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../tests/python"))
        .join("write_ros_logs.py");
    let unavailable = |why: String| {
        assert!(
            std::env::var_os("IMUD_REQUIRE_PEERS").is_none(),
            "Python peer unavailable: {why} (python3 -m pip install -r requirements-dev.txt)"
        );
        eprintln!("skipping (install requirements-dev.txt): {why}");
        false
    };
    match Command::new("python3").arg(&script).args(args).output() {
        Ok(out) if out.status.success() => true,
        Ok(out) if out.status.code() == Some(77) => {
            unavailable(String::from_utf8_lossy(&out.stderr).trim().to_string())
        }
        Ok(out) => panic!(
            "{} {args:?} failed: {}",
            script.display(),
            String::from_utf8_lossy(&out.stderr)
        ),
        Err(e) => unavailable(format!("cannot run python3: {e}")),
    }
}

fn read(
    paths: &[PathBuf],
    topic: Option<&str>,
    source: Source,
) -> Result<imu_analysis::ImuSeries, InputError> {
    let options = InputOptions {
        topic: topic.map(str::to_string),
        source,
        ..InputOptions::default()
    };
    read_input(paths, &options, &mut |_, _| {})
}

/// Asserts `s` holds samples 0..m of the truth of topic `/imu/a` (sign 1) or `/imu/b` (-1),
/// exactly, with the truth's temperatures.
fn assert_truth(s: &imu_analysis::ImuSeries, m: usize, sign: f64, what: &str) {
    assert_eq!(s.len(), m, "{what}: samples");
    assert_eq!(s.t0_ns, T0_NS, "{what}");
    for k in 0..m {
        let x = k as f64;
        let a = [0.125 * x, -0.5, 9.75].map(|v| sign * v);
        let g = [1e-3 * x, 2e-3, -3e-3 * x].map(|v| sign * v);
        assert_eq!(s.accel_m_s2[k], a, "{what}: accel {k}");
        assert_eq!(s.gyro_rad_s[k], g, "{what}: gyro {k}");
        assert!((s.t_s[k] - 0.01 * x).abs() < 1e-9, "{what}: t {k}");
    }
    assert!(s.temp.len() >= m.saturating_sub(1), "{what}: temperatures");
    for (k, &(t, c)) in s.temp.iter().enumerate() {
        assert!(
            (t - 0.01 * k as f64).abs() < 1e-9,
            "{what}: temperature time {k}"
        );
        assert_eq!(c, 20.0 + 0.01 * k as f64, "{what}: temperature {k}");
    }
}

/// `sensor_msgs/Imu` sample `k` of `/imu/a` as ROS 1 serializes it (seq k, frame `imu`): what
/// locates each message in an uncompressed bag independently of the reader.
fn ros1_imu_a(k: u64) -> Vec<u8> {
    let t = T0_NS + k * 10_000_000;
    let mut b = Vec::new();
    b.extend_from_slice(&(k as u32).to_le_bytes());
    b.extend_from_slice(&((t / 1_000_000_000) as u32).to_le_bytes());
    b.extend_from_slice(&((t % 1_000_000_000) as u32).to_le_bytes());
    b.extend_from_slice(&3u32.to_le_bytes());
    b.extend_from_slice(b"imu");
    let x = k as f64;
    let mut values = vec![0.0, 0.0, 0.0, 1.0];
    values.extend([0.0; 9]);
    values.extend([1e-3 * x, 2e-3, -3e-3 * x]);
    values.extend([0.0; 9]);
    values.extend([0.125 * x, -0.5, 9.75]);
    values.extend([0.0; 9]);
    for v in values {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

#[test]
fn ros1_bags_in_every_compression_with_topic_choice() {
    let dir = tempfile::tempdir().unwrap();
    let n = 300;
    for compression in ["none", "bz2", "lz4"] {
        // Small chunks: many of them, connections inside the first.
        let bag = dir.path().join(format!("robot-{compression}.log"));
        if !python(&[
            "ros1",
            bag.to_str().unwrap(),
            &n.to_string(),
            &T0_NS.to_string(),
            compression,
            "8192",
        ]) {
            return;
        }
        let paths = [bag.clone()];
        let e = read(&paths, None, Source::Corrected).unwrap_err();
        let text = e.to_string();
        assert!(matches!(e, InputError::AmbiguousTopic { .. }), "{text}");
        assert!(
            text.contains("/imu/a (300 messages), /imu/b (300 messages)")
                && text.contains("--topic"),
            "{text}"
        );
        for (topic, sign) in [("/imu/a", 1.0), ("/imu/b", -1.0)] {
            let s = read(&paths, Some(topic), Source::Corrected).unwrap();
            assert_truth(&s, n, sign, &format!("{compression} {topic}"));
            assert_eq!(s.input.topic.as_deref(), Some(topic));
            assert!(
                s.unfinished.is_none() && s.stopped_early.is_none(),
                "{compression}"
            );
            // A file without imud's raw stream: the raw read is its IMU topic.
            assert_eq!(read(&paths, Some(topic), Source::Raw).unwrap(), s);
        }
        let e = read(&paths, Some("/imu/c"), Source::Corrected)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("`/imu/c`") && e.contains("/imu/b (300 messages)"),
            "{e}"
        );
    }
}

#[test]
fn a_cut_or_unindexed_ros1_bag_is_read_to_its_last_complete_record() {
    let dir = tempfile::tempdir().unwrap();
    let n = 400u64;
    let bags: Vec<(String, PathBuf)> = ["none", "bz2", "lz4"]
        .iter()
        .map(|c| (c.to_string(), dir.path().join(format!("{c}.bag"))))
        .collect();
    for (c, bag) in &bags {
        if !python(&[
            "ros1",
            bag.to_str().unwrap(),
            &n.to_string(),
            &T0_NS.to_string(),
            c,
            "16384",
        ]) {
            return;
        }
    }
    let whole = std::fs::read(&bags[0].1).unwrap();
    // Uncompressed: the messages wholly before the cut are found in the bytes, by their content.
    let cut = whole.len() * 3 / 5;
    let expected = (0..n)
        .take_while(|&k| {
            let m = ros1_imu_a(k);
            find(&whole, &m).is_some_and(|at| at + m.len() <= cut)
        })
        .count();
    assert!(
        expected > 10 && expected < n as usize / 2 + 200,
        "{expected}"
    );
    let cut_bag = dir.path().join("cut-none.bag");
    std::fs::write(&cut_bag, &whole[..cut]).unwrap();
    let s = read(
        std::slice::from_ref(&cut_bag),
        Some("/imu/a"),
        Source::Corrected,
    )
    .unwrap();
    assert_truth(&s, expected, 1.0, "cut, uncompressed");
    let u = s.unfinished.as_ref().expect("reported unfinished");
    assert!(
        u.footer_missing && u.reason.contains("not closed cleanly"),
        "{u:?}"
    );
    assert_eq!(u.repair, format!("rosbag reindex {}", cut_bag.display()));
    assert_eq!(
        u.last_log_time_ns
            .map(|t| t >= T0_NS + (expected as u64 - 1) * 10_000_000),
        Some(true)
    );
    assert_eq!(s.input.unfinished_file.as_ref(), Some(&cut_bag));
    // Compressed: a cut chunk's decompressed prefix still gives its complete records; the
    // samples read are a prefix of the truth, more than the chunks before the cut hold.
    for (c, bag) in &bags[1..] {
        let bytes = std::fs::read(bag).unwrap();
        let cut = bytes.len() * 3 / 5;
        let cut_bag = dir.path().join(format!("cut-{c}.bag"));
        std::fs::write(&cut_bag, &bytes[..cut]).unwrap();
        let s = read(&[cut_bag], Some("/imu/a"), Source::Corrected).unwrap();
        let m = s.len();
        assert!(m > 0 && m < n as usize, "{c}: {m}");
        assert_truth(&s, m, 1.0, &format!("cut {c}"));
        assert!(
            s.unfinished.as_ref().is_some_and(|u| u.footer_missing),
            "{c}"
        );
    }
    // Never indexed (index_pos 0, nothing after the chunks): every message, and a warning.
    for (c, bag) in &bags {
        let mut bytes = std::fs::read(bag).unwrap();
        let at = find(&bytes[..4096], b"index_pos=").unwrap() + b"index_pos=".len();
        let index_pos = u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()) as usize;
        bytes[at..at + 8].copy_from_slice(&0u64.to_le_bytes());
        bytes.truncate(index_pos);
        let unindexed = dir.path().join(format!("unindexed-{c}.bag"));
        std::fs::write(&unindexed, &bytes).unwrap();
        let s = read(&[unindexed], Some("/imu/b"), Source::Corrected).unwrap();
        assert_truth(&s, n as usize, -1.0, &format!("unindexed {c}"));
        let u = s.unfinished.as_ref().expect("reported unfinished");
        assert!(u.footer_missing && u.reason.contains("no index"), "{u:?}");
        assert_eq!(u.n_messages, 3 * n);
    }
    // Corrupt bytes anywhere: a result or an error, never a panic.
    for (c, bag) in &bags {
        let bytes = std::fs::read(bag).unwrap();
        let bad = dir.path().join(format!("corrupt-{c}.bag"));
        for i in (0..bytes.len()).step_by(bytes.len() / 97 + 1) {
            let mut b = bytes.clone();
            b[i] ^= 0xA5;
            std::fs::write(&bad, &b).unwrap();
            let _ = read(
                std::slice::from_ref(&bad),
                Some("/imu/a"),
                Source::Corrected,
            );
        }
    }
    // Not a bag of format 2.0, and damage in the first record: errors naming the file.
    let old = dir.path().join("old.bag");
    std::fs::write(&old, b"#ROSBAG V1.2\nrest").unwrap();
    let e = read(&[old], None, Source::Corrected)
        .unwrap_err()
        .to_string();
    assert!(e.contains("old.bag") && e.contains("#ROSBAG V1.2"), "{e}");
}

/// The top-level records of a bag: (offset, header, data length) up to its index.
fn records(bytes: &[u8], end: usize) -> Vec<(usize, Vec<u8>, usize)> {
    let u32_at = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
    let mut out = Vec::new();
    let mut pos = b"#ROSBAG V2.0\n".len();
    while pos < end {
        let hl = u32_at(pos);
        let header = bytes[pos + 4..pos + 4 + hl].to_vec();
        let dl = u32_at(pos + 4 + hl);
        out.push((pos, header, dl));
        pos += 8 + hl + dl;
    }
    out
}

#[test]
fn a_killed_recorders_last_chunk_without_sizes_is_read() {
    // `rosbag record` writes a chunk's header with sizes 0 and fills them in when the chunk is
    // closed; killed before that, its last chunk's records (or compressed stream) simply run
    // to the end of the file, and the bag has no index.
    let dir = tempfile::tempdir().unwrap();
    let n = 300u64;
    for c in ["none", "bz2", "lz4"] {
        let bag = dir.path().join(format!("{c}.bag"));
        if !python(&[
            "ros1",
            bag.to_str().unwrap(),
            &n.to_string(),
            &T0_NS.to_string(),
            c,
            "16384",
        ]) {
            return;
        }
        let mut bytes = std::fs::read(&bag).unwrap();
        let at = find(&bytes[..4096], b"index_pos=").unwrap() + b"index_pos=".len();
        let index_pos = u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()) as usize;
        bytes[at..at + 8].copy_from_slice(&0u64.to_le_bytes());
        let chunks: Vec<_> = records(&bytes, index_pos)
            .into_iter()
            .filter(|(_, h, _)| find(h, b"op=\x05").is_some())
            .collect();
        assert!(chunks.len() > 3, "{c}: {} chunks", chunks.len());
        let (pos, header, data_len) = chunks.last().unwrap().clone();
        let size_at = pos + 4 + find(&header, b"size=").unwrap() + b"size=".len();
        bytes[size_at..size_at + 4].copy_from_slice(&0u32.to_le_bytes());
        let len_at = pos + 4 + header.len();
        bytes[len_at..len_at + 4].copy_from_slice(&0u32.to_le_bytes());
        bytes.truncate(len_at + 4 + data_len);
        let killed = dir.path().join(format!("killed-{c}.bag"));
        std::fs::write(&killed, &bytes).unwrap();
        let s = read(
            std::slice::from_ref(&killed),
            Some("/imu/a"),
            Source::Corrected,
        )
        .unwrap();
        assert_truth(&s, n as usize, 1.0, &format!("killed recorder, {c}"));
        let u = s.unfinished.as_ref().expect("reported unfinished");
        assert!(u.footer_missing && u.n_messages == 3 * n, "{c}: {u:?}");
    }
}

#[test]
fn sqlite3_bags_split_and_compressed_by_file_or_by_message() {
    let dir = tempfile::tempdir().unwrap();
    let n = 60;
    for mode in ["none", "file", "message"] {
        let bag = dir.path().join(format!("bag-{mode}"));
        if !python(&[
            "sqlite3",
            bag.to_str().unwrap(),
            &n.to_string(),
            &T0_NS.to_string(),
            mode,
        ]) {
            return;
        }
        let paths = [bag.clone()];
        let e = read(&paths, None, Source::Corrected).unwrap_err();
        let text = e.to_string();
        assert!(
            matches!(e, InputError::AmbiguousTopic { .. }),
            "{mode}: {text}"
        );
        assert!(
            text.contains("/imu/a (30 messages), /imu/b (30 messages)"),
            "{text}"
        );
        for (topic, sign) in [("/imu/a", 1.0), ("/imu/b", -1.0)] {
            let s = read(&paths, Some(topic), Source::Corrected).unwrap();
            assert_truth(&s, n, sign, &format!("sqlite3 {mode} {topic}"));
            assert_eq!(
                s.input.files.len(),
                2,
                "{mode}: both files of the split bag"
            );
            assert!(s.input.gaps.is_empty(), "{:?}", s.input.gaps);
            assert!(s.unfinished.is_none());
        }
        // One file of the bag given alone, by content (no metadata needed).
        let first = s_files(&bag)[0].clone();
        let s = read(
            std::slice::from_ref(&first),
            Some("/imu/a"),
            Source::Corrected,
        )
        .unwrap();
        assert_truth(&s, n / 2, 1.0, &format!("{mode}: first file alone"));
        assert_eq!(s.input.files, vec![first]);
    }
    let not_bag = dir.path().join("other.db3");
    let db = rusqlite_free_sqlite(&not_bag);
    if db {
        let e = read(&[not_bag], None, Source::Corrected)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("other.db3") && e.contains("not a rosbag2 sqlite3 file"),
            "{e}"
        );
    }
}

/// The data files of a bag directory, sorted.
fn s_files(bag: &Path) -> Vec<PathBuf> {
    let mut f: Vec<PathBuf> = std::fs::read_dir(bag)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| !p.ends_with("metadata.yaml"))
        .collect();
    f.sort();
    f
}

/// Writes an SQLite database with an unrelated table through Python's `sqlite3`; false when
/// python3 is unavailable.
fn rusqlite_free_sqlite(path: &Path) -> bool {
    Command::new("python3")
        .arg("-c")
        .arg(format!(
            "import sqlite3; c = sqlite3.connect({:?}); c.execute('CREATE TABLE t (x)'); c.commit()",
            path.to_str().unwrap()
        ))
        .status()
        .is_ok_and(|s| s.success())
}

#[path = "../../../tests/ros_formats/mod.rs"]
mod ros_formats;

#[test]
fn a_recording_converted_to_every_format_gives_identical_samples() {
    let dir = tempfile::tempdir().unwrap();
    let recording = ros_formats::record(dir.path());
    let Some(converted) = ros_formats::convert(&recording, dir.path()) else {
        return;
    };
    let original = read(std::slice::from_ref(&recording), None, Source::Corrected).unwrap();
    assert!(original.len() > 1000 && !original.temp.is_empty());
    for path in &converted {
        for source in [Source::Corrected, Source::Raw] {
            let s = read(std::slice::from_ref(path), None, source).unwrap();
            let what = format!("{} {source:?}", path.display());
            assert_eq!(s.t0_ns, original.t0_ns, "{what}");
            assert_eq!(s.t_s, original.t_s, "{what}");
            assert_eq!(s.accel_m_s2, original.accel_m_s2, "{what}");
            assert_eq!(s.gyro_rad_s, original.gyro_rad_s, "{what}");
            assert_eq!(s.temp, original.temp, "{what}");
            assert_eq!(s.input.topic, original.input.topic, "{what}");
            assert!(s.unfinished.is_none(), "{what}");
        }
    }
}
