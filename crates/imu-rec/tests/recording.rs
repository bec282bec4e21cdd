//! The recorder on real files: every record read back in order with equal values, rotation by
//! size and time, metadata updates and the CDR of a recorded message. Failures (queue overflow,
//! write errors, a killed writer) are in `recording_failures.rs`.

mod recording_common;

use std::collections::BTreeMap;
use std::fs::File;
use std::io;
use std::path::Path;
use std::time::Duration;

use imu_rec::recording::{
    CALIBRATION_METADATA, CALIBRATION_TOPIC, IMU_TOPIC, LogRecord, RECORDING_METADATA,
    RecordedMessage, Recorder, for_each_record, list_recordings, read_recording,
};
use imu_rec::ros2::RosMessage;
use recording_common::*;

/// Messages a list of records becomes (a corrected sample is two, a sample three and its
/// frame).
fn message_count(records: &[LogRecord]) -> u64 {
    records
        .iter()
        .map(|r| match r {
            LogRecord::Corrected(_) => 2,
            LogRecord::Sample {
                frame, compensated, ..
            } => 3 + u64::from(frame.is_some()) + u64::from(compensated.is_some()),
            _ => 1,
        })
        .sum()
}

/// `test-YYYYMMDDTHHMMSSZ-NNNN.mcap`.
fn assert_file_name(path: &Path) {
    let name = path.file_name().unwrap().to_str().unwrap();
    let rest = name.strip_prefix("test-").expect(name);
    let b = rest.as_bytes();
    assert_eq!(b.len(), 16 + 1 + 4 + 5, "{name}");
    let digits = |r: std::ops::Range<usize>| b[r].iter().all(u8::is_ascii_digit);
    assert!(
        digits(0..8) && b[8] == b'T' && digits(9..15) && b[15] == b'Z',
        "{name}"
    );
    assert!(
        b[16] == b'-' && digits(17..21) && rest.ends_with(".mcap"),
        "{name}"
    );
}

#[test]
fn every_record_is_read_back_in_order_with_equal_values() {
    let dir = tempfile::tempdir().unwrap();
    let rec = Recorder::start(test_config(dir.path()), device_metadata()).unwrap();
    assert!(rec.stats().logging);
    let records = mixed(0, 500);
    log_all(&rec, &records);
    let stats = rec.finish().unwrap();
    let n = records.len() as u64;
    assert_eq!((stats.written, stats.flushed), (n, n));
    assert_eq!(
        (stats.dropped_queue_full, stats.dropped_not_logging),
        (0, 0)
    );
    assert_eq!(stats.files_started, 1);
    assert!(!stats.logging && stats.last_error.is_none() && stats.current_file.is_none());

    let files = list_recordings(dir.path(), "test").unwrap();
    assert_eq!(files.len(), 1);
    assert_file_name(&files[0]);
    let bytes = std::fs::read(&files[0]).unwrap();
    assert_eq!(stats.bytes_written, bytes.len() as u64);

    let got = read_recording(&files[0]).unwrap();
    assert_eq!(got.stopped_early, None);
    let want = expected(&records, "imu_link");
    assert_same_messages(&got, &want);
    // The covariance follows the calibration in force: known noise, then unknown.
    assert_eq!(got.imu[0].linear_acceleration_covariance[4], 2e-4);
    assert_eq!(got.imu[0].angular_velocity_covariance[8], 3e-7);
    assert_eq!(got.mag[0].magnetic_field_covariance[0], 1e-14);
    assert_eq!(got.imu[499].linear_acceleration_covariance, [0.0; 9]);
    assert_eq!(got.imu[0].orientation_covariance[0], -1.0);
    assert_eq!(got.mag[3].magnetic_field.x, 0.21 * 1e-4);
    assert_eq!(got.temperatures.len(), 50);

    assert_eq!(got.metadata["imud.device"]["serial"], "1234");
    assert_eq!(got.metadata[RECORDING_METADATA]["file-index"], "0");
    assert_eq!(got.metadata[RECORDING_METADATA]["frame-id"], "imu_link");
    assert_eq!(got.metadata[CALIBRATION_METADATA]["id"], "cal-250");

    // The summary is complete: every channel, every message counted.
    let summary = mcap::Summary::read(&bytes).unwrap().expect("summary");
    assert_eq!(summary.channels.len(), 9);
    let stats = summary.stats.unwrap();
    assert_eq!(stats.message_count, message_count(&records));
    let imu = summary
        .channels
        .values()
        .find(|c| c.topic == IMU_TOPIC)
        .unwrap();
    let schema = imu.schema.as_ref().unwrap();
    assert_eq!(
        (schema.name.as_str(), schema.encoding.as_str()),
        ("sensor_msgs/msg/Imu", "ros2msg")
    );
    assert_eq!(imu.message_encoding, "cdr");
}

#[test]
fn streaming_reader_delivers_messages_in_file_order() {
    let dir = tempfile::tempdir().unwrap();
    let rec = Recorder::start(test_config(dir.path()), Vec::new()).unwrap();
    let records = mixed(0, 60);
    log_all(&rec, &records);
    rec.finish().unwrap();
    let file = &list_recordings(dir.path(), "test").unwrap()[0];
    let mut kinds = Vec::new();
    let report = for_each_record(file, |m| {
        kinds.push(match m {
            RecordedMessage::Calibration(_) => 'c',
            RecordedMessage::Frame(_) => 'f',
            RecordedMessage::Raw(_) => 'r',
            RecordedMessage::Imu(_) => 'i',
            RecordedMessage::MagneticField(_) => 'm',
            RecordedMessage::Temperature(_) => 't',
            RecordedMessage::Status { .. } => 's',
            RecordedMessage::Health(_) => 'h',
            RecordedMessage::DeviceCompensated(_) => 'd',
        })
    })
    .unwrap();
    let want: String = records
        .iter()
        .map(|r| match r {
            LogRecord::Calibration { .. } => "c",
            LogRecord::RawFrame { .. } => "f",
            LogRecord::Sample {
                frame: Some(_),
                compensated: None,
                ..
            } => "frim",
            LogRecord::Sample {
                frame: Some(_),
                compensated: Some(_),
                ..
            } => "frimd",
            LogRecord::Sample {
                frame: None,
                compensated: None,
                ..
            } => "rim",
            LogRecord::Sample {
                frame: None,
                compensated: Some(_),
                ..
            } => "rimd",
            LogRecord::Raw(_) => "r",
            LogRecord::Corrected(_) => "im",
            LogRecord::Temperature { .. } => "t",
            LogRecord::Status { .. } => "s",
            LogRecord::Health(_) => "h",
        })
        .collect();
    assert_eq!(kinds.into_iter().collect::<String>(), want);
    assert_eq!(report.n_messages, message_count(&records));
}

#[test]
fn a_topic_with_the_wrong_schema_is_an_error_naming_file_and_topic() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("odd.mcap");
    {
        let mut w = mcap::Writer::new(io::BufWriter::new(File::create(&path).unwrap())).unwrap();
        let schema = w
            .add_schema("std_msgs/msg/String", "ros2msg", b"string data\n")
            .unwrap();
        let ch = w
            .add_channel(schema, CALIBRATION_TOPIC, "cdr", &BTreeMap::new())
            .unwrap();
        let header = mcap::records::MessageHeader {
            channel_id: ch,
            sequence: 1,
            log_time: 5,
            publish_time: 5,
        };
        w.write_to_known_channel(&header, &[0, 1, 0, 0, 1, 0, 0, 0, 0])
            .unwrap();
        w.finish().unwrap();
    }
    let err = read_recording(&path).unwrap_err().to_string();
    assert!(
        err.contains("odd.mcap") && err.contains(CALIBRATION_TOPIC) && err.contains("expected"),
        "{err}"
    );
}

#[test]
fn size_rotation_gives_complete_files_whose_union_is_every_record_once() {
    let dir = tempfile::tempdir().unwrap();
    let mut config = test_config(dir.path());
    config.rotate_size_bytes = 64 * 1024;
    let rec = Recorder::start(config, device_metadata()).unwrap();
    let records = mixed(0, 1500);
    log_all(&rec, &records);
    let stats = rec.finish().unwrap();
    assert_eq!(stats.written, records.len() as u64);

    let files = list_recordings(dir.path(), "test").unwrap();
    assert!(files.len() >= 3, "{} files", files.len());
    assert_eq!(stats.files_started, files.len() as u64);
    let mut all = imu_rec::recording::Recording::default();
    let mut total_bytes = 0;
    for (i, file) in files.iter().enumerate() {
        assert_file_name(file);
        total_bytes += std::fs::metadata(file).unwrap().len();
        let got = read_recording(file).unwrap();
        assert_eq!(got.stopped_early, None, "{} not finished", file.display());
        assert_eq!(got.metadata["imud.device"]["firmware"], "3.1");
        assert_eq!(
            got.metadata[RECORDING_METADATA]["file-index"],
            i.to_string()
        );
        // The calibration in force is in every file, even those without a calibration message.
        assert!(got.metadata.contains_key(CALIBRATION_METADATA), "file {i}");
        assert!(!got.raw.is_empty(), "file {i} has no samples");
        append(&mut all, got);
    }
    assert_eq!(stats.bytes_written, total_bytes);
    assert_same_messages(&all, &expected(&records, "imu_link"));
}

/// An offline simulation's recorder: its files are dated by the records' synthetic clock (a
/// scenario in 2031, one sample every 10 minutes), not by the system clock: the first file at
/// the configured start, each rotated one at its first record, in the name and `started-utc`.
#[test]
fn a_synthetic_clock_dates_the_files_by_their_records() {
    const START_NS: u64 = 1_940_000_000_000_000_000; // 2031-06-22T12:26:40Z
    const STEP_NS: u64 = 600_000_000_000;
    let dir = tempfile::tempdir().unwrap();
    let mut config = test_config(dir.path());
    config.rotate_size_bytes = 4 * 1024;
    config.synthetic_start_wall_ns = Some(START_NS);
    let rec = Recorder::start(config, Vec::new()).unwrap();
    for k in 0..200u64 {
        let t = START_NS + k * STEP_NS;
        assert!(rec.log(LogRecord::Corrected(imu_rec::CorrectedSample {
            seq: k,
            t_sample_ns: t,
            t_wall_ns: t,
            accel_m_s2: [k as f64, 0.5, 9.8],
            ..imu_rec::CorrectedSample::default()
        })));
    }
    rec.finish().unwrap();
    let files = list_recordings(dir.path(), "test").unwrap();
    assert!(files.len() >= 3, "{files:?}");
    let stamp =
        |ns: u64| imu_rec::recording::utc_stamp(std::time::UNIX_EPOCH + Duration::from_nanos(ns));
    let mut seen = 0;
    for (i, file) in files.iter().enumerate() {
        let got = read_recording(file).unwrap();
        let first_ns = got.imu[0].header.stamp.to_ns();
        assert_eq!(first_ns, START_NS + seen * STEP_NS, "{file:?}");
        seen += got.imu.len() as u64;
        let started = stamp(if i == 0 { START_NS } else { first_ns });
        assert!(started.starts_with("2031"), "{started}");
        assert_eq!(got.metadata[RECORDING_METADATA]["started-utc"], started);
        let name = file.file_name().unwrap().to_str().unwrap();
        assert_eq!(name, format!("test-{started}-{i:04}.mcap"));
    }
    assert_eq!(seen, 200);
}

#[test]
fn time_rotation_starts_a_new_file_for_records_after_the_interval() {
    let dir = tempfile::tempdir().unwrap();
    let mut config = test_config(dir.path());
    config.rotate_interval_s = 0.2;
    let rec = Recorder::start(config, Vec::new()).unwrap();
    let first = mixed(0, 100);
    log_all(&rec, &first);
    wait_until("the first batch is written", || {
        rec.stats().written == first.len() as u64
    });
    // Longer than the rotation interval: the next record belongs in a new file.
    std::thread::sleep(Duration::from_millis(400));
    let second = mixed(100, 100);
    log_all(&rec, &second);
    rec.finish().unwrap();

    let files = list_recordings(dir.path(), "test").unwrap();
    assert!(files.len() >= 2, "{} files", files.len());
    let mut all = imu_rec::recording::Recording::default();
    let mut second_starts_a_file = false;
    for file in &files {
        let got = read_recording(file).unwrap();
        assert_eq!(got.stopped_early, None);
        second_starts_a_file |= got.calibrations.first().map(|c| c.id.as_str()) == Some("cal-100")
            && got.raw.first().map(|s| s.seq) == Some(100);
        append(&mut all, got);
    }
    assert!(second_starts_a_file);
    let records: Vec<LogRecord> = first.into_iter().chain(second).collect();
    assert_same_messages(&all, &expected(&records, "imu_link"));
}

#[test]
fn metadata_updates_reach_the_current_file_and_every_later_one() {
    let dir = tempfile::tempdir().unwrap();
    let mut config = test_config(dir.path());
    config.rotate_size_bytes = 32 * 1024;
    let rec = Recorder::start(config, device_metadata()).unwrap();
    let first = mixed(0, 10);
    log_all(&rec, &first);
    wait_until("the first records are written", || {
        rec.stats().written == first.len() as u64
    });
    rec.update_metadata(
        "imud.device",
        BTreeMap::from([
            ("serial".to_string(), "1234".to_string()),
            ("firmware".to_string(), "3.2".to_string()),
        ]),
    );
    rec.update_metadata(
        "imud.gains",
        BTreeMap::from([("accel".to_string(), "7000".to_string())]),
    );
    log_all(&rec, &mixed(10, 600));
    rec.finish().unwrap();
    let files = list_recordings(dir.path(), "test").unwrap();
    assert!(files.len() >= 2);
    for file in &files {
        let got = read_recording(file).unwrap();
        assert_eq!(got.metadata["imud.device"]["firmware"], "3.2", "{file:?}");
        assert_eq!(got.metadata["imud.gains"]["accel"], "7000", "{file:?}");
    }
}

/// A sink that blocks every write while its gate is closed (a disk that stalls).

#[test]
fn cdr_of_a_recorded_message_is_what_the_ros2_module_encodes() {
    // The recorder and a direct encoding agree byte for byte (the file holds plain CDR).
    let dir = tempfile::tempdir().unwrap();
    let rec = Recorder::start(test_config(dir.path()), Vec::new()).unwrap();
    rec.log(LogRecord::Corrected(corrected(3)));
    rec.finish().unwrap();
    let file = &list_recordings(dir.path(), "test").unwrap()[0];
    let mut found = None;
    imu_rec::mcap_read::for_each_message(file, |ch, header, data| {
        if ch.topic == IMU_TOPIC {
            found = Some((header.log_time, data.to_vec()));
        }
        Ok(())
    })
    .unwrap();
    let (log_time, data) = found.unwrap();
    assert_eq!(log_time, corrected(3).t_wall_ns);
    let want = imu_rec::recording::imu_message(&corrected(3), "imu_link", None).to_cdr();
    assert_eq!(data, want);
}
