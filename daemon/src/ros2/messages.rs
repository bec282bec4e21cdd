//! The messages of the DDS output that the MCAP log does not have: the uncalibrated
//! `sensor_msgs/msg/Imu` (`imu/data_raw`) and the status as a `diagnostic_msgs/DiagnosticArray`.
//! The others are imu-bus's (`imu_bus::recording::imu_message` and its siblings).

use imu_bus::recording::{header, imu_message};
use imu_bus::ros2::{DiagnosticArray, DiagnosticLevel, DiagnosticStatus, Imu, KeyValue};
use imu_bus::sample::time_sync;
use imu_bus::{CorrectedSample, DaemonStatus, RawSample};

use super::Ros2Stats;

/// The `imu/data_raw` message: the device's own reading (the raw sample's `*_device_*`: the
/// GainScale conversion of a GX1's counts, a MIP unit's scaled fields), stamped and framed like
/// the corrected sample of the same `seq` (covariance unknown: the noise model is the
/// calibrated outputs').
pub fn raw_imu_message(raw: &RawSample, corrected: &CorrectedSample, frame_id: &str) -> Imu {
    let as_sample = CorrectedSample {
        accel_m_s2: raw.accel_device_m_s2,
        gyro_rad_s: raw.gyro_device_rad_s,
        mag_gauss: raw.mag_device_gauss,
        ..*corrected
    };
    imu_message(&as_sample, frame_id, None)
}

/// The daemon's status as one `DiagnosticStatus` named `<node>: <instance>`: ERROR while the
/// device is not connected, WARN with fallback GainScales, no calibration, lost DDS messages or
/// GNSS time in holdover or lost (`device.time-source = "gnss"`), else OK; every counter as a key/value. Then one `DiagnosticStatus` per triad for the live
/// calibration health (`<node>: <instance> calibration accel` / `gyro`): OK while the still
/// windows agree with physics (or none was seen yet), WARN when `degraded` or uncalibrated,
/// ERROR when `stale`.
pub fn diagnostics(
    t_wall_ns: u64,
    status: &DaemonStatus,
    dds: Ros2Stats,
    node: &str,
    instance: &str,
) -> DiagnosticArray {
    let (level, message) = if status.device_connected == 0 {
        (DiagnosticLevel::Error, "device not connected")
    } else if status.gains_fallback != 0 {
        (DiagnosticLevel::Warn, "streaming with fallback GainScales")
    } else if status.calibration_id == 0 {
        (DiagnosticLevel::Warn, "streaming uncalibrated")
    } else if dds.dropped_queue_full + dds.write_failures > 0 {
        (
            DiagnosticLevel::Warn,
            "streaming; DDS messages were dropped",
        )
    } else if status.time_sync == time_sync::GNSS_HOLDOVER {
        (
            DiagnosticLevel::Warn,
            "streaming; GNSS time invalid: stamps held over on the device clock",
        )
    } else if status.time_sync == time_sync::GNSS_LOST {
        (
            DiagnosticLevel::Warn,
            "streaming; GNSS time lost: stamps held over on the device clock",
        )
    } else {
        (DiagnosticLevel::Ok, "streaming")
    };
    DiagnosticArray {
        header: header(t_wall_ns, ""),
        status: vec![DiagnosticStatus {
            level,
            name: format!("{node}: {instance}"),
            message: message.into(),
            hardware_id: format!("imud/{instance}"),
            values: key_values(status, dds),
        }]
        .into_iter()
        .chain(
            [("accel", status.health_accel), ("gyro", status.health_gyro)]
                .map(|(triad, state)| health_status(node, instance, triad, state)),
        )
        .collect(),
    }
}

/// One triad's live calibration health as a `DiagnosticStatus`.
fn health_status(node: &str, instance: &str, triad: &str, state: u8) -> DiagnosticStatus {
    use imu_bus::sample::health_state;
    let (level, message) = match state {
        health_state::OK => (
            DiagnosticLevel::Ok,
            "the still windows agree with gravity and Earth's rate",
        ),
        health_state::DEGRADED => (
            DiagnosticLevel::Warn,
            "a still window disagrees with physics beyond the noise model: see /imud/health",
        ),
        health_state::STALE => (
            DiagnosticLevel::Error,
            "the calibration no longer holds (three still windows disagree): recalibrate",
        ),
        health_state::UNCALIBRATED => (DiagnosticLevel::Warn, "no calibration loaded"),
        _ => (DiagnosticLevel::Ok, "no still window seen yet"),
    };
    DiagnosticStatus {
        level,
        name: format!("{node}: {instance} calibration {triad}"),
        message: message.into(),
        hardware_id: format!("imud/{instance}"),
        values: vec![KeyValue {
            key: "state".into(),
            value: health_state::name(state).into(),
        }],
    }
}

fn key_values(s: &DaemonStatus, dds: Ros2Stats) -> Vec<KeyValue> {
    let kv = |key: &str, value: String| KeyValue {
        key: key.into(),
        value,
    };
    // A flat list of the status fields, one line each.
    vec![
        kv("frames", s.frames.to_string()),
        kv("samples", s.samples.to_string()),
        kv("samples_lost", s.samples_lost.to_string()),
        kv("checksum_failures", s.checksum_failures.to_string()),
        kv("resyncs", s.resyncs.to_string()),
        kv("garbage_bytes", s.garbage_bytes.to_string()),
        kv("truncated_frames", s.truncated_frames.to_string()),
        kv("log_drops", s.log_drops.to_string()),
        kv("publish_drops", s.publish_drops.to_string()),
        kv("dds_written", dds.written.to_string()),
        kv("dds_dropped_queue_full", dds.dropped_queue_full.to_string()),
        kv("dds_write_failures", dds.write_failures.to_string()),
        kv("dds_not_sent_unmatched", dds.not_sent_unmatched.to_string()),
        kv("reconnects", s.reconnects.to_string()),
        kv("calibration_id", format!("{:016x}", s.calibration_id)),
        kv("temp_c", s.temp_c.to_string()),
        kv("tick_period_est_s", s.tick_period_est_s.to_string()),
        kv("clock_drift_ppm", s.clock_drift_ppm.to_string()),
        kv("clock_offset_s", s.clock_offset_s.to_string()),
        kv("clock_residual_s", s.clock_residual_s.to_string()),
        kv("device_connected", s.device_connected.to_string()),
        kv("logging", s.logging.to_string()),
        kv("gains_fallback", s.gains_fallback.to_string()),
        kv(
            "configuration_unverified",
            s.configuration_unverified.to_string(),
        ),
        kv(
            "health_accel",
            imu_bus::sample::health_state::name(s.health_accel).into(),
        ),
        kv(
            "health_gyro",
            imu_bus::sample::health_state::name(s.health_gyro).into(),
        ),
        kv("gain_scale_accel", s.gain_scale_accel.to_string()),
        kv("gain_scale_gyro", s.gain_scale_gyro.to_string()),
        kv("gain_scale_mag", s.gain_scale_mag.to_string()),
        kv(
            "protocol",
            crate::drivers::status_protocol_name(s.protocol).into(),
        ),
        kv("packets_unusable", s.packets_unusable.to_string()),
        kv("fields_skipped", s.fields_skipped.to_string()),
        kv(
            "time_source",
            imu_bus::sample::time_source::name(s.time_source).into(),
        ),
        kv(
            "time_sync",
            imu_bus::sample::time_sync::name(s.time_sync).into(),
        ),
        kv("gnss_minus_wall_s", s.gnss_minus_wall_s.to_string()),
        kv("gnss_drift_ppm", s.gnss_drift_ppm.to_string()),
        kv(
            "gnss_valid_transitions",
            s.gnss_valid_transitions.to_string(),
        ),
        kv("gnss_lost_transitions", s.gnss_lost_transitions.to_string()),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::drivers::gx1::{self, Gx1Driver};
    use crate::drivers::{Driver, DriverEvent};
    use crate::pipeline::{GainFallback, Gains, Pipeline, Sinks};
    use imu_bus::recording::{Recorder, RecordingConfig, TESLA_PER_GAUSS, read_recording};
    use imu_bus::sample::raw_flags;
    use imu_proto::reply::Reply;

    /// The uncalibrated topic's values are the raw sample's device reading, which is the
    /// pipeline's own GainScale conversion: without a calibration the corrected stream (as the
    /// MCAP log stores it) is exactly that, for raw bits and for scaled vectors.
    #[test]
    fn raw_values_equal_the_uncalibrated_pipeline() {
        let gains = Gains {
            accel: 7000,
            gyro: 10000,
            mag: 2000,
            fallback: GainFallback::NONE,
        };
        let replies = [
            Reply::RawSensorBits {
                mag: [30_000, 33_000, 40_000],
                accel: [32_768 + 100, 32_768 - 2000, 32_768 + 4681],
                rate: [32_768 + 17, 1, u16::MAX],
                ticks: 5,
            },
            Reply::Vectors {
                kind: imu_proto::reply::Filter::Instantaneous,
                mag: [-1200, 300, 4000],
                accel: [10, -4681, 2000],
                rate: [-7, 0, i16::MAX],
                ticks: 6,
            },
        ];
        let dir = tempfile::tempdir().unwrap();
        let config = RecordingConfig {
            dir: dir.path().to_path_buf(),
            ..RecordingConfig::default()
        };
        let mut sinks = Sinks {
            recorder: Some(Recorder::start(config, Vec::new()).unwrap()),
            ..Sinks::default()
        };
        // A 3DM-GX1's replies (it sends counts) through its driver, as a streaming unit's.
        let device = crate::config::DeviceConfig::default();
        let mut driver = Gx1Driver::with_session(&device, gains);
        let mut p = Pipeline::new(gx1::session(&device, gains), None);
        for (k, reply) in replies.iter().enumerate() {
            driver.handle_input(&reply.to_bytes(), std::time::Instant::now());
            let mut slot = crate::drivers::FrameSlot::default();
            while let Some(DriverEvent::Frame) = driver.poll_event(&mut slot) {
                p.on_frame(&mut slot, k as u64 * 1_000, k as u64 * 2_000, &mut sinks);
            }
        }
        let stats = sinks.recorder.take().unwrap().finish().unwrap();
        let file = stats.current_file.clone();
        let path = file.unwrap_or_else(|| {
            std::fs::read_dir(dir.path())
                .unwrap()
                .next()
                .unwrap()
                .unwrap()
                .path()
        });
        let rec = read_recording(&path).unwrap();
        assert_eq!((rec.raw.len(), rec.imu.len()), (2, 2));
        assert_eq!(
            rec.raw[1].flags & raw_flags::SCALED_COUNTS,
            raw_flags::SCALED_COUNTS
        );
        for ((raw, imu), mag) in rec.raw.iter().zip(&rec.imu).zip(&rec.mag) {
            let c = CorrectedSample {
                seq: raw.seq,
                ..CorrectedSample::default()
            };
            let msg = raw_imu_message(raw, &c, "imu_link");
            assert_eq!(msg.linear_acceleration, imu.linear_acceleration);
            assert_eq!(msg.angular_velocity, imu.angular_velocity);
            assert_eq!(
                raw.mag_device_gauss.map(|v| v * TESLA_PER_GAUSS),
                <[f64; 3]>::from(mag.magnetic_field)
            );
        }
        // Raw bits: accel z of 4681 counts above the middle at GainScale 7000 is ~1 g.
        let g0 = imu_model::units::STANDARD_GRAVITY_M_S2;
        let a = rec.raw[0].accel_device_m_s2;
        assert!((a[2] - g0).abs() < 1e-3 * g0, "{a:?}");
    }

    /// GNSS time in holdover or lost is a warning, named in the message and the values; locked
    /// is OK.
    #[test]
    fn gnss_holdover_and_loss_warn_in_the_diagnostics() {
        let streaming = DaemonStatus {
            device_connected: 1,
            calibration_id: 7,
            time_source: imu_bus::sample::time_source::GNSS,
            ..DaemonStatus::default()
        };
        let value = |a: &DiagnosticArray, key: &str| {
            a.status[0]
                .values
                .iter()
                .find(|kv| kv.key == key)
                .map(|kv| kv.value.clone())
        };
        for (state, level, name) in [
            (time_sync::GNSS_LOCKED, DiagnosticLevel::Ok, "gnss-locked"),
            (
                time_sync::GNSS_HOLDOVER,
                DiagnosticLevel::Warn,
                "gnss-holdover",
            ),
            (time_sync::GNSS_LOST, DiagnosticLevel::Warn, "gnss-lost"),
        ] {
            let s = DaemonStatus {
                time_sync: state,
                ..streaming
            };
            let a = diagnostics(0, &s, Ros2Stats::default(), "imud", "imu0");
            assert_eq!(a.status[0].level, level, "{name}");
            assert_eq!(value(&a, "time_sync").as_deref(), Some(name));
            assert_eq!(value(&a, "time_source").as_deref(), Some("gnss"));
            if level == DiagnosticLevel::Warn {
                assert!(a.status[0].message.contains("GNSS time"), "{name}");
            }
        }
    }
}
