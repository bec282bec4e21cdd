//! Recordings of several files read as one: imud's rotated files of a session (and a restart
//! later, a gap that is reported), and a rosbag2 directory written by Python `rosbags` (an
//! independent writer) with two IMU topics: an error listing both without a topic, the right
//! values with one. Samples holding NaN or infinity are skipped and counted.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use imu_analysis::input::{InputError, InputOptions, read_input};
use imu_rec::CorrectedSample;
use imu_rec::recording::{LogRecord, Recorder, RecordingConfig, list_recordings};

const T0_NS: u64 = 1_700_000_000_000_000_000;
const DT_NS: u64 = 10_000_000;

/// The truth of sample `k`: accel, gyro.
fn truth(k: u64) -> ([f64; 3], [f64; 3]) {
    let x = k as f64;
    (
        [0.01 * x, -0.5, 9.75 - 1e-3 * x],
        [1e-4 * x, 2e-3, -3e-4 * x],
    )
}

/// A recorder of imud's corrected stream into `dir`, rotating files at ~24 KiB.
fn rotating_recorder(dir: &Path, metadata: Vec<(String, BTreeMap<String, String>)>) -> Recorder {
    let config = RecordingConfig {
        dir: dir.to_path_buf(),
        prefix: "imud".into(),
        rotate_size_bytes: 24 * 1024,
        rotate_interval_s: 0.0,
        ..RecordingConfig::default()
    };
    Recorder::start(config, metadata).unwrap()
}

/// Logs corrected sample `k` (time `T0_NS + k DT_NS`) with accel `a` and gyro `g`.
fn log_sample(rec: &Recorder, k: u64, a: [f64; 3], g: [f64; 3]) {
    let t = T0_NS + k * DT_NS;
    assert!(rec.log(LogRecord::Corrected(CorrectedSample {
        seq: k,
        t_sample_ns: t,
        t_wall_ns: t,
        accel_m_s2: a,
        gyro_rad_s: g,
        ..CorrectedSample::default()
    })));
}

/// One daemon run of unit 4242 with calibration `cal_id` in force: samples `ks` on the
/// corrected stream, rotated into files of ~24 KiB.
fn record_run(dir: &Path, ks: std::ops::Range<u64>, cal_id: &str) {
    let device = BTreeMap::from([("serial-number".to_string(), "4242".to_string())]);
    let rec = rotating_recorder(dir, vec![("imud.device".into(), device)]);
    assert!(rec.log(LogRecord::Calibration {
        t_wall_ns: T0_NS + ks.start * DT_NS,
        id: cal_id.into(),
        toml: format!("# {cal_id}\n"),
        noise: None,
    }));
    for k in ks {
        let (a, g) = truth(k);
        log_sample(&rec, k, a, g);
    }
    rec.finish().unwrap();
}

#[test]
fn rotated_imud_files_are_one_recording_with_the_gap_reported() {
    let dir = tempfile::tempdir().unwrap();
    record_run(dir.path(), 0..600, "cal-a");
    let first_run = list_recordings(dir.path(), "imud").unwrap();
    assert!(first_run.len() >= 3, "rotation made {first_run:?}");
    // The daemon restarted one second later: samples 700.. in new files (index from 0 again).
    std::thread::sleep(std::time::Duration::from_millis(1100));
    record_run(dir.path(), 700..900, "cal-b");
    let all = list_recordings(dir.path(), "imud").unwrap();
    assert!(all.len() > first_run.len());
    let options = InputOptions::default();
    // The directory, and the files given one by one in any order, are the same recording.
    let from_dir = read_input(&[dir.path().to_path_buf()], &options, &mut |_, _| {}).unwrap();
    let mut shuffled = all.clone();
    shuffled.reverse();
    let from_files = read_input(&shuffled, &options, &mut |_, _| {}).unwrap();
    assert_eq!(from_dir, from_files);
    let s = from_dir;
    let ks: Vec<u64> = (0..600).chain(700..900).collect();
    assert_eq!(s.len(), ks.len());
    assert_eq!(s.t0_ns, T0_NS);
    for (i, &k) in ks.iter().enumerate() {
        let (a, g) = truth(k);
        assert!(
            (s.t_s[i] - (k * DT_NS) as f64 * 1e-9).abs() < 1e-9,
            "t of {k}"
        );
        assert_eq!(s.accel_m_s2[i], a, "accel of {k}");
        assert_eq!(s.gyro_rad_s[i], g, "gyro of {k}");
    }
    assert_eq!(s.input.files.len(), all.len());
    assert_eq!(s.input.topic.as_deref(), Some("/imu/data"));
    // One gap, between the runs: samples 600..=699 missing; none between rotated files.
    assert_eq!(s.input.gaps.len(), 1, "{:?}", s.input.gaps);
    let gap = &s.input.gaps[0];
    assert_eq!(gap.missing_samples, 100);
    assert!((gap.gap_s - 1.01).abs() < 1e-9 && (gap.at_s - 5.99).abs() < 1e-9);
    assert_eq!(gap.after, *first_run.last().unwrap());
    assert_eq!(s.missing_samples(), 100);
    // What the session says about itself: its device, and the calibration put in force last
    // (the second run's), from the latest file.
    assert_eq!(s.input.device["serial-number"], "4242");
    let cal = s
        .input
        .calibration
        .as_ref()
        .expect("a calibration in force");
    assert_eq!((cal.id.as_str(), cal.toml.as_str()), ("cal-b", "# cal-b\n"));
    assert_eq!(cal.file, *all.last().unwrap());
    assert_eq!(
        s.started_utc().as_deref(),
        Some("2023-11-14T22:13:20.000000000Z")
    );
    // Files of one session that overlap in time are refused.
    let twice = [all[0].clone(), all[0].clone()];
    let e = read_input(&twice, &options, &mut |_, _| {}).unwrap_err();
    assert!(
        matches!(e, InputError::Session { .. }) && e.to_string().contains("overlap"),
        "{e}"
    );
}

#[test]
fn samples_holding_nan_or_infinity_are_skipped_and_counted() {
    // A unit that sends NaN for a reading it lacks, and an infinity: over rotated files of one
    // session, every finite sample is read exactly, the others skipped, counted and missing.
    let dir = tempfile::tempdir().unwrap();
    let bad = |k: u64| k % 97 == 5 || k % 101 == 7;
    let rec = rotating_recorder(dir.path(), Vec::new());
    for k in 0..600u64 {
        let (mut a, mut g) = truth(k);
        if k % 97 == 5 {
            a[(k % 3) as usize] = f64::NAN;
        }
        if k % 101 == 7 {
            g[(k % 3) as usize] = f64::NEG_INFINITY;
        }
        log_sample(&rec, k, a, g);
    }
    rec.finish().unwrap();
    assert!(list_recordings(dir.path(), "imud").unwrap().len() >= 3);
    let s = read_input(
        &[dir.path().to_path_buf()],
        &InputOptions::default(),
        &mut |_, _| {},
    )
    .unwrap();
    let kept: Vec<u64> = (0..600).filter(|&k| !bad(k)).collect();
    let skipped = 600 - kept.len() as u64;
    assert_eq!(skipped, 13);
    assert_eq!(s.input.non_finite_samples, skipped);
    assert_eq!(s.len(), kept.len());
    for (i, &k) in kept.iter().enumerate() {
        assert_eq!((s.accel_m_s2[i], s.gyro_rad_s[i]), truth(k), "sample {k}");
        assert!(
            (s.t_s[i] - (k * DT_NS) as f64 * 1e-9).abs() < 1e-9,
            "t of {k}"
        );
    }
    // Each one skipped leaves one sample interval without a sample.
    assert_eq!(s.missing_samples(), skipped);
    // A recording with nothing finite is an error that says so.
    let dir2 = tempfile::tempdir().unwrap();
    let rec = rotating_recorder(dir2.path(), Vec::new());
    for k in 0..5u64 {
        log_sample(&rec, k, [f64::NAN; 3], [0.0; 3]);
    }
    rec.finish().unwrap();
    let e = read_input(
        &[dir2.path().to_path_buf()],
        &InputOptions::default(),
        &mut |_, _| {},
    )
    .unwrap_err();
    assert!(
        e.to_string().contains("all 5 IMU samples hold a NaN"),
        "{e}"
    );
}

/// Writes the rosbag2 directory with Python `rosbags`; `None` when the peer is unavailable
/// and that is allowed (fails under IMUD_REQUIRE_PEERS).
fn write_bag(dir: &Path, n: u64) -> Option<PathBuf> {
    let script = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../tests/python"))
        .join("write_rosbag2.py");
    let bag = dir.join("bag");
    let unavailable = |why: String| {
        assert!(
            std::env::var_os("IMUD_REQUIRE_PEERS").is_none(),
            "Python peer unavailable: {why} (python3 -m pip install -r requirements-dev.txt)"
        );
        eprintln!("skipping the rosbag2 test (install requirements-dev.txt): {why}");
        None
    };
    match Command::new("python3")
        .arg(&script)
        .arg(&bag)
        .arg(n.to_string())
        .arg(T0_NS.to_string())
        .output()
    {
        Ok(out) if out.status.success() => Some(bag),
        Ok(out) if out.status.code() == Some(77) => {
            unavailable(String::from_utf8_lossy(&out.stderr).trim().to_string())
        }
        Ok(out) => panic!(
            "{} failed: {}",
            script.display(),
            String::from_utf8_lossy(&out.stderr)
        ),
        Err(e) => unavailable(format!("cannot run python3: {e}")),
    }
}

#[test]
fn a_rosbag2_directory_with_two_imu_topics() {
    let dir = tempfile::tempdir().unwrap();
    let n = 40;
    let Some(bag) = write_bag(dir.path(), n) else {
        return;
    };
    let paths = [bag.clone()];
    let e = read_input(&paths, &InputOptions::default(), &mut |_, _| {}).unwrap_err();
    let text = e.to_string();
    assert!(matches!(e, InputError::AmbiguousTopic { .. }), "{text}");
    assert!(
        text.contains("/imu/a (20 messages), /imu/b (20 messages)") && text.contains("--topic"),
        "{text}"
    );
    for (topic, sign) in [("/imu/a", 1.0), ("/imu/b", -1.0)] {
        let options = InputOptions {
            topic: Some(topic.into()),
            ..InputOptions::default()
        };
        let s = read_input(&paths, &options, &mut |_, _| {}).unwrap();
        assert_eq!(s.len(), n as usize, "{topic}: both files of the bag");
        assert_eq!(s.t0_ns, T0_NS);
        for k in 0..n as usize {
            let x = k as f64;
            let a = [0.125 * x, -0.5, 9.75].map(|v| sign * v);
            let g = [1e-3 * x, 2e-3, -3e-3 * x].map(|v| sign * v);
            assert_eq!(s.accel_m_s2[k], a, "{topic} accel {k}");
            assert_eq!(s.gyro_rad_s[k], g, "{topic} gyro {k}");
            assert!((s.t_s[k] - 0.01 * x).abs() < 1e-9);
        }
        assert_eq!(s.input.topic.as_deref(), Some(topic));
        assert_eq!(
            s.input.files,
            vec![bag.join("bag_0.mcap"), bag.join("bag_1.mcap")]
        );
        assert!(s.input.gaps.is_empty(), "{:?}", s.input.gaps);
    }
    let options = InputOptions {
        topic: Some("/imu/c".into()),
        ..InputOptions::default()
    };
    let e = read_input(&paths, &options, &mut |_, _| {})
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("no IMU topic (sensor_msgs Imu) `/imu/c`") && e.contains("/imu/b"),
        "{e}"
    );
}
