//! Shared by the recording tests: deterministic records of every kind, the reading a list of
//! records must produce, and polling helpers.

#![allow(dead_code)] // each test crate uses a different part

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use imu_rec::recording::{
    DeviceCompensated, ImuNoiseVariances, LogRecord, RecordedCalibration, RecordedFrame, Recorder,
    Recording, RecordingConfig, SampleFrame, device_compensated_message, imu_message,
    magnetic_field_message,
};
use imu_rec::sample::{CorrectedSample, DaemonStatus, RawSample, raw_flags};
use serde_json::Value;

/// Wall clock of sample 0, ns.
pub const T0_WALL_NS: u64 = 1_700_000_000_000_000_000;
/// Sample period, ns.
pub const DT_NS: u64 = 10_000_000;

pub fn raw(seq: u64) -> RawSample {
    let s = seq as i32;
    RawSample {
        seq,
        t_device_ns: 5_000_000_000 + seq * DT_NS,
        t_host_monotonic_ns: 7_000_000_000 + seq * DT_NS + 17,
        t_host_wall_ns: T0_WALL_NS + seq * DT_NS + 17,
        t_sample_ns: 7_000_000_000 + seq * DT_NS,
        ticks_unwrapped: 40_000 + seq * 2,
        accel_counts: [32_768 + s, 32_000 - s, 40_000],
        gyro_counts: [-s, s * 3, 65_535],
        mag_counts: [1, -2, s],
        temp_c: 25.0 + seq as f64 * 1e-3,
        ticks: ((40_000 + seq * 2) % 65_536) as u16,
        command: 0x01,
        reserved: 0,
        flags: if seq.is_multiple_of(7) {
            raw_flags::GAP_BEFORE
        } else {
            0
        },
        accel_device_m_s2: [0.01 * seq as f64, -9.8, 0.5],
        gyro_device_rad_s: [1e-3, -(seq as f64) * 1e-4, 0.0],
        mag_device_gauss: [0.2, 0.0, -0.4],
    }
}

pub fn corrected(seq: u64) -> CorrectedSample {
    let x = seq as f64;
    CorrectedSample {
        seq,
        t_sample_ns: 7_000_000_000 + seq * DT_NS,
        t_wall_ns: T0_WALL_NS + seq * DT_NS,
        t_device_ns: 5_000_000_000 + seq * DT_NS,
        accel_m_s2: [0.01 * x.sin(), -0.02, -9.80665 + 1e-6 * x],
        gyro_rad_s: [1e-4 * x.cos(), 0.5, -std::f64::consts::PI / 3.0],
        mag_gauss: [0.21, -0.05 * x.sin(), -0.43],
        temp_c: 25.0,
        calibration_id: 0xABCD,
        flags: 0,
        reserved: 0,
    }
}

pub fn frame(i: u64) -> LogRecord {
    let accepted = i % 5 != 3;
    LogRecord::RawFrame {
        t_host_wall_ns: T0_WALL_NS + i * DT_NS + 17,
        t_host_monotonic_ns: 7_000_000_000 + i * DT_NS + 17,
        stream_offset: i * 23,
        accepted,
        reject_reason: if accepted {
            None
        } else {
            Some(Cow::Borrowed("bad-checksum"))
        },
        bytes: (0..23)
            .map(|k| (i as u8).wrapping_mul(31).wrapping_add(k))
            .collect(),
    }
}

/// Sample `seq`'s records: as one [`LogRecord::Sample`] (with its frame, or none every sixth),
/// or for one in three as a frame, a raw and a corrected record.
pub fn sample(seq: u64) -> Vec<LogRecord> {
    if seq.is_multiple_of(3) {
        return vec![
            frame(seq),
            LogRecord::Raw(raw(seq)),
            LogRecord::Corrected(corrected(seq)),
        ];
    }
    let LogRecord::RawFrame {
        stream_offset,
        bytes,
        ..
    } = frame(seq)
    else {
        unreachable!("frame() makes frames")
    };
    vec![LogRecord::Sample {
        frame: (seq % 6 != 5).then_some(SampleFrame {
            stream_offset,
            bytes,
        }),
        raw: raw(seq),
        corrected: corrected(seq),
        // A unit's own compensated reading on every fourth (an Xsens unit sends one a sample).
        compensated: (seq % 4 == 1).then(|| DeviceCompensated {
            accel_m_s2: [0.1 * seq as f64, -9.8, 0.25],
            gyro_rad_s: [0.001, -0.002 * seq as f64, 0.003],
        }),
    }]
}

pub fn status(i: u64) -> LogRecord {
    LogRecord::Status {
        t_wall_ns: T0_WALL_NS + i * DT_NS + 500,
        status: DaemonStatus {
            t_host_monotonic_ns: 7_000_000_000 + i * DT_NS,
            frames: i,
            samples: i,
            checksum_failures: i / 5,
            resyncs: 1,
            garbage_bytes: 3,
            truncated_frames: 0,
            samples_lost: 2,
            log_drops: 0,
            publish_drops: 4,
            reconnects: 0,
            calibration_id: 0xABCD,
            tick_period_est_s: 0.0065536,
            clock_drift_ppm: -3.25,
            temp_c: 25.5,
            device_connected: 1,
            logging: 1,
            gains_fallback: 4,
            health_accel: 2,
            health_gyro: 1,
            protocol: 1,
            configuration_unverified: 1,
            reserved: 0,
            clock_offset_s: 123.25,
            clock_residual_s: 1.5e-4,
            gain_scale_accel: 8500,
            gain_scale_gyro: 10_000,
            gain_scale_mag: 2000,
            reserved_end: [0; 2],
            packets_unusable: 3,
            fields_skipped: 4,
            time_source: 2,
            time_sync: 3,
            reserved_sync: [0; 6],
            gnss_minus_wall_s: -0.375,
            gnss_drift_ppm: 150.25,
            gnss_valid_transitions: 5,
            gnss_lost_transitions: 6,
        },
    }
}

/// A calibration health report with distinct values in every field.
pub fn health(i: u64) -> LogRecord {
    LogRecord::Health(imu_rec::CalibrationHealth {
        t_sample_ns: 9_000_000_000 + i * DT_NS,
        t_wall_ns: T0_WALL_NS + i * DT_NS + 700,
        window_start_ns: 8_000_000_000 + i * DT_NS,
        calibration_id: 0xABCD,
        still_windows: i,
        plateaus_skipped: 2,
        accel_residual_m_s2: -1.25e-3,
        accel_expected_std_m_s2: 4.5e-4,
        accel_p: 3.5e-3,
        accel_offset_m_s2: [1e-4, f64::NAN, 2.5e-3],
        gyro_residual_rad_s: 2.5e-4,
        gyro_vertical_residual_rad_s: -1e-5,
        gyro_expected_std_rad_s: 3e-4,
        gyro_p: 0.75,
        gyro_offset_rad_s: [1e-5, 2e-5, -3e-5],
        gravity_m_s2: 9.80665,
        temp_c: 31.5,
        accel_state: 2,
        gyro_state: 1,
        checks: 0b1101,
        noise_source: 0,
        bias_tracking: 0,
        reserved: [0; 3],
    })
}

pub fn calibration(i: u64, noise: Option<ImuNoiseVariances>) -> LogRecord {
    LogRecord::Calibration {
        t_wall_ns: T0_WALL_NS + i * DT_NS + 1,
        id: format!("cal-{i}"),
        toml: format!("format = \"imu-model/1\"\n# calibration {i}\n"),
        noise,
    }
}

pub fn noise() -> ImuNoiseVariances {
    ImuNoiseVariances {
        accel_var_m2_s4: [1e-4, 2e-4, 3e-4],
        gyro_var_rad2_s2: [1e-7, 2e-7, 3e-7],
        mag_var_t2: [1e-14, 2e-14, 3e-14],
    }
}

/// Samples `first..first + n`, two of every three as the daemon logs them (one
/// [`LogRecord::Sample`] with its frame, or without one every sixth sample) and one as separate
/// frame, raw and corrected records; a temperature every 10, a status every 50, a health report every 60, a calibration with noise at the first sample and one without
/// at the middle.
pub fn mixed(first: u64, n: u64) -> Vec<LogRecord> {
    let mut out = Vec::new();
    for seq in first..first + n {
        if seq == first {
            out.push(calibration(seq, Some(noise())));
        }
        if seq == first + n / 2 {
            out.push(calibration(seq, None));
        }
        out.extend(sample(seq));
        if seq.is_multiple_of(10) {
            out.push(LogRecord::Temperature {
                t_wall_ns: T0_WALL_NS + seq * DT_NS + 3,
                temp_c: 25.0 + seq as f64 * 0.01,
            });
        }
        if seq.is_multiple_of(50) {
            out.push(status(seq));
        }
        if seq.is_multiple_of(60) {
            out.push(health(seq));
        }
    }
    out
}

/// What reading back `records` must give (messages only; metadata not compared).
pub fn expected(records: &[LogRecord], frame_id: &str) -> Recording {
    let mut rec = Recording::default();
    let mut noise: Option<ImuNoiseVariances> = None;
    for r in records {
        match r.clone() {
            LogRecord::RawFrame {
                t_host_wall_ns,
                t_host_monotonic_ns,
                stream_offset,
                accepted,
                reject_reason,
                bytes,
            } => rec.frames.push(RecordedFrame {
                t_host_wall_ns,
                t_host_monotonic_ns,
                stream_offset,
                accepted,
                reject_reason: reject_reason.map(Cow::into_owned),
                bytes: bytes.to_vec(),
            }),
            LogRecord::Sample {
                frame,
                raw,
                corrected,
                compensated,
            } => {
                // The frame at the raw sample's host times, accepted; then raw, imu, mag.
                if let Some(f) = frame {
                    rec.frames.push(RecordedFrame {
                        t_host_wall_ns: raw.t_host_wall_ns,
                        t_host_monotonic_ns: raw.t_host_monotonic_ns,
                        stream_offset: f.stream_offset,
                        accepted: true,
                        reject_reason: None,
                        bytes: f.bytes.to_vec(),
                    });
                }
                rec.raw.push(raw);
                rec.imu
                    .push(imu_message(&corrected, frame_id, noise.as_ref()));
                rec.mag
                    .push(magnetic_field_message(&corrected, frame_id, noise.as_ref()));
                if let Some(c) = compensated {
                    rec.device_compensated.push(device_compensated_message(
                        corrected.t_wall_ns,
                        &c,
                        frame_id,
                    ));
                }
            }
            LogRecord::Raw(s) => rec.raw.push(s),
            LogRecord::Corrected(c) => {
                rec.imu.push(imu_message(&c, frame_id, noise.as_ref()));
                rec.mag
                    .push(magnetic_field_message(&c, frame_id, noise.as_ref()));
            }
            LogRecord::Temperature { t_wall_ns, temp_c } => {
                rec.temperatures.push((t_wall_ns, temp_c))
            }
            LogRecord::Status { t_wall_ns, status } => rec.statuses.push((t_wall_ns, status)),
            LogRecord::Health(h) => rec.health.push(h),
            LogRecord::Calibration {
                t_wall_ns,
                id,
                toml,
                noise: n,
            } => {
                noise = n;
                rec.calibrations.push(RecordedCalibration {
                    t_wall_ns,
                    id,
                    toml,
                });
            }
        }
    }
    rec
}

/// Appends the messages of `b` to `a` (reading rotated files in order).
pub fn append(a: &mut Recording, b: Recording) {
    a.raw.extend(b.raw);
    a.imu.extend(b.imu);
    a.mag.extend(b.mag);
    a.temperatures.extend(b.temperatures);
    a.frames.extend(b.frames);
    a.statuses.extend(b.statuses);
    a.calibrations.extend(b.calibrations);
    a.device_compensated.extend(b.device_compensated);
}

/// Field-by-field comparison with a useful message.
pub fn assert_same_messages(actual: &Recording, expected: &Recording) {
    assert_eq!(
        actual.raw.len(),
        expected.raw.len(),
        "number of raw samples"
    );
    assert_eq!(actual.raw, expected.raw, "raw samples");
    assert_eq!(
        actual.imu.len(),
        expected.imu.len(),
        "number of imu messages"
    );
    assert_eq!(actual.imu, expected.imu, "imu messages");
    assert_eq!(actual.mag, expected.mag, "mag messages");
    assert_eq!(actual.temperatures, expected.temperatures, "temperatures");
    assert_eq!(actual.frames, expected.frames, "raw frames");
    assert_eq!(actual.statuses, expected.statuses, "statuses");
    assert_eq!(actual.calibrations, expected.calibrations, "calibrations");
    assert_eq!(
        actual.device_compensated, expected.device_compensated,
        "device compensated"
    );
}

/// A config for tests: fast flushing and retrying, no rotation, in `dir`.
pub fn test_config(dir: &Path) -> RecordingConfig {
    RecordingConfig {
        dir: dir.to_path_buf(),
        prefix: "test".into(),
        rotate_size_bytes: 0,
        rotate_interval_s: 0.0,
        queue_capacity: 100_000,
        flush_interval: Duration::from_millis(20),
        retry_interval: Duration::from_millis(20),
        frame_id: "imu_link".into(),
        compression_level: 0,
        synthetic_start_wall_ns: None,
    }
}

/// Polls `cond` until it holds; fails the test after a generous deadline (this bounds a hang,
/// it does not measure speed).
pub fn wait_until(what: &str, mut cond: impl FnMut() -> bool) {
    let deadline = Instant::now() + Duration::from_secs(30);
    while !cond() {
        assert!(Instant::now() < deadline, "timed out waiting until {what}");
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// A peer script under tests/python.
pub fn script(name: &str) -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../tests/python")).join(name)
}

/// Runs a peer script and parses its JSON; `None` when the peer is unavailable and that is allowed.
pub fn run_peer(name: &str, args: &[&std::ffi::OsStr]) -> Option<Value> {
    let script = script(name);
    let unavailable = |why: String| {
        assert!(
            std::env::var_os("IMUD_REQUIRE_PEERS").is_none(),
            "Python peer unavailable for {name}: {why} (python3 -m pip install -r requirements-dev.txt)"
        );
        eprintln!("skipping the {name} comparison (install requirements-dev.txt): {why}");
        None
    };
    match Command::new("python3").arg(&script).args(args).output() {
        Ok(out) if out.status.success() => Some(
            serde_json::from_slice(&out.stdout)
                .unwrap_or_else(|e| panic!("{name} printed no JSON ({e})")),
        ),
        // The scripts exit 77 when an import fails.
        Ok(out) if out.status.code() == Some(77) => {
            unavailable(String::from_utf8_lossy(&out.stderr).trim().to_string())
        }
        Ok(out) => panic!(
            "{} failed ({}):\n{}",
            script.display(),
            out.status,
            String::from_utf8_lossy(&out.stderr)
        ),
        Err(e) => unavailable(format!("cannot run python3: {e}")),
    }
}

/// Metadata like the daemon's device record.
pub fn device_metadata() -> Vec<(String, BTreeMap<String, String>)> {
    vec![(
        "imud.device".to_string(),
        BTreeMap::from([
            ("serial".to_string(), "1234".to_string()),
            ("firmware".to_string(), "3.1".to_string()),
        ]),
    )]
}

/// Logs every record, asserting none is refused.
pub fn log_all(rec: &Recorder, records: &[LogRecord]) {
    for r in records {
        assert!(rec.log(r.clone()), "queue unexpectedly full");
    }
}
