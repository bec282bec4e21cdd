//! Tests of the recorder: topics, rotation, flushes, disk-full handling, read-back.

use super::*;

#[test]
fn a_recorder_can_be_shared_between_threads() {
    fn send_sync<T: Send + Sync>() {}
    send_sync::<Recorder>();
    send_sync::<LogRecord>();
}

#[test]
fn utc_stamps() {
    let at = |s: u64| utc_stamp(UNIX_EPOCH + Duration::from_secs(s));
    assert_eq!(at(0), "19700101T000000Z");
    assert_eq!(at(951_782_400), "20000229T000000Z");
    assert_eq!(at(1_700_000_000), "20231114T221320Z");
    assert_eq!(at(4_102_444_799), "20991231T235959Z");
    assert_eq!(utc_iso8601_ns(0), "1970-01-01T00:00:00.000000000Z");
    assert_eq!(
        utc_iso8601_ns(1_700_000_000_123_456_789),
        "2023-11-14T22:13:20.123456789Z"
    );
    assert_eq!(
        utc_iso8601_ns(951_868_799_000_000_001),
        "2000-02-29T23:59:59.000000001Z"
    );
}

#[test]
fn bad_configs_are_refused_with_the_reason() {
    let cases = [
        RecordingConfig {
            flush_interval: Duration::from_secs(2),
            ..RecordingConfig::default()
        },
        RecordingConfig {
            queue_capacity: 0,
            ..RecordingConfig::default()
        },
        RecordingConfig {
            rotate_interval_s: f64::NAN,
            ..RecordingConfig::default()
        },
        RecordingConfig {
            prefix: "a/b".into(),
            ..RecordingConfig::default()
        },
    ];
    for config in cases {
        let err = Recorder::start(config.clone(), Vec::new())
            .err()
            .unwrap_or_else(|| panic!("{config:?} accepted"));
        assert!(err.to_string().starts_with("recording config: "), "{err}");
    }
    assert!(RecordingConfig::default().validate().is_ok());
}

#[test]
fn imu_and_mag_messages_follow_the_conventions() {
    let s = CorrectedSample {
        t_wall_ns: 1_700_000_000_000_000_001,
        accel_m_s2: [0.1, 0.2, -9.8],
        gyro_rad_s: [0.01, 0.02, 0.03],
        mag_gauss: [0.2, -0.4, 0.5],
        ..CorrectedSample::default()
    };
    let imu = imu_message(&s, "f", None);
    assert_eq!(imu.orientation_covariance[0], -1.0);
    assert_eq!(imu.orientation, Quaternion::default());
    assert_eq!(imu.angular_velocity_covariance, [0.0; 9]);
    assert_eq!(imu.header.stamp.to_ns(), s.t_wall_ns);
    let noise = ImuNoiseVariances {
        accel_var_m2_s4: [1.0, 2.0, 3.0],
        gyro_var_rad2_s2: [4.0, 5.0, 6.0],
        mag_var_t2: [7.0, 8.0, 9.0],
    };
    let imu = imu_message(&s, "f", Some(&noise));
    assert_eq!(
        imu.linear_acceleration_covariance,
        [1.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 3.0]
    );
    assert_eq!(imu.angular_velocity_covariance[8], 6.0);
    let mag = magnetic_field_message(&s, "f", Some(&noise));
    assert_eq!(
        <[f64; 3]>::from(mag.magnetic_field),
        [0.2 * 1e-4, -0.4 * 1e-4, 0.5 * 1e-4]
    );
    assert_eq!(mag.magnetic_field_covariance[4], 8.0);
}
