//! Tests of the simulated VectorNav unit: power-up output, register reads and writes as the
//! codec decodes them, refused configurations, and binary messages against the truth.

use imu_model::Calibration;
use imu_proto::vectornav::{BinaryMessage, VnDecoder, VnEvent};

use super::*;
use crate::Scenario;

fn scenario(rate_hz: f64, extra: &str) -> Scenario {
    let text = format!(
        "name = \"vn-unit\"\nrate-hz = {rate_hz:?}\n[device]\nprotocol = \"vectornav\"\n\
         serial-number = 77\nfirmware = 2104\nclock-drift-ppm = 50.0\n{extra}\n\
         [[segment]]\nkind = \"static\"\nduration-s = 2.0\n"
    );
    Scenario::from_toml_str(&text, "vn-unit.toml").unwrap()
}

fn device(rate_hz: f64, extra: &str) -> VnDevice {
    VnDevice::new(DeviceCore::new(
        scenario(rate_hz, extra),
        Calibration::identity(),
        1,
    ))
}

/// Sends `cmd` as the host would and returns the unit's single reply.
fn ask(d: &mut VnDevice, cmd: &VnCommand) -> VnReply {
    d.push(cmd.to_sentence(Check::Checksum8).as_bytes());
    let request = d.next_request().expect("a request").expect("a sentence");
    assert!(d.next_request().is_none());
    let mut dec = VnDecoder::new();
    dec.push(&d.handle(request));
    let Some(VnEvent::Ascii { sentence, .. }) = dec.next_event() else {
        panic!("no reply sentence")
    };
    VnReply::decode(&sentence).unwrap()
}

/// Every event of what the unit streams over `n` samples from `t0_s`.
fn stream(d: &mut VnDevice, n: usize) -> (Vec<VnEvent>, Vec<TruthSample>) {
    let rate = d.core().scenario().rate_hz;
    let mut out = Vec::new();
    let truth: Vec<_> = (0..n)
        .filter_map(|k| d.stream_sample(k as f64 / rate, &mut out))
        .collect();
    let mut dec = VnDecoder::new();
    dec.push(&out);
    let events: Vec<_> = std::iter::from_fn(|| dec.next_event()).collect();
    assert_eq!(dec.stats().rejected_bytes, 0);
    (events, truth)
}

#[test]
fn powers_up_streaming_ypr_at_40_hz_and_stops_on_register_6() {
    let mut d = device(200.0, "");
    assert!(d.is_streaming());
    assert_eq!(d.active_output(), None);
    let (events, truth) = stream(&mut d, 200);
    assert!(truth.is_empty(), "no binary output, no truth");
    assert_eq!(events.len(), 40, "one second of YPR at 40 Hz");
    let VnEvent::Ascii { sentence, .. } = &events[0] else {
        panic!("{:?}", events[0])
    };
    let VnReply::Ypr([_, pitch, roll]) = VnReply::decode(sentence).unwrap() else {
        panic!("not YPR")
    };
    assert!(pitch.abs() < 1e-3 && roll.abs() < 1e-3, "level");
    let off = ask(&mut d, &VnCommand::Write(Register::AsyncOutputType(0)));
    assert_eq!(off, VnReply::Written(Register::AsyncOutputType(0)));
    assert!(!d.is_streaming());
}

#[test]
fn identifies_and_applies_a_binary_output() {
    let mut d = device(100.0, "model = \"VN-200T-CR\"");
    assert_eq!(
        ask(&mut d, &VnCommand::Read(reg::MODEL)),
        VnReply::Read(Register::Model("VN-200T-CR".into()))
    );
    assert_eq!(
        ask(&mut d, &VnCommand::Read(reg::SERIAL_NUMBER)),
        VnReply::Read(Register::SerialNumber(77))
    );
    assert_eq!(
        ask(&mut d, &VnCommand::Read(reg::FIRMWARE)),
        VnReply::Read(Register::Firmware("2.1.4.0".into()))
    );
    ask(&mut d, &VnCommand::Write(Register::AsyncOutputType(0)));
    let config = BinaryOutputConfig {
        async_mode: 1,
        rate_divisor: 8,
        fields: default_fields(true),
    };
    let write = Register::BinaryOutput { index: 1, config };
    assert_eq!(
        ask(&mut d, &VnCommand::Write(write.clone())),
        VnReply::Written(write.clone())
    );
    assert_eq!(ask(&mut d, &VnCommand::Read(75)), VnReply::Read(write));
    let (events, truth) = stream(&mut d, 100);
    assert_eq!((events.len(), truth.len()), (100, 100));
    for (e, t) in events.iter().zip(&truth) {
        let VnEvent::Binary { message, .. } = e else {
            panic!("{e:?}")
        };
        let data = message.data();
        // The uncompensated outputs are the measured values, the compensated ones the truth
        // (identity truth model, no noise here: equal), to f32 rounding.
        for k in 0..3 {
            let close = |a: f32, b: f64| (f64::from(a) - b).abs() <= 1e-6 * (1.0 + b.abs());
            assert!(close(
                data.uncomp_accel_m_s2.unwrap()[k],
                t.measured_accel_m_s2[k]
            ));
            assert!(close(
                data.uncomp_gyro_rad_s.unwrap()[k],
                t.measured_gyro_rad_s[k]
            ));
            assert!(close(data.accel_m_s2.unwrap()[k], t.specific_force_m_s2[k]));
            assert!(close(
                data.angular_rate_rad_s.unwrap()[k],
                t.angular_rate_rad_s[k]
            ));
        }
        assert_eq!(
            data.startup_ns,
            Some(t.ticks_unwrapped),
            "truth keyed by startup time"
        );
        assert!(data.time_status.unwrap().gps_valid());
        let unix_ns = imu_proto::gnss_time::gps_ns_to_unix_ns(data.gps_ns.unwrap());
        let expected = GPS_START_UNIX_NS + (t.t_s * 1e9).round() as i64;
        assert_eq!(unix_ns, expected, "GPS time is true time");
    }
    // The startup time runs on the drifting oscillator: 50 ppm fast.
    let span_ns = (truth[99].ticks_unwrapped - truth[0].ticks_unwrapped) as f64;
    let true_ns = (truth[99].t_s - truth[0].t_s) * 1e9;
    assert!(
        (span_ns / true_ns - 1.0 - 50e-6).abs() < 1e-8,
        "{}",
        span_ns / true_ns
    );
}

#[test]
fn saved_binary_output_streams_from_power_up_without_gnss_on_a_vn100() {
    let mut d = device(800.0, "power-up-streaming = true");
    assert_eq!(d.model(), DEFAULT_MODEL);
    let active = *d.active_output().unwrap();
    assert_eq!(
        (active.rate_divisor, active.fields),
        (1, default_fields(false))
    );
    let (events, truth) = stream(&mut d, 10);
    assert_eq!(truth.len(), 10);
    assert!(events.iter().all(|e| matches!(e, VnEvent::Binary { .. })));
    // Asked for GPS time, a VN-100 sends it invalid.
    let mut fields = default_fields(false);
    fields.words[group::TIME] = time::TIME_GPS | time::TIME_STATUS;
    let (m, _) = d.data_message(fields, 0.5);
    let back = BinaryMessage::parse(m.as_bytes()).unwrap();
    assert!(!back.data().time_status.unwrap().gps_valid());
}

#[test]
fn unusable_writes_are_refused_and_change_nothing() {
    let mut d = device(100.0, "");
    let before = d.read(75).unwrap();
    let wrong_rate = Register::BinaryOutput {
        index: 1,
        config: BinaryOutputConfig {
            async_mode: 1,
            rate_divisor: 1,
            fields: default_fields(false),
        },
    };
    assert_eq!(
        ask(&mut d, &VnCommand::Write(wrong_rate)),
        VnReply::Error(error_code::INVALID_PARAMETER)
    );
    let mut attitude = default_fields(false);
    attitude.words[group::ATTITUDE] = 0x0004;
    let unfillable = Register::BinaryOutput {
        index: 1,
        config: BinaryOutputConfig {
            async_mode: 1,
            rate_divisor: 8,
            fields: attitude,
        },
    };
    assert_eq!(
        ask(&mut d, &VnCommand::Write(unfillable)),
        VnReply::Error(error_code::INVALID_PARAMETER)
    );
    assert_eq!(d.read(75).unwrap(), before);
    assert_eq!(
        ask(&mut d, &VnCommand::Write(Register::SerialNumber(1))),
        VnReply::Error(error_code::UNAUTHORIZED_ACCESS)
    );
    assert_eq!(
        ask(&mut d, &VnCommand::Read(11)),
        VnReply::Error(error_code::INVALID_REGISTER)
    );
    // A bad checksum is answered with error 3, garbage before it counted.
    d.push(b"\x00\x01$VNRRG,01*00\r\n");
    assert_eq!(d.next_request(), Some(Err(2)));
    assert_eq!(d.next_request(), Some(Err(14)));
    let Some(Ok(request)) = d.next_request() else {
        panic!("no error request")
    };
    assert_eq!(request, Err(error_code::INVALID_CHECKSUM));
}

#[test]
fn same_scenario_and_seed_give_the_gx1_s_measurements() {
    let s = scenario(200.0, "power-up-streaming = true");
    let mut truth_model = Calibration::identity();
    truth_model.gyro.noise = Some(imu_model::NoiseModel {
        white_density: [1e-4; 3],
        ..Default::default()
    });
    let mut gx1 = DeviceCore::new(s.clone(), truth_model.clone(), 9);
    let mut vn = VnDevice::new(DeviceCore::new(s, truth_model, 9));
    let mut out = Vec::new();
    for k in 0..300 {
        let t_s = k as f64 / 200.0;
        let (_, a) = gx1.data_reply(imu_proto::Command::RawSensorBits, t_s);
        let b = vn.stream_sample(t_s, &mut out).unwrap();
        assert_eq!(a.measured_gyro_rad_s, b.measured_gyro_rad_s, "sample {k}");
        assert_eq!((a.seq, a.t_s), (b.seq, b.t_s));
    }
}
