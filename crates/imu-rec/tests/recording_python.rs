//! Recordings read by independent peers: Python `mcap` + `mcap-ros2-support` (which decodes the
//! CDR messages from our ros2msg schema text alone) and `rosbags` (which opens the file as a ROS 2
//! bag). Every decoded value must equal what was written.
//!
//! A missing peer (no python3, or a package not installed) skips the comparison locally and
//! fails under CI (`IMUD_REQUIRE_PEERS` set), so the check cannot silently vanish.

mod recording_common;

use std::path::{Path, PathBuf};

use imu_rec::recording::{LogRecord, Recorder, list_recordings, read_recording};
use recording_common::*;
use serde_json::Value;

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

fn u(v: &Value) -> u64 {
    v.as_u64()
        .unwrap_or_else(|| panic!("not an unsigned integer: {v}"))
}

fn close(got: &Value, want: f64, what: &str) {
    let g = f(got);
    assert!((g - want).abs() <= 1e-12, "{what}: {g} != {want}");
}

fn close_all(got: &Value, want: &[f64], what: &str) {
    let got = got
        .as_array()
        .unwrap_or_else(|| panic!("{what}: not an array"));
    assert_eq!(got.len(), want.len(), "{what}");
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        close(g, *w, &format!("{what}[{i}]"));
    }
}

fn check_header(got: &Value, stamp_ns: u64, frame_id: &str, what: &str) {
    assert_eq!(u(&got["sec"]), stamp_ns / 1_000_000_000, "{what} sec");
    assert_eq!(
        u(&got["nanosec"]),
        stamp_ns % 1_000_000_000,
        "{what} nanosec"
    );
    assert_eq!(got["frame_id"], frame_id, "{what} frame_id");
}

fn record_file(dir: &Path, records: &[LogRecord]) -> PathBuf {
    let rec = Recorder::start(test_config(dir), Vec::new()).unwrap();
    for r in records {
        assert!(rec.log(r.clone()));
    }
    rec.finish().unwrap();
    list_recordings(dir, "test").unwrap().remove(0)
}

#[test]
fn python_mcap_ros2_decodes_every_topic_as_written() {
    let dir = tempfile::tempdir().unwrap();
    let records = mixed(0, 120);
    let path = record_file(dir.path(), &records);
    let Some(out) = run_peer("recording_read.py", &[path.as_os_str()]) else {
        return;
    };
    let want = expected(&records, "imu_link");
    assert_eq!(out["profile"], "ros2");
    for (topic, schema) in [
        ("/imu/data", "sensor_msgs/msg/Imu"),
        ("/imu/mag", "sensor_msgs/msg/MagneticField"),
        ("/imu/temperature", "sensor_msgs/msg/Temperature"),
        ("/imu/raw", "imud_msgs/msg/RawSample"),
        ("/imu/raw_frame", "imud_msgs/msg/RawFrame"),
        ("/imud/status", "imud_msgs/msg/DaemonStatus"),
        ("/imud/calibration", "imud_msgs/msg/Calibration"),
        ("/imud/health", "imud_msgs/msg/CalibrationHealth"),
    ] {
        assert_eq!(
            out["schemas"][topic],
            serde_json::json!([schema, "ros2msg", "cdr"])
        );
    }
    let msgs = &out["messages"];

    let imu = msgs["/imu/data"].as_array().unwrap();
    assert_eq!(imu.len(), want.imu.len());
    for (i, (g, w)) in imu.iter().zip(&want.imu).enumerate() {
        let what = format!("/imu/data[{i}]");
        check_header(&g["header"], w.header.stamp.to_ns(), "imu_link", &what);
        let q = w.orientation;
        close_all(&g["orientation"], &[q.x, q.y, q.z, q.w], &what);
        close_all(
            &g["orientation_covariance"],
            &w.orientation_covariance,
            &what,
        );
        close_all(
            &g["angular_velocity"],
            &<[f64; 3]>::from(w.angular_velocity),
            &what,
        );
        close_all(
            &g["angular_velocity_covariance"],
            &w.angular_velocity_covariance,
            &what,
        );
        close_all(
            &g["linear_acceleration"],
            &<[f64; 3]>::from(w.linear_acceleration),
            &what,
        );
        close_all(
            &g["linear_acceleration_covariance"],
            &w.linear_acceleration_covariance,
            &what,
        );
    }

    // The unit's compensated outputs, a sensor_msgs/msg/Imu of their own.
    let comp = msgs["/imu/device_compensated"].as_array().unwrap();
    assert_eq!(comp.len(), want.device_compensated.len());
    assert!(!comp.is_empty());
    for (i, (g, w)) in comp.iter().zip(&want.device_compensated).enumerate() {
        let what = format!("/imu/device_compensated[{i}]");
        check_header(&g["header"], w.header.stamp.to_ns(), "imu_link", &what);
        close_all(
            &g["angular_velocity"],
            &<[f64; 3]>::from(w.angular_velocity),
            &what,
        );
        close_all(
            &g["linear_acceleration"],
            &<[f64; 3]>::from(w.linear_acceleration),
            &what,
        );
        assert_eq!(
            g["orientation_covariance"][0].as_f64(),
            Some(-1.0),
            "{what}"
        );
    }

    let mag = msgs["/imu/mag"].as_array().unwrap();
    assert_eq!(mag.len(), want.mag.len());
    for (i, (g, w)) in mag.iter().zip(&want.mag).enumerate() {
        let what = format!("/imu/mag[{i}]");
        check_header(&g["header"], w.header.stamp.to_ns(), "imu_link", &what);
        close_all(
            &g["magnetic_field"],
            &<[f64; 3]>::from(w.magnetic_field),
            &what,
        );
        close_all(
            &g["magnetic_field_covariance"],
            &w.magnetic_field_covariance,
            &what,
        );
    }

    let temps = msgs["/imu/temperature"].as_array().unwrap();
    assert_eq!(temps.len(), want.temperatures.len());
    for (g, &(t_ns, temp_c)) in temps.iter().zip(&want.temperatures) {
        check_header(&g["header"], t_ns, "imu_link", "/imu/temperature");
        close(&g["temperature"], temp_c, "temperature");
        close(&g["variance"], 0.0, "variance");
    }

    let raw = msgs["/imu/raw"].as_array().unwrap();
    assert_eq!(raw.len(), want.raw.len());
    for (g, w) in raw.iter().zip(&want.raw) {
        let what = format!("/imu/raw seq {}", w.seq);
        check_header(&g["header"], w.t_host_wall_ns, "imu_link", &what);
        for (field, value) in [
            ("seq", w.seq),
            ("t_device_ns", w.t_device_ns),
            ("t_host_monotonic_ns", w.t_host_monotonic_ns),
            ("t_host_wall_ns", w.t_host_wall_ns),
            ("t_sample_ns", w.t_sample_ns),
            ("ticks_unwrapped", w.ticks_unwrapped),
            ("ticks", u64::from(w.ticks)),
            ("command", u64::from(w.command)),
            ("reserved", u64::from(w.reserved)),
            ("flags", u64::from(w.flags)),
        ] {
            assert_eq!(u(&g[field]), value, "{what} {field}");
        }
        for (field, value) in [
            ("accel_counts", w.accel_counts),
            ("gyro_counts", w.gyro_counts),
            ("mag_counts", w.mag_counts),
        ] {
            assert_eq!(g[field], serde_json::json!(value), "{what} {field}");
        }
        close(&g["temp_c"], w.temp_c, &what);
        for (field, value) in [
            ("accel_device_m_s2", w.accel_device_m_s2),
            ("gyro_device_rad_s", w.gyro_device_rad_s),
            ("mag_device_gauss", w.mag_device_gauss),
        ] {
            for (i, v) in value.iter().enumerate() {
                close(&g[field][i], *v, &format!("{what} {field}[{i}]"));
            }
        }
    }

    let frames = msgs["/imu/raw_frame"].as_array().unwrap();
    assert_eq!(frames.len(), want.frames.len());
    for (g, w) in frames.iter().zip(&want.frames) {
        check_header(&g["header"], w.t_host_wall_ns, "imu_link", "/imu/raw_frame");
        assert_eq!(u(&g["t_host_monotonic_ns"]), w.t_host_monotonic_ns);
        assert_eq!(u(&g["stream_offset"]), w.stream_offset);
        assert_eq!(g["accepted"], w.accepted);
        assert_eq!(
            g["reject_reason"],
            w.reject_reason.clone().unwrap_or_default()
        );
        assert_eq!(g["data"], serde_json::json!(w.bytes));
    }

    let statuses = msgs["/imud/status"].as_array().unwrap();
    assert_eq!(statuses.len(), want.statuses.len());
    for (g, (t_ns, w)) in statuses.iter().zip(&want.statuses) {
        check_header(&g["header"], *t_ns, "", "/imud/status");
        for (field, value) in [
            ("t_host_monotonic_ns", w.t_host_monotonic_ns),
            ("frames", w.frames),
            ("samples", w.samples),
            ("checksum_failures", w.checksum_failures),
            ("resyncs", w.resyncs),
            ("garbage_bytes", w.garbage_bytes),
            ("truncated_frames", w.truncated_frames),
            ("samples_lost", w.samples_lost),
            ("log_drops", w.log_drops),
            ("publish_drops", w.publish_drops),
            ("reconnects", w.reconnects),
            ("calibration_id", w.calibration_id),
            ("device_connected", u64::from(w.device_connected)),
            ("logging", u64::from(w.logging)),
            ("gains_fallback", u64::from(w.gains_fallback)),
            ("health_accel", u64::from(w.health_accel)),
            ("health_gyro", u64::from(w.health_gyro)),
            ("gain_scale_accel", u64::from(w.gain_scale_accel)),
            ("gain_scale_gyro", u64::from(w.gain_scale_gyro)),
            ("gain_scale_mag", u64::from(w.gain_scale_mag)),
            ("protocol", u64::from(w.protocol)),
            (
                "configuration_unverified",
                u64::from(w.configuration_unverified),
            ),
            ("reserved", u64::from(w.reserved)),
            ("packets_unusable", w.packets_unusable),
            ("fields_skipped", w.fields_skipped),
            ("time_source", u64::from(w.time_source)),
            ("time_sync", u64::from(w.time_sync)),
            ("gnss_valid_transitions", w.gnss_valid_transitions),
            ("gnss_lost_transitions", w.gnss_lost_transitions),
        ] {
            assert_eq!(u(&g[field]), value, "/imud/status {field}");
        }
        close(&g["tick_period_est_s"], w.tick_period_est_s, "tick period");
        close(&g["clock_drift_ppm"], w.clock_drift_ppm, "drift");
        close(&g["gnss_minus_wall_s"], w.gnss_minus_wall_s, "GNSS offset");
        close(&g["gnss_drift_ppm"], w.gnss_drift_ppm, "GNSS drift");
        close(&g["temp_c"], w.temp_c, "status temp");
        close(&g["clock_offset_s"], w.clock_offset_s, "clock offset");
        close(&g["clock_residual_s"], w.clock_residual_s, "clock residual");
    }

    let cals = msgs["/imud/calibration"].as_array().unwrap();
    assert_eq!(cals.len(), want.calibrations.len());
    for (g, w) in cals.iter().zip(&want.calibrations) {
        check_header(&g["header"], w.t_wall_ns, "", "/imud/calibration");
        assert_eq!(g["id"], w.id.as_str());
        assert_eq!(g["toml"], w.toml.as_str());
    }

    let health = msgs["/imud/health"].as_array().unwrap();
    assert_eq!(health.len(), want.health.len());
    for (g, w) in health.iter().zip(&want.health) {
        check_header(&g["header"], w.t_wall_ns, "", "/imud/health");
        for (field, value) in [
            ("t_sample_ns", w.t_sample_ns),
            ("window_start_ns", w.window_start_ns),
            ("still_windows", w.still_windows),
            ("plateaus_skipped", w.plateaus_skipped),
            ("accel_state", u64::from(w.accel_state)),
            ("gyro_state", u64::from(w.gyro_state)),
            ("checks", u64::from(w.checks)),
        ] {
            assert_eq!(u(&g[field]), value, "/imud/health {field}");
        }
        close(&g["accel_residual_m_s2"], w.accel_residual_m_s2, "residual");
        close(&g["gyro_p"], w.gyro_p, "gyro p");
        close(&g["temp_c"], w.temp_c, "health temp");
        close_all(&g["gyro_offset_rad_s"], &w.gyro_offset_rad_s, "gyro offset");
        // NaN (an unobservable component) survives the round trip.
        assert_eq!(g["accel_offset_m_s2"][1], "nan", "{g}");
        close(
            &g["accel_offset_m_s2"][2],
            w.accel_offset_m_s2[2],
            "accel offset z",
        );
    }

    assert_eq!(
        u(&out["statistics_message_count"]),
        (imu.len() + mag.len() + temps.len() + raw.len() + frames.len()) as u64
            + (statuses.len() + cals.len() + health.len() + comp.len()) as u64
    );
    assert_eq!(out["metadata"]["imud.recording"]["frame-id"], "imu_link");
}

#[test]
fn rosbags_opens_the_recording_as_a_ros2_bag() {
    let dir = tempfile::tempdir().unwrap();
    let records = mixed(0, 80);
    let path = record_file(dir.path(), &records);
    let Some(out) = run_peer("recording_rosbags.py", &[path.as_os_str()]) else {
        return;
    };
    let want = expected(&records, "imu_link");
    assert_eq!(out["connections"]["/imu/data"], "sensor_msgs/msg/Imu");
    assert_eq!(out["connections"]["/imu/raw"], "imud_msgs/msg/RawSample");
    assert_eq!(
        out["connections"]["/imud/status"],
        "imud_msgs/msg/DaemonStatus"
    );
    let imu = out["imu"].as_array().unwrap();
    assert_eq!(imu.len(), want.imu.len());
    for (g, w) in imu.iter().zip(&want.imu) {
        assert_eq!(u(&g["stamp_ns"]), w.header.stamp.to_ns());
        assert_eq!(g["frame_id"], "imu_link");
        close_all(
            &g["angular_velocity"],
            &<[f64; 3]>::from(w.angular_velocity),
            "gyro",
        );
        close_all(
            &g["linear_acceleration"],
            &<[f64; 3]>::from(w.linear_acceleration),
            "accel",
        );
        close(
            &g["orientation_covariance_0"],
            -1.0,
            "orientation covariance",
        );
        close_all(
            &g["linear_acceleration_covariance"],
            &w.linear_acceleration_covariance,
            "accel covariance",
        );
    }
    let seqs: Vec<u64> = want.raw.iter().map(|s| s.seq).collect();
    assert_eq!(out["raw_seq"], serde_json::json!(seqs));
    let frames: Vec<&Vec<u8>> = want.frames.iter().map(|f| &f.bytes).collect();
    assert_eq!(out["raw_frame_data"], serde_json::json!(frames));
    let temps: Vec<f64> = want.temperatures.iter().map(|t| t.1).collect();
    close_all(&out["temperature"], &temps, "temperature");
    let mag = out["mag"].as_array().unwrap();
    assert_eq!(mag.len(), want.mag.len());
    for (g, w) in mag.iter().zip(&want.mag) {
        close_all(g, &<[f64; 3]>::from(w.magnetic_field), "mag");
    }
}

#[test]
fn python_streaming_reader_reads_an_unfinished_file_up_to_its_last_flush() {
    let dir = tempfile::tempdir().unwrap();
    let rec = Recorder::start(test_config(dir.path()), Vec::new()).unwrap();
    // Four flushes, so the file holds several chunks.
    let mut n = 0;
    for batch in 0..4 {
        for r in mixed(batch * 50, 50) {
            assert!(rec.log(r));
            n += 1;
        }
        wait_until("the batch is flushed", || rec.stats().flushed == n);
    }
    // What a SIGKILL now would leave: every flushed byte, no summary, no footer.
    let live = rec.stats().current_file.unwrap();
    let snapshot = dir.path().join("snapshot.mcap");
    std::fs::copy(&live, &snapshot).unwrap();
    // And a kill in the middle of writing a chunk: the last bytes missing.
    let bytes = std::fs::read(&snapshot).unwrap();
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 3 / 4]).unwrap();
    rec.finish().unwrap();

    let ours = read_recording(&snapshot).unwrap();
    assert_eq!(ours.raw.len(), 200);
    let ours_cut = read_recording(&cut).unwrap();
    assert!(ours_cut.stopped_early.is_some());
    assert!(
        (50..200).contains(&ours_cut.raw.len()),
        "{} samples before the cut",
        ours_cut.raw.len()
    );

    for (file, ours) in [(&snapshot, &ours), (&cut, &ours_cut)] {
        let Some(out) = run_peer(
            "recording_read.py",
            &[file.as_os_str(), std::ffi::OsStr::new("--stream")],
        ) else {
            return;
        };
        let raw = out["messages"]["/imu/raw"].as_array().unwrap();
        let seqs: Vec<u64> = raw.iter().map(|r| u(&r["seq"])).collect();
        // The same gap-free prefix our reader gets.
        assert_eq!(
            seqs,
            (0..ours.raw.len() as u64).collect::<Vec<_>>(),
            "{file:?}"
        );
        let imu = out["messages"]["/imu/data"].as_array().unwrap();
        assert_eq!(imu.len(), ours.imu.len(), "{file:?}");
        assert!(!out["error"].is_null(), "{file:?}: the peer saw no damage");
    }
}
