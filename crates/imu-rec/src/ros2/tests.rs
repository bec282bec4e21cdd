//! Round trips and byte layouts of the CDR messages.

use super::*;

fn header(frame_id: &str) -> Header {
    Header {
        stamp: Time {
            sec: 1_700_000_000,
            nanosec: 123_456_789,
        },
        frame_id: frame_id.into(),
    }
}

fn imu() -> Imu {
    Imu {
        header: header("imu_link"),
        orientation: Quaternion::default(),
        orientation_covariance: NOT_PROVIDED_COVARIANCE,
        angular_velocity: [0.01, -0.02, 0.03].into(),
        angular_velocity_covariance: diagonal_covariance([1e-6, 2e-6, 3e-6]),
        linear_acceleration: [0.1, -0.2, -9.80665].into(),
        linear_acceleration_covariance: [0.0; 9],
    }
}

#[test]
fn imu_golden_bytes() {
    let bytes = imu().to_cdr();
    // Hand-checked layout: 4 header bytes, then offsets relative to byte 4:
    // 0 sec, 4 nanosec, 8 string length (9 = "imu_link" + NUL), 12..20 text, 20 NUL,
    // 21..24 padding to 8, 24 orientation (4 x f64), 56 covariance (9 x f64), 128 angular
    // velocity, 152 covariance, 224 linear acceleration, 248 covariance, 320 end.
    assert_eq!(bytes.len(), 4 + 320);
    let mut expected_head = vec![0x00, 0x01, 0x00, 0x00];
    expected_head.extend_from_slice(&1_700_000_000i32.to_le_bytes());
    expected_head.extend_from_slice(&123_456_789u32.to_le_bytes());
    expected_head.extend_from_slice(&[9, 0, 0, 0]);
    expected_head.extend_from_slice(b"imu_link\0");
    expected_head.extend_from_slice(&[0, 0, 0]);
    assert_eq!(&bytes[..28], &expected_head[..]);
    assert_eq!(
        &bytes[4..16],
        &[
            0x00, 0xF1, 0x53, 0x65, 0x15, 0xCD, 0x5B, 0x07, 0x09, 0x00, 0x00, 0x00
        ]
    );
    let f64_at = |rel: usize| f64::from_le_bytes(bytes[4 + rel..12 + rel].try_into().unwrap());
    assert_eq!(
        [f64_at(24), f64_at(32), f64_at(40), f64_at(48)],
        [0.0, 0.0, 0.0, 1.0]
    );
    assert_eq!(f64_at(56), -1.0);
    assert_eq!(f64_at(128), 0.01);
    assert_eq!(f64_at(152), 1e-6);
    assert_eq!(f64_at(152 + 32), 2e-6);
    assert_eq!(f64_at(224 + 16), -9.80665);
    assert_eq!(f64_at(312), 0.0);
}

#[test]
fn empty_frame_id_pads_to_the_next_eight() {
    let mut m = imu();
    m.header.frame_id.clear();
    let bytes = m.to_cdr();
    // 8 stamp, 4 length (1), 1 NUL, 3 padding: orientation at relative 16.
    assert_eq!(&bytes[12..20], &[1, 0, 0, 0, 0, 0, 0, 0]);
    assert_eq!(bytes.len(), 4 + 16 + 296);
    assert_eq!(Imu::from_cdr(&bytes).unwrap(), m);
}

fn round_trip<M: RosMessage + PartialEq + std::fmt::Debug>(m: &M) {
    round_trip_with_legacy_prefix(m, &[]);
}

/// [`round_trip`], where a prefix of `legacy_len` bytes is an older schema's whole message.
fn round_trip_with_legacy_prefix<M: RosMessage + PartialEq + std::fmt::Debug>(
    m: &M,
    legacy_lens: &[usize],
) {
    let bytes = m.to_cdr();
    assert_eq!(&M::from_cdr(&bytes).unwrap(), m);
    // Every strict prefix is an error, never a panic (no message here ends in padding).
    for n in (0..bytes.len()).filter(|n| !legacy_lens.contains(n)) {
        assert!(
            M::from_cdr(&bytes[..n]).is_err(),
            "{} decoded from {n} bytes",
            M::DEFINITION.type_name
        );
    }
}

// One message of every type with every field set: a flat table, which is why it is long.
#[test]
fn every_type_round_trips_and_rejects_truncation() {
    round_trip(&imu());
    round_trip(&Temperature {
        header: header("imu_link"),
        temperature: 24.5,
        variance: 0.0,
    });
    round_trip(&MagneticField {
        header: header("x"),
        magnetic_field: [2.2e-5, -4.2e-5, 1e-6].into(),
        magnetic_field_covariance: diagonal_covariance([1e-14, 2e-14, 3e-14]),
    });
    // A v1 RawSample ended before the device reading (three f64 arrays).
    let raw_v2_len = RawSampleMsg {
        header: header("imu_link"),
        ..RawSampleMsg::default()
    }
    .to_cdr()
    .len();
    round_trip_with_legacy_prefix(
        &RawSampleMsg {
            header: header("imu_link"),
            sample: RawSample {
                seq: 42,
                t_device_ns: 1,
                t_host_monotonic_ns: 2,
                t_host_wall_ns: 3,
                t_sample_ns: 4,
                ticks_unwrapped: 70_000,
                accel_counts: [32768, 1, -5],
                gyro_counts: [65535, 0, 7],
                mag_counts: [-32768, 2, 3],
                temp_c: 25.25,
                ticks: 4464,
                command: 0x0C,
                reserved: 0,
                flags: raw_flags::SATURATED | raw_flags::GAP_BEFORE,
                accel_device_m_s2: [0.25, -9.75, 1e-3],
                gyro_device_rad_s: [1e-4, 2.5, -0.125],
                mag_device_gauss: [0.2, -0.4, 0.5],
            },
        },
        &[raw_v2_len - 72],
    );
    round_trip(&RawFrameMsg {
        header: header("imu_link"),
        t_host_monotonic_ns: 5,
        stream_offset: 1234,
        accepted: false,
        reject_reason: "bad-checksum".into(),
        data: vec![0x0C, 1, 2, 3, 0xFF],
    });
    // A v2 status ended before the MIP counters (two u64), a v3 one before the time sync (8
    // bytes, two f64 and two u64).
    let status_v4_len = DaemonStatusMsg {
        header: header(""),
        ..DaemonStatusMsg::default()
    }
    .to_cdr()
    .len();
    round_trip_with_legacy_prefix(
        &DaemonStatusMsg {
            header: header(""),
            status: DaemonStatus {
                t_host_monotonic_ns: 9,
                frames: 1,
                samples: 2,
                checksum_failures: 3,
                resyncs: 4,
                garbage_bytes: 5,
                truncated_frames: 6,
                samples_lost: 7,
                log_drops: 8,
                publish_drops: 9,
                reconnects: 10,
                calibration_id: 0xDEAD_BEEF,
                tick_period_est_s: 0.0065536,
                clock_drift_ppm: -12.5,
                temp_c: 30.0,
                device_connected: 1,
                logging: 1,
                gains_fallback: 2,
                health_accel: 2,
                health_gyro: 3,
                protocol: 1,
                configuration_unverified: 1,
                reserved: 2,
                clock_offset_s: 1234.5,
                clock_residual_s: 2.5e-4,
                gain_scale_accel: 8500,
                gain_scale_gyro: 10_000,
                gain_scale_mag: 2000,
                reserved_end: [6, 7],
                packets_unusable: 11,
                fields_skipped: 12,
                time_source: 2,
                time_sync: 3,
                reserved_sync: [1, 2, 3, 4, 5, 6],
                gnss_minus_wall_s: -0.125,
                gnss_drift_ppm: 150.5,
                gnss_valid_transitions: 13,
                gnss_lost_transitions: 14,
            },
        },
        &[status_v4_len - 40 - 16, status_v4_len - 40],
    );
    round_trip(&CalibrationMsg {
        header: header("imu_link"),
        id: "abc123".into(),
        toml: "format = \"imu-model/1\"\n# µ".into(),
    });
}

#[test]
fn a_v1_raw_sample_without_the_device_reading_reads_with_nan_there() {
    let v2 = RawSampleMsg {
        header: header("imu_link"),
        sample: RawSample {
            seq: 7,
            accel_counts: [1, 2, 3],
            flags: raw_flags::GAP_BEFORE,
            accel_device_m_s2: [1.0; 3],
            ..RawSample::default()
        },
    };
    let bytes = v2.to_cdr();
    // v1 ended at `flags`: the three f64 arrays (72 bytes) go (no padding precedes them with
    // this frame id).
    let v1_len = bytes.len() - 72;
    {
        let back = RawSampleMsg::from_cdr(&bytes[..v1_len]).unwrap();
        assert_eq!(back.sample.seq, 7);
        assert_eq!(back.sample.accel_counts, [1, 2, 3]);
        assert_eq!(back.sample.flags, raw_flags::GAP_BEFORE);
        assert!(back.sample.accel_device_m_s2.iter().all(|v| v.is_nan()));
        assert!(back.sample.mag_device_gauss.iter().all(|v| v.is_nan()));
    }
    // Cut inside the new fields: an error, not a silent NaN.
    assert!(RawSampleMsg::from_cdr(&bytes[..bytes.len() - 8]).is_err());
}

#[test]
fn nan_survives_the_round_trip() {
    let m = RawSampleMsg {
        sample: RawSample {
            temp_c: f64::NAN,
            ..RawSample::default()
        },
        ..RawSampleMsg::default()
    };
    let back = RawSampleMsg::from_cdr(&m.to_cdr()).unwrap();
    assert!(back.sample.temp_c.is_nan());
}

#[test]
fn bad_input_is_an_error_with_its_place() {
    assert_eq!(
        Imu::from_cdr(&[0x00, 0x00, 0x00, 0x00]).unwrap_err(),
        CdrError::BadEncapsulation {
            found: vec![0, 0, 0, 0]
        }
    );
    let mut bytes = CalibrationMsg {
        header: header("f"),
        id: "id".into(),
        toml: String::new(),
    }
    .to_cdr();
    // Make the id's terminating NUL a letter.
    let nul = bytes.iter().rposition(|&b| b == b'd').unwrap() + 1;
    bytes[nul] = b'x';
    let err = CalibrationMsg::from_cdr(&bytes).unwrap_err();
    assert!(
        matches!(err, CdrError::BadString { field: "id", .. }),
        "{err}"
    );
    // A huge length never allocates or panics.
    let mut bytes = RawFrameMsg::default().to_cdr();
    let n = bytes.len();
    bytes[n - 4..].copy_from_slice(&u32::MAX.to_le_bytes());
    let err = RawFrameMsg::from_cdr(&bytes).unwrap_err();
    assert!(
        matches!(err, CdrError::Truncated { field: "data", .. }),
        "{err}"
    );
    assert!(err.to_string().contains("`data`"), "{err}");
}

#[test]
fn time_conversions() {
    let t = Time::from_ns(1_700_000_000_123_456_789);
    assert_eq!((t.sec, t.nanosec), (1_700_000_000, 123_456_789));
    assert_eq!(t.to_ns(), 1_700_000_000_123_456_789);
    assert_eq!(Time::from_ns(u64::MAX).sec, i32::MAX);
    assert_eq!(
        Time {
            sec: -1,
            nanosec: 0
        }
        .to_ns(),
        0
    );
}

/// Every non-primitive field type named in a schema has its own `MSG:` section, each
/// section appears once, and separators are exactly 80 `=`.
fn check_schema(def: &MsgDefinition) {
    const PRIMITIVES: &[&str] = &[
        "bool", "byte", "char", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64",
        "uint64", "float32", "float64", "string", "wstring",
    ];
    let text = def.schema_text();
    let sections: Vec<&str> = text.split(&format!("{DEFINITION_SEPARATOR}\n")).collect();
    let mut names = vec![def.type_name.to_string()];
    for s in &sections[1..] {
        let first = s.lines().next().unwrap();
        let name = first.strip_prefix("MSG: ").expect("MSG: line");
        assert_eq!(name.split('/').count(), 3, "{name}");
        assert!(!names.contains(&name.to_string()), "{name} twice");
        names.push(name.to_string());
    }
    for line in text.lines() {
        assert!(
            !line.starts_with('=') || line == DEFINITION_SEPARATOR,
            "bad separator {line:?}"
        );
        let line = line.split('#').next().unwrap().trim();
        if line.is_empty() || line.starts_with("MSG:") || line.starts_with('=') {
            continue;
        }
        let ty = line.split_whitespace().next().unwrap();
        let base = ty.split('[').next().unwrap();
        if PRIMITIVES.contains(&base) {
            continue;
        }
        let (pkg, name) = base.split_once('/').expect("package-qualified type");
        let full = format!("{pkg}/msg/{name}");
        assert!(
            names.contains(&full),
            "{} uses {full} without MSG section",
            def.type_name
        );
    }
}

#[test]
fn schemas_are_complete_ros2msg_text() {
    for def in [
        &IMU_DEF,
        &TEMPERATURE_DEF,
        &MAGNETIC_FIELD_DEF,
        &RAW_SAMPLE_DEF,
        &RAW_FRAME_DEF,
        &DAEMON_STATUS_DEF,
        &CALIBRATION_DEF,
        &CALIBRATION_HEALTH_DEF,
        &DIAGNOSTIC_ARRAY_DEF,
    ] {
        check_schema(def);
    }
    let imu = IMU_DEF.schema_text();
    assert!(imu.starts_with("# If you have no estimate"));
    assert!(imu.contains(&format!(
        "\n{DEFINITION_SEPARATOR}\nMSG: std_msgs/msg/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n"
    )));
    assert!(imu.contains(&format!(
        "\n{DEFINITION_SEPARATOR}\nMSG: builtin_interfaces/msg/Time\nint32 sec\nuint32 nanosec\n"
    )));
    assert_eq!(imu.matches("MSG: ").count(), 4);
    assert_eq!(DEFINITION_SEPARATOR.len(), 80);
}

#[test]
fn diagnostics_round_trip_with_their_sequences() {
    let array = DiagnosticArray {
        header: header(""),
        status: vec![
            DiagnosticStatus {
                level: DiagnosticLevel::Warn,
                name: "imud: imu0".into(),
                message: "device disconnected".into(),
                hardware_id: "3DM-GX1 serial 1234".into(),
                values: vec![
                    KeyValue {
                        key: "samples".into(),
                        value: "1000".into(),
                    },
                    KeyValue {
                        key: "temp_c".into(),
                        value: "24.5".into(),
                    },
                ],
            },
            DiagnosticStatus::default(),
        ],
    };
    round_trip(&array);
    let bytes = array.to_cdr();
    // 8 stamp, 4 + 1 empty frame id, 3 padding, then the sequence count 2 and the first level.
    assert_eq!(&bytes[4 + 16..4 + 21], &[2, 0, 0, 0, 1]);
    // An unknown level byte reads as STALE, never an error.
    let mut unknown = bytes.clone();
    unknown[4 + 20] = 9;
    let back = DiagnosticArray::from_cdr(&unknown).unwrap();
    assert_eq!(back.status[0].level, DiagnosticLevel::Stale);
}

#[test]
fn dds_type_names_follow_the_ros2_middleware_mangling() {
    assert_eq!(IMU_DEF.dds_type_name(), "sensor_msgs::msg::dds_::Imu_");
    assert_eq!(
        DIAGNOSTIC_ARRAY_DEF.dds_type_name(),
        "diagnostic_msgs::msg::dds_::DiagnosticArray_"
    );
    assert_eq!(
        TIME_DEF.dds_type_name(),
        "builtin_interfaces::msg::dds_::Time_"
    );
}

#[test]
fn a_v3_status_without_the_time_sync_reads_as_device_time_unknown_there() {
    let v4 = DaemonStatusMsg {
        header: header(""),
        status: DaemonStatus {
            frames: 5,
            fields_skipped: 9,
            time_source: 2,
            time_sync: 2,
            gnss_minus_wall_s: 0.5,
            gnss_drift_ppm: 1.0,
            gnss_valid_transitions: 1,
            ..DaemonStatus::default()
        },
    };
    let bytes = v4.to_cdr();
    // v3 ended at `fields_skipped`: 8 bytes, two f64 and two u64 go.
    let back = DaemonStatusMsg::from_cdr(&bytes[..bytes.len() - 40]).unwrap();
    assert_eq!(back.status.frames, 5);
    assert_eq!(back.status.fields_skipped, 9);
    assert_eq!(back.status.time_source, crate::sample::time_source::DEVICE);
    assert_eq!(back.status.time_sync, crate::sample::time_sync::NONE);
    assert!(back.status.gnss_minus_wall_s.is_nan() && back.status.gnss_drift_ppm.is_nan());
    assert_eq!(back.status.gnss_valid_transitions, 0);
}
