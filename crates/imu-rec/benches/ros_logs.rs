//! Reading other robots' logs: a ROS 1 bag and a rosbag2 sqlite3 file of about 1 GB each
//! (`sensor_msgs/Imu` at 200 Hz), written at run time by Python `rosbags` into a temporary
//! directory, read by imu-rec's readers (every message decoded, stamps and vectors collected as
//! the offline tools' series does) and by Python `rosbags` (AnyReader, every message
//! deserialized, the same collected), on the same files.
//!
//! Also measured: the peak resident memory of a read that keeps nothing (streaming), against
//! the chunk size, to show memory is bounded by one chunk (or one row), not by the file.
//!
//! Run: `cargo bench -p imu-rec --bench ros_logs` (`IMUD_BENCH_ROS_LOG_BYTES` sets the size,
//! default 1e9). Needs python3 with requirements-dev.txt; results in BENCHMARKS.md.

use std::path::Path;
use std::process::Command;
use std::time::Instant;

use imu_rec::ros1::Ros1Message;
use imu_rec::ros2::{Imu, RosMessage};

/// Bytes per message of each format as the peer writes them (record or row overhead included),
/// measured on 100 000 messages: what sizes the message count for a target file size.
const ROS1_BYTES_PER_MESSAGE: f64 = 373.1;
const DB3_BYTES_PER_MESSAGE: f64 = 361.6;

fn peer() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/python/ros_logs_bench_peer.py")
}

/// This process's peak resident set (VmHWM), KiB.
fn peak_rss_kib() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|v| v.parse().ok())
        })
        .unwrap_or(0)
}

/// Resets this process's peak resident set to its current one (Linux `clear_refs` 5), so the
/// next peak is the next read's own.
fn reset_peak_rss() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

/// One sample as the offline tools keep it.
type Sample = (u64, [f64; 3], [f64; 3]);

fn keep(m: &Imu) -> Sample {
    let a = m.linear_acceleration;
    let w = m.angular_velocity;
    (m.header.stamp.to_ns(), [a.x, a.y, a.z], [w.x, w.y, w.z])
}

/// Reads the file with imu-rec: `collect` keeps every sample, else only a sum (streaming).
fn read_rust(kind: &str, path: &Path, collect: bool) -> (usize, f64, Vec<Sample>) {
    let mut out = Vec::new();
    let (mut n, mut sum) = (0usize, 0.0);
    let mut take = |m: Imu| {
        n += 1;
        sum += m.linear_acceleration.x;
        if collect {
            out.push(keep(&m));
        }
    };
    if kind == "ros1" {
        imu_rec::ros1::bag::for_each_message(path, |c, _, data| {
            if c.msg_type == Imu::TYPE {
                take(Imu::from_ros1(data).map_err(|e| e.to_string())?);
            }
            Ok(())
        })
        .unwrap();
    } else {
        imu_rec::ros2::sqlite::for_each_message_with_progress(
            path,
            path,
            &mut |_, _| {},
            |t, _, data| {
                if t.msg_type == "sensor_msgs/msg/Imu" {
                    take(Imu::from_cdr(data).map_err(|e| e.to_string())?);
                }
                Ok(())
            },
        )
        .unwrap();
    }
    (n, sum, out)
}

fn main() {
    let target_bytes: f64 = std::env::var("IMUD_BENCH_ROS_LOG_BYTES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1e9);
    let dir = tempfile::tempdir().unwrap();
    println!(
        "ros_logs: {:.0} MB files in {}",
        target_bytes / 1e6,
        dir.path().display()
    );
    for (kind, per_message) in [
        ("ros1", ROS1_BYTES_PER_MESSAGE),
        ("sqlite3", DB3_BYTES_PER_MESSAGE),
    ] {
        let n = (target_bytes / per_message) as u64;
        // Python rosbags tells a ROS 1 bag by its extension and a rosbag2 bag by its directory.
        let out = dir.path().join(if kind == "ros1" {
            "robot.bag"
        } else {
            "sqlite3"
        });
        let t = Instant::now();
        let status = Command::new("python3")
            .arg(peer())
            .args(["gen", kind])
            .arg(&out)
            .arg(n.to_string())
            .status()
            .expect("python3");
        assert!(status.success(), "the peer could not write the {kind} file");
        let file = if kind == "ros1" {
            out.clone()
        } else {
            out.join("sqlite3.db3")
        };
        let size = std::fs::metadata(&file).unwrap().len();
        println!(
            "{kind}: wrote {n} messages, {:.3} GB, in {:.1} s (Python rosbags)",
            size as f64 / 1e9,
            t.elapsed().as_secs_f64()
        );

        // Streaming first, from a reset peak, so the peak it leaves is its own.
        reset_peak_rss();
        let before_kib = peak_rss_kib();
        let t = Instant::now();
        let (count, sum, _) = read_rust(kind, &file, false);
        let stream_s = t.elapsed().as_secs_f64();
        let stream_peak_kib = peak_rss_kib();
        assert_eq!(count as u64, n);
        let t = Instant::now();
        let (count2, sum2, kept) = read_rust(kind, &file, true);
        let collect_s = t.elapsed().as_secs_f64();
        assert_eq!((count2, sum2), (count, sum));
        let collect_peak_kib = peak_rss_kib();

        let py = Command::new("python3")
            .arg(peer())
            .arg("read")
            .arg(&out)
            .output()
            .expect("python3");
        assert!(
            py.status.success(),
            "{}",
            String::from_utf8_lossy(&py.stderr)
        );
        let py: serde_json::Value = serde_json::from_slice(&py.stdout).unwrap();
        assert_eq!(py["n"].as_u64(), Some(n), "Python read as many messages");
        assert_eq!(
            py["sum_accel_x"].as_f64(),
            Some(sum),
            "Python read the same values"
        );
        let py_s = py["seconds"].as_f64().unwrap();
        println!(
            "{kind}: imu-rec streaming {stream_s:.2} s ({:.0} MB/s, peak RSS {} MiB, +{} MiB over \
             the {} MiB before), collecting {} samples {collect_s:.2} s (peak RSS {} MiB); Python \
             rosbags {py_s:.1} s (peak RSS {} MiB): {:.0}x faster",
            size as f64 / 1e6 / stream_s,
            stream_peak_kib / 1024,
            stream_peak_kib.saturating_sub(before_kib) / 1024,
            before_kib / 1024,
            kept.len(),
            collect_peak_kib / 1024,
            py["max_rss_kib"].as_u64().unwrap_or(0) / 1024,
            py_s / collect_s
        );
        drop(kept);
        std::fs::remove_dir_all(&out).ok();
        std::fs::remove_file(&out).ok();
    }
}
