//! Golden vectors from public sources, whole-message errors, the decoder's resync and byte
//! accounting, and property round trips of every command, reply and data message.

use proptest::prelude::*;

use super::command::error_name;
use super::data::{UTC_VALID, id};
use super::message::checksum;
use super::*;
use crate::RejectReason;

fn hex(s: &str) -> Vec<u8> {
    s.split_whitespace()
        .map(|h| u8::from_str_radix(h, 16).unwrap())
        .collect()
}

fn drain(d: &mut XsensDecoder) -> Vec<XsensEvent> {
    std::iter::from_fn(|| d.next_event()).collect()
}

fn messages(events: &[XsensEvent]) -> Vec<Message> {
    events
        .iter()
        .filter_map(|e| match e {
            XsensEvent::Packet { packet, .. } => Some(packet.clone()),
            XsensEvent::Rejected { .. } => None,
        })
        .collect()
}

/// Packet example 4 of xsens-mti `docs/mtmanager_packets.md` (an MTi-300 with MT Manager):
/// the MTData2 data with packet counter, sample time fine, quaternion, acceleration, delta v,
/// free acceleration, rate of turn, delta q, magnetic field, temperature, pressure, status.
const EXAMPLE_4: &str = "10 20 02 91 8D 10 60 04 01 36 3F A6 20 10 10 3F 35 E0 42 3F 31 CD \
    15 BD 9F 49 DB BD A9 38 CF 40 20 0C BD 63 5A 90 41 1D 08 D4 3E 5F AA 50 40 10 0C B9 11 68 \
    00 3C C9 01 00 3A 0F 7D 00 40 30 0C BC 3B 29 80 3C 35 FC 00 3C A4 6E 00 80 20 0C 3C AE A2 \
    41 BB 56 D8 00 BA D5 AC 01 80 30 10 3F 80 00 00 37 DF 88 01 B6 89 80 00 B6 08 C0 00 C0 20 \
    0C BE FB FB F2 3F 33 C4 85 BF A0 A2 C1 08 10 04 42 16 80 00 30 10 04 00 01 86 E1 E0 20 04 \
    00 40 00 03";

#[test]
fn golden_requests_encode_as_documented() {
    // xsens-mti test/test_xsens_mti_send.c and docs/mtmanager_packets.md.
    let cases = [
        (XsensCommand::GoToConfig, "FA FF 30 00 D1"),
        (XsensCommand::GoToMeasurement, "FA FF 10 00 F1"),
        (XsensCommand::ReqDeviceId, "FA FF 00 00 01"),
        (XsensCommand::ReqProductCode, "FA FF 1C 00 E5"),
        (XsensCommand::ReqFirmwareRev, "FA FF 12 00 EF"),
    ];
    for (cmd, wire) in cases {
        let msg = cmd.to_message();
        assert_eq!(msg.as_bytes(), hex(wire), "{cmd:?}");
        assert_eq!(
            XsensCommand::decode(&Message::parse(&hex(wire)).unwrap()),
            Ok(cmd)
        );
    }
    // WakeUp, as a unit sends it at power-up.
    assert_eq!(
        XsensReply::WakeUp.to_message().as_bytes(),
        hex("FA FF 3E 00 C3")
    );
}

#[test]
fn golden_set_output_configuration_of_mt_manager() {
    // test_set_configuration_2: twelve outputs sniffed from MT Manager and an MTi-300.
    let wire = hex(
        "FA FF C0 30 10 20 FF FF 10 60 FF FF 20 10 01 90 40 20 01 90 40 10 01 90 40 30 01 90 \
         80 20 01 90 80 30 01 90 C0 20 00 64 08 10 00 0A 30 10 00 32 E0 20 FF FF 99",
    );
    let msg = Message::parse(&wire).unwrap();
    let XsensCommand::SetOutputConfiguration(config) = XsensCommand::decode(&msg).unwrap() else {
        panic!("not a configuration");
    };
    assert_eq!(config.0.len(), 12);
    assert_eq!(
        config.0[3],
        OutputSetting {
            data_id: id::ACCELERATION,
            rate_hz: 400
        }
    );
    assert_eq!(config.0[9].rate_hz, 10);
    assert_eq!(
        XsensCommand::SetOutputConfiguration(config)
            .to_message()
            .as_bytes(),
        wire
    );
    // test_set_configuration_3: format bits 1 (fp1220) and 2 (fp1632) in the ids.
    let wire = hex(
        "FA FF C0 1C 10 20 FF FF 20 10 00 C8 80 21 00 64 C0 22 00 64 08 10 00 01 30 10 00 02 \
         E0 20 FF FF 5B",
    );
    let XsensCommand::SetOutputConfiguration(config) =
        XsensCommand::decode(&Message::parse(&wire).unwrap()).unwrap()
    else {
        panic!("not a configuration");
    };
    assert_eq!(DataId(config.0[2].data_id).format(), Format::Fp1220);
    assert_eq!(DataId(config.0[3].data_id).format(), Format::Fp1632);
    assert_eq!(DataId(config.0[3].data_id).base(), id::MAGNETIC_FIELD);
}

#[test]
fn golden_replies_of_mt_manager_session() {
    // docs/mtmanager_packets.md, "Configuration Response".
    let ack = Message::parse(&hex("FA FF 31 00 D0")).unwrap();
    assert_eq!(XsensReply::decode(&ack), Ok(XsensReply::GoToConfigAck));
    let config = Message::parse(&hex("FA FF C1 08 10 20 FF FF 10 60 FF FF 9C")).unwrap();
    assert_eq!(
        XsensReply::decode(&config),
        Ok(XsensReply::OutputConfiguration(OutputConfiguration(vec![
            OutputSetting {
                data_id: id::PACKET_COUNTER,
                rate_hz: 0xFFFF
            },
            OutputSetting {
                data_id: id::SAMPLE_TIME_FINE,
                rate_hz: 0xFFFF
            },
        ])))
    );
    let fw = hex("FA FF 13 0B 01 08 02 00 00 00 25 00 01 15 34 69");
    let fw = XsensReply::decode(&Message::parse(&fw).unwrap()).unwrap();
    let XsensReply::FirmwareRev(rev) = fw else {
        panic!("{fw:?}")
    };
    assert_eq!(rev.to_string(), "1.8.2 build 37 rev 70964");
    assert_eq!(
        XsensReply::FirmwareRev(rev).to_message().as_bytes(),
        hex("FA FF 13 0B 01 08 02 00 00 00 25 00 01 15 34 69")
    );
}

#[test]
fn golden_mtdata2_example_decodes_to_the_documented_values() {
    let data = hex(EXAMPLE_4);
    assert_eq!(data.len(), 0x92);
    let msg = Message::new(mid::MT_DATA2, &data).unwrap();
    // Reframed by the decoder after garbage, then decoded.
    let mut d = XsensDecoder::new();
    d.push(&[0xFA, 0x00]);
    d.push(msg.as_bytes());
    let got = messages(&drain(&mut d));
    assert_eq!(got, std::slice::from_ref(&msg));
    let m = MtData2::decode(&got[0]).unwrap();
    assert_eq!(m.packet_counter, Some(37261));
    assert_eq!(m.sample_time_fine, Some(20332454));
    let close = |a: [f64; 3], b: [f64; 3]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-7);
    assert!(close(
        m.acceleration_m_s2.unwrap(),
        [-0.05550629, 9.81465530, 0.21842313]
    ));
    assert!(close(
        m.rate_of_turn_rad_s.unwrap(),
        [0.02131760, -0.00327826, -0.00163019]
    ));
    assert!(close(
        m.magnetic_field_normalised.unwrap(),
        [-0.49215657, 0.70221740, -1.25496686]
    ));
    assert!(close(
        m.delta_v_m_s.unwrap(),
        [-0.00013867, 0.02453661, 0.00054736]
    ));
    assert_eq!(m.delta_q.unwrap()[0], 1.0);
    assert_eq!(m.temperature_c, Some(37.625));
    assert_eq!(m.status_word, Some(0x0040_0003));
    // Quaternion, free acceleration and pressure are not decoded: skipped and counted.
    assert_eq!((m.unknown_items, m.bad_items), (3, 0));
}

#[test]
fn fixed_point_formats_decode_as_xspublic_does() {
    // fp1220: -1.25 is -1.25 * 2^20; fp1632: fraction u32 first, then the i16 integer part.
    let mut data = Vec::new();
    data.extend_from_slice(
        &DataId::with_format(id::ACCELERATION_HR, Format::Fp1220)
            .0
            .to_be_bytes(),
    );
    data.push(12);
    for v in [-1.25f64, 0.5, 9.75] {
        data.extend_from_slice(&((v * 1048576.0) as i32).to_be_bytes());
    }
    data.extend_from_slice(
        &DataId::with_format(id::RATE_OF_TURN_HR, Format::Fp1632)
            .0
            .to_be_bytes(),
    );
    data.push(18);
    // -1.5 = -2 + 0.5: integer part -2 (0xFFFE), fraction 0x8000_0000.
    data.extend_from_slice(&[0x80, 0, 0, 0, 0xFF, 0xFE]);
    data.extend_from_slice(&[0, 0, 0, 0, 0, 3]);
    data.extend_from_slice(&[0x40, 0, 0, 0, 0, 0]);
    data.extend_from_slice(
        &DataId::with_format(id::TEMPERATURE, Format::Float64)
            .0
            .to_be_bytes(),
    );
    data.push(8);
    data.extend_from_slice(&21.5f64.to_be_bytes());
    let m = MtData2::decode_data(&data).unwrap();
    assert_eq!(m.acceleration_hr_m_s2, Some([-1.25, 0.5, 9.75]));
    assert_eq!(m.rate_of_turn_hr_rad_s, Some([-1.5, 3.0, 0.25]));
    assert_eq!(m.temperature_c, Some(21.5));
}

#[test]
fn utc_time_valid_bit_and_unix_time() {
    let t = UtcTime {
        ns: 250_000_000,
        year: 2017,
        month: 1,
        day: 1,
        hour: 0,
        minute: 0,
        second: 0,
        flags: UTC_VALID,
    };
    assert!(t.valid());
    assert_eq!(t.unix_ns(), Some(1_483_228_800_250_000_000));
    let m = MtData2 {
        utc: Some(UtcTime { flags: 0, ..t }),
        ..MtData2::default()
    };
    let back = MtData2::decode(&m.to_message(Format::Float32)).unwrap();
    assert!(!back.utc.unwrap().valid());
}

#[test]
fn known_items_of_the_wrong_size_and_bad_layouts() {
    // A 3-byte packet counter is skipped and counted; the sample time after it still counts.
    let data = hex("10 20 03 00 01 02 10 60 04 00 00 00 07");
    let m = MtData2::decode_data(&data).unwrap();
    assert_eq!(
        (m.packet_counter, m.sample_time_fine, m.bad_items),
        (None, Some(7), 1)
    );
    assert_eq!(
        MtData2::decode_data(&hex("10 60 05 00 00")),
        Err(XsensError::BadItemLayout {
            offset: 0,
            id: 0x1060
        })
    );
    assert_eq!(
        MtData2::decode_data(&hex("10")),
        Err(XsensError::BadItemLayout { offset: 0, id: 0 })
    );
}

#[test]
fn whole_message_errors_name_the_problem() {
    assert_eq!(Message::parse(&[0xFA, 0xFF]), Err(XsensError::TooShort(2)));
    assert_eq!(
        Message::parse(&hex("FA 01 30 00 D1")),
        Err(XsensError::BadPreamble(0xFA, 0x01))
    );
    assert_eq!(
        Message::parse(&hex("FA FF 30 00 D2")),
        Err(XsensError::BadChecksum(1))
    );
    assert_eq!(
        Message::parse(&hex("FA FF 30 01 D1")),
        Err(XsensError::WrongLength {
            expected: 6,
            found: 5
        })
    );
    assert_eq!(
        Message::parse(&hex("FA FF 36 FF 20 00 00")),
        Err(XsensError::BadExtendedLength(0x2000))
    );
    // The extended form of a short length is taken as it is.
    let mut short_ext = hex("FA FF 36 FF 00 02 10 20");
    short_ext.push(checksum(&short_ext[1..]));
    assert_eq!(Message::parse(&short_ext).unwrap().data(), [0x10, 0x20]);
    let e = XsensReply::decode(&Message::new(0x99, &[]).unwrap()).unwrap_err();
    assert_eq!(e.to_string(), "unknown message id 0x99");
    let e = XsensReply::decode(&Message::new(mid::DEVICE_ID, &[1, 2]).unwrap()).unwrap_err();
    assert!(e.to_string().contains("device id of 4 or 8 bytes"), "{e}");
    assert_eq!(
        XsensReply::decode(&Message::new(mid::ERROR, &[33]).unwrap()),
        Ok(XsensReply::Error(33))
    );
    assert_eq!(error_name(33), "invalid parameter");
}

#[test]
fn extended_length_messages_round_trip() {
    let data: Vec<u8> = (0..600u16).map(|i| i as u8).collect();
    let msg = Message::new(0x0D, &data).unwrap();
    assert_eq!(&msg.as_bytes()[..6], [0xFA, 0xFF, 0x0D, 0xFF, 0x02, 0x58]);
    assert_eq!(msg.data(), data);
    assert_eq!(Message::parse(msg.as_bytes()), Ok(msg.clone()));
    let mut d = XsensDecoder::new();
    for piece in msg.as_bytes().chunks(7) {
        d.push(piece);
    }
    assert_eq!(messages(&drain(&mut d)), [msg]);
    assert_eq!(
        Message::new(1, &vec![0; MAX_DATA_LEN + 1]),
        Err(XsensError::TooLong(MAX_DATA_LEN + 1))
    );
}

#[test]
fn decoder_resyncs_after_garbage_bad_checksum_truncation_and_a_bogus_length() {
    let good = XsensCommand::GoToConfig.to_message();
    let mut stream = vec![0x00, 0xFA, 0x11];
    stream.extend_from_slice(&hex("FA FF 30 00 D2")); // bad checksum, nothing good inside
    stream.extend_from_slice(&hex("FA FF 36 FF FF FF")); // extended length beyond the maximum
    stream.extend_from_slice(&hex("FA FF 12 00")); // cut short by the next message
    stream.extend_from_slice(good.as_bytes());
    let mut d = XsensDecoder::new();
    for b in &stream {
        d.push(std::slice::from_ref(b));
    }
    let kinds: Vec<_> = drain(&mut d)
        .iter()
        .map(|e| match e {
            XsensEvent::Packet { offset, .. } => (*offset, None),
            XsensEvent::Rejected { offset, reason, .. } => (*offset, Some(*reason)),
        })
        .collect();
    assert_eq!(
        kinds,
        [
            (0, Some(RejectReason::Garbage)),
            (3, Some(RejectReason::BadChecksum)),
            (8, Some(RejectReason::Malformed)),
            (14, Some(RejectReason::Truncated)),
            (18, None)
        ]
    );
    let s = d.stats();
    assert_eq!(
        (
            s.frames,
            s.resyncs,
            s.checksum_failures,
            s.truncated_frames,
            s.malformed_frames
        ),
        (1, 1, 1, 1, 1)
    );
    assert_eq!(s.bytes_in, s.frame_bytes + s.rejected_bytes);
}

#[test]
fn decoder_waits_then_flush_reports_a_cut_message() {
    let mut d = XsensDecoder::new();
    d.push(&hex("FA FF 36 10 00 01"));
    assert_eq!(drain(&mut d), []);
    assert_eq!(d.pending_len(), 6);
    d.flush();
    let events = drain(&mut d);
    assert!(matches!(
        &events[..],
        [XsensEvent::Rejected {
            reason: RejectReason::Truncated,
            offset: 0,
            ..
        }]
    ));
    // Bytes after the flush decode normally.
    d.push(XsensCommand::Reset.to_message().as_bytes());
    assert_eq!(messages(&drain(&mut d)).len(), 1);
}

fn arb_config() -> impl Strategy<Value = OutputConfiguration> {
    prop::collection::vec(
        (any::<u16>(), any::<u16>())
            .prop_map(|(data_id, rate_hz)| OutputSetting { data_id, rate_hz }),
        0..=OutputConfiguration::MAX_OUTPUTS,
    )
    .prop_map(OutputConfiguration)
}

fn arb_command() -> impl Strategy<Value = XsensCommand> {
    prop_oneof![
        Just(XsensCommand::WakeUpAck),
        Just(XsensCommand::GoToConfig),
        Just(XsensCommand::GoToMeasurement),
        Just(XsensCommand::ReqDeviceId),
        Just(XsensCommand::ReqProductCode),
        Just(XsensCommand::ReqFirmwareRev),
        Just(XsensCommand::ReqOutputConfiguration),
        Just(XsensCommand::Reset),
        // An empty configuration is the request form on the wire.
        arb_config()
            .prop_filter("non-empty", |c| !c.0.is_empty())
            .prop_map(XsensCommand::SetOutputConfiguration),
    ]
}

fn arb_vec<const N: usize>() -> impl Strategy<Value = Option<[f64; N]>> {
    prop::option::of(
        prop::array::uniform::<_, N>(-1000.0f32..1000.0).prop_map(|a| a.map(f64::from)),
    )
}

fn arb_data() -> impl Strategy<Value = MtData2> {
    (
        (
            prop::option::of(any::<u16>()),
            prop::option::of(any::<u32>()),
            prop::option::of((any::<u32>(), any::<u16>(), any::<[u8; 6]>()).prop_map(
                |(ns, year, b)| UtcTime {
                    ns,
                    year,
                    month: b[0],
                    day: b[1],
                    hour: b[2],
                    minute: b[3],
                    second: b[4],
                    flags: b[5],
                },
            )),
            arb_vec::<1>(),
            prop::option::of(any::<u32>()),
            prop::option::of(
                any::<([u16; 9], i16)>().prop_map(|(w, temp)| RawAccGyrMagTemp {
                    acc: [w[0], w[1], w[2]],
                    gyr: [w[3], w[4], w[5]],
                    mag: [w[6], w[7], w[8]],
                    temp,
                }),
            ),
        ),
        (
            arb_vec::<3>(),
            arb_vec::<3>(),
            arb_vec::<3>(),
            arb_vec::<3>(),
            arb_vec::<4>(),
            arb_vec::<3>(),
            arb_vec::<3>(),
        ),
    )
        .prop_map(
            |((pc, stf, utc, temp, status, raw), (dv, acc, acc_hr, rot, dq, rot_hr, mag))| {
                MtData2 {
                    packet_counter: pc,
                    sample_time_fine: stf,
                    utc,
                    temperature_c: temp.map(|[t]| t),
                    delta_v_m_s: dv,
                    acceleration_m_s2: acc,
                    acceleration_hr_m_s2: acc_hr,
                    rate_of_turn_rad_s: rot,
                    delta_q: dq,
                    rate_of_turn_hr_rad_s: rot_hr,
                    raw,
                    magnetic_field_normalised: mag,
                    status_word: status,
                    ..MtData2::default()
                }
            },
        )
}

fn arb_reply() -> impl Strategy<Value = XsensReply> {
    prop_oneof![
        Just(XsensReply::WakeUp),
        Just(XsensReply::GoToConfigAck),
        Just(XsensReply::GoToMeasurementAck),
        Just(XsensReply::ResetAck),
        any::<u64>().prop_map(XsensReply::DeviceId),
        "[A-Za-z0-9-]{0,20}".prop_map(XsensReply::ProductCode),
        (any::<[u8; 3]>(), prop::option::of(any::<(u32, u32)>())).prop_map(|(v, build)| {
            XsensReply::FirmwareRev(FirmwareRev {
                major: v[0],
                minor: v[1],
                revision: v[2],
                build,
            })
        }),
        arb_config().prop_map(XsensReply::OutputConfiguration),
        any::<u8>().prop_map(XsensReply::Error),
        arb_data().prop_map(|d| XsensReply::MtData2(Box::new(d))),
    ]
}

fn arb_message() -> impl Strategy<Value = Message> {
    prop_oneof![
        arb_command().prop_map(|c| c.to_message()),
        arb_reply().prop_map(|r| r.to_message()),
    ]
}

proptest! {
    #[test]
    fn command_round_trip(cmd in arb_command()) {
        let msg = Message::parse(cmd.to_message().as_bytes()).unwrap();
        prop_assert_eq!(XsensCommand::decode(&msg), Ok(cmd));
    }

    #[test]
    fn reply_round_trip(reply in arb_reply()) {
        let msg = Message::parse(reply.to_message().as_bytes()).unwrap();
        prop_assert_eq!(XsensReply::decode(&msg), Ok(reply));
    }

    /// Every format round-trips within its resolution (float32 values are exact in all but
    /// the fixed-point formats).
    #[test]
    fn mtdata2_round_trip_in_every_format(data in arb_data(), f in 0usize..4) {
        let format = Format::ALL[f];
        let back = MtData2::decode(&data.to_message(format)).unwrap();
        let tol = match format {
            Format::Float32 | Format::Float64 => 0.0,
            Format::Fp1220 => 0.5 / 1048576.0,
            Format::Fp1632 => 0.5 / 4294967296.0,
        };
        let pairs = [
            (data.acceleration_m_s2, back.acceleration_m_s2),
            (data.acceleration_hr_m_s2, back.acceleration_hr_m_s2),
            (data.rate_of_turn_rad_s, back.rate_of_turn_rad_s),
            (data.rate_of_turn_hr_rad_s, back.rate_of_turn_hr_rad_s),
            (data.magnetic_field_normalised, back.magnetic_field_normalised),
            (data.delta_v_m_s, back.delta_v_m_s),
        ];
        for (a, b) in pairs {
            prop_assert_eq!(a.is_some(), b.is_some());
            if let (Some(a), Some(b)) = (a, b) {
                for (x, y) in a.iter().zip(b) {
                    prop_assert!((x - y).abs() <= tol, "{} vs {} in {:?}", x, y, format);
                }
            }
        }
        prop_assert_eq!(
            (data.packet_counter, data.sample_time_fine, data.utc, data.status_word, data.raw),
            (back.packet_counter, back.sample_time_fine, back.utc, back.status_word, back.raw)
        );
        prop_assert_eq!((back.unknown_items, back.bad_items), (0, 0));
    }

    /// Good messages interleaved with random garbage, fed in random chunks: every good message
    /// comes out, in order, and the events rebuild the stream byte for byte.
    #[test]
    fn garbage_interleaving_loses_no_message(
        parts in prop::collection::vec(
            (arb_message(), prop::collection::vec(any::<u8>(), 0..40)),
            1..12,
        ),
        chunk in 1usize..64,
    ) {
        let mut stream = Vec::new();
        let mut sent = Vec::new();
        for (msg, garbage) in &parts {
            stream.extend_from_slice(garbage);
            stream.extend_from_slice(msg.as_bytes());
            sent.push(msg.clone());
        }
        let mut d = XsensDecoder::new();
        let mut events = Vec::new();
        for piece in stream.chunks(chunk) {
            d.push(piece);
            events.extend(drain(&mut d));
        }
        d.flush();
        events.extend(drain(&mut d));
        let rebuilt: Vec<u8> = events.iter().flat_map(|e| e.bytes().to_vec()).collect();
        prop_assert_eq!(&rebuilt, &stream);
        let mut at = 0u64;
        for e in &events {
            prop_assert_eq!(e.offset(), at);
            at += e.bytes().len() as u64;
        }
        // Garbage forming a message with a good 8-bit checksum of its own is possible; it
        // would only add one, never hide a sent one.
        let got = messages(&events);
        let mut it = got.iter();
        for m in &sent {
            prop_assert!(it.any(|g| g == m), "lost {:?}", m);
        }
        let s = d.stats();
        prop_assert_eq!(s.bytes_in, s.frame_bytes + s.rejected_bytes);
        prop_assert_eq!(d.pending_len(), 0);
    }

    /// Arbitrary bytes: never a panic, every byte reported once.
    #[test]
    fn arbitrary_bytes_are_accounted(
        bytes in prop::collection::vec(
            prop_oneof![Just(0xFAu8), Just(0xFFu8), Just(0x00u8), any::<u8>()],
            0..600,
        ),
        chunk in 1usize..32,
    ) {
        let mut d = XsensDecoder::new();
        let mut rebuilt = Vec::new();
        for piece in bytes.chunks(chunk) {
            d.push(piece);
            for e in drain(&mut d) {
                if let XsensEvent::Packet { packet, .. } = &e {
                    prop_assert_eq!(Message::parse(packet.as_bytes()), Ok(packet.clone()));
                    // Typed decoding never panics either.
                    let _ = XsensReply::decode(packet);
                    let _ = XsensCommand::decode(packet);
                }
                rebuilt.extend_from_slice(e.bytes());
            }
            let s = d.stats();
            prop_assert_eq!(s.bytes_in, s.frame_bytes + s.rejected_bytes + d.pending_len() as u64);
        }
        d.flush();
        for e in drain(&mut d) {
            rebuilt.extend_from_slice(e.bytes());
        }
        prop_assert_eq!(rebuilt, bytes);
    }
}
