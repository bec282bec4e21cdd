//! Tests of the MIP codec: golden vectors from the vendor's mip_sdk, round trips of every typed
//! value, and the streaming decoder's resynchronisation and byte accounting.

use proptest::prelude::*;

use super::command::base;
use super::data::field;
use super::*;
use crate::decoder::RejectReason;

/// mip_sdk `test/c/mip/test_mip_format.c`, `PING_PACKET`.
const PING: [u8; 8] = [0x75, 0x65, 0x01, 0x02, 0x02, 0x01, 0xE0, 0xC6];

/// mip_sdk `test/c/mip/test_mip_format.c`, `SET_SAVE_COMM_SPEED`: two comm speed commands (write
/// port 1 at 115200, save port 1) in one base-set packet.
const SET_SAVE_COMM_SPEED: [u8; 18] = [
    0x75, 0x65, 0x01, 0x0c, 0x08, 0x09, 0x01, 0x01, 0x00, 0x01, 0xc2, 0x00, 0x04, 0x09, 0x03, 0x01,
    0xCE, 0x80,
];

/// mip_sdk `test/cpp/packet_interface.cpp`, `ACCEL_PKT`: scaled accel (1, 2, -3) g.
const ACCEL_PKT: [u8; 20] = [
    0x75, 0x65, 0x80, 0x0e, 0x0e, 0x04, 0x3f, 0x80, 0x00, 0x00, 0x40, 0x00, 0x00, 0x00, 0xC0, 0x40,
    0x00, 0x00, 0x79, 0xed,
];

/// mip_sdk `examples/c/mip_packet/mip_packet_example.c`, `create_from_raw_buffer_packet_4`:
/// reference time (0xD5), reference time delta (0xD6), scaled accel, scaled gyro, delta theta,
/// delta velocity.
const EXAMPLE_PACKET_4: [u8; 82] = [
    0x75, 0x65, 0x80, 0x4C, // header
    0x0A, 0xD5, 0x00, 0x00, 0x00, 0x05, 0x5E, 0xE6, 0x7C, 0xC0, // reference time
    0x0A, 0xD6, 0x00, 0x00, 0x00, 0x01, 0x4E, 0x43, 0x4A, 0x00, // reference time delta
    0x0E, 0x04, 0x3D, 0x9E, 0xE8, 0x8D, 0x38, 0x7F, 0xDB, 0x00, 0xBF, 0x7A, 0xAF,
    0x03, // accel
    0x0E, 0x05, 0xBB, 0x0C, 0x1E, 0x30, 0xBB, 0x57, 0x2E, 0x68, 0xBB, 0xAA, 0x24,
    0xAE, // gyro
    0x0E, 0x07, 0xBC, 0x8A, 0xAC, 0x80, 0xBC, 0x72, 0xC5, 0x0E, 0xBC, 0xC4, 0xE2,
    0xC1, // dtheta
    0x0E, 0x08, 0x3E, 0xEE, 0x3D, 0x9F, 0xBD, 0x66, 0xDA, 0xDD, 0xC0, 0xAF, 0xDE,
    0xF5, // dvel
    0x91, 0x96, // checksum
];

/// mip_sdk `test/cpp/mip_parser_performance.cpp`, `DATA_PACKET`: a 199-byte filter (0x82)
/// data packet.
const FILTER_PACKET: [u8; 199] = [
    0x75, 0x65, 0x82, 0xc1, 0x0e, 0xd3, 0x40, 0x8c, 0x84, 0xef, 0x9d, 0xb2, 0x2d, 0x0f, 0x00, 0x00,
    0x00, 0x00, 0x0a, 0xd5, 0x00, 0x00, 0x00, 0xd4, 0x7c, 0x36, 0x4c, 0x40, 0x10, 0x05, 0x7f, 0xff,
    0xff, 0xf8, 0x7f, 0xc0, 0x00, 0x00, 0x7f, 0xff, 0xff, 0xf8, 0x00, 0x01, 0x10, 0x06, 0x7f, 0xc0,
    0x00, 0x00, 0x7f, 0xc0, 0x00, 0x00, 0x7f, 0xc0, 0x00, 0x00, 0x00, 0x01, 0x10, 0x07, 0x00, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x01, 0x08, 0x10, 0x00, 0x02,
    0x00, 0x00, 0x00, 0x00, 0x1c, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
    0x10, 0x02, 0x7f, 0xc0, 0x00, 0x00, 0x7f, 0xc0, 0x00, 0x00, 0x7f, 0xc0, 0x00, 0x00, 0x00, 0x00,
    0x1c, 0x42, 0x7f, 0xf8, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x7f, 0xf8, 0x00, 0x00, 0x00, 0x00,
    0x00, 0x00, 0x7f, 0xf8, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x09, 0x46, 0x44, 0x64,
    0x26, 0x87, 0x00, 0x04, 0x01, 0x10, 0x08, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x10, 0x09, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x87, 0x56,
];

fn drain(d: &mut MipDecoder) -> Vec<MipEvent> {
    std::iter::from_fn(|| d.next_event()).collect()
}

fn packets(events: &[MipEvent]) -> Vec<Packet> {
    events
        .iter()
        .filter_map(|e| match e {
            MipEvent::Packet { packet, .. } => Some(*packet),
            MipEvent::Rejected { .. } => None,
        })
        .collect()
}

#[test]
fn golden_ping_encodes_and_decodes() {
    assert_eq!(MipCommand::Ping.to_packet().as_bytes(), PING);
    let p = Packet::parse(&PING).unwrap();
    let cmds: Vec<_> = MipCommand::decode_packet(&p).collect();
    assert_eq!(cmds, [(base::PING, Ok(MipCommand::Ping))]);
}

#[test]
fn golden_two_field_command_packet_frames_and_unknown_commands_are_named() {
    let p = Packet::parse(&SET_SAVE_COMM_SPEED).unwrap();
    let fields: Vec<_> = p.fields().map(|f| (f.descriptor, f.data.len())).collect();
    assert_eq!(fields, [(0x09, 6), (0x09, 2)]);
    for (_, cmd) in MipCommand::decode_packet(&p) {
        assert_eq!(
            cmd,
            Err(MipError::UnknownCommand {
                set: 0x01,
                descriptor: 0x09
            })
        );
    }
    // The builder lays out the same two fields with the same checksum.
    let mut b = PacketBuilder::new(0x01);
    b.field(0x09, &[0x01, 0x01, 0x00, 0x01, 0xc2, 0x00])
        .unwrap()
        .field(0x09, &[0x03, 0x01])
        .unwrap();
    assert_eq!(b.build().as_bytes(), SET_SAVE_COMM_SPEED);
}

#[test]
fn golden_max_length_packets_from_the_sdk_tests() {
    // test/c/mip/test_mip_format.c MAX_PACKET_SINGLE_FIELD (checksum 5A2B) and
    // MAX_PACKET_MULTIPLE_FIELDS (checksum 3A0B), rebuilt from their description.
    let ramp: Vec<u8> = (1..=0xFE).collect();
    let mut b = PacketBuilder::new(0x01);
    b.field(0x01, &ramp[1..]).unwrap();
    let single = b.build();
    assert_eq!(single.as_bytes().len(), MAX_PACKET_LEN);
    assert_eq!(
        &single.as_bytes()[..6],
        [0x75, 0x65, 0x01, 0xFF, 0xFF, 0x01]
    );
    assert_eq!(&single.as_bytes()[259..], [0x5A, 0x2B]);
    let mut b = PacketBuilder::new(0x01);
    for _ in 0..7 {
        b.field(0x01, &ramp[1..0x1F]).unwrap();
    }
    b.field(0x01, &ramp[1..0x1E]).unwrap();
    assert!(matches!(
        b.field(0x01, &[]),
        Err(MipError::PayloadFull(257))
    ));
    let multi = b.build();
    assert_eq!(&multi.as_bytes()[259..], [0x3A, 0x0B]);
    assert_eq!(Packet::parse(multi.as_bytes()).unwrap().fields().count(), 8);
}

#[test]
fn golden_scaled_accel_packet() {
    let data = ImuData {
        accel_g: Some([1.0, 2.0, -3.0]),
        ..ImuData::default()
    };
    assert_eq!(data.to_packet().as_bytes(), ACCEL_PKT);
    let p = Packet::parse(&ACCEL_PKT).unwrap();
    assert_eq!(ImuData::decode_packet(&p), Ok(data));
}

#[test]
fn golden_example_packet_4_decodes_and_skips_the_unknown_field() {
    let p = Packet::parse(&EXAMPLE_PACKET_4).unwrap();
    let d = ImuData::decode_packet(&p).unwrap();
    let f = |bits: [u32; 3]| Some(bits.map(f32::from_bits));
    assert_eq!(d.reference_time_ns, Some(0x0000_0005_5EE6_7CC0));
    assert_eq!(d.accel_g, f([0x3D9E_E88D, 0x387F_DB00, 0xBF7A_AF03]));
    assert_eq!(d.gyro_rad_s, f([0xBB0C_1E30, 0xBB57_2E68, 0xBBAA_24AE]));
    assert_eq!(
        d.delta_theta_rad,
        f([0xBC8A_AC80, 0xBC72_C50E, 0xBCC4_E2C1])
    );
    assert_eq!(
        d.delta_velocity_g_s,
        f([0x3EEE_3D9F, 0xBD66_DADD, 0xC0AF_DEF5])
    );
    // A level unit at rest: accel about -1 g on z, small rates.
    let a = d.accel_g.unwrap();
    assert!((a[2] + 0.98).abs() < 0.03, "{a:?}");
    assert_eq!(d.skipped_fields, 1, "the reference time delta (0xD6)");
    assert_eq!((d.mag_gauss, d.internal_ticks), (None, None));
}

#[test]
fn golden_filter_packet_frames_but_is_not_imu_data() {
    let mut d = MipDecoder::new();
    d.push(&FILTER_PACKET);
    let events = drain(&mut d);
    let got = packets(&events);
    assert_eq!(got.len(), 1, "{events:?}");
    assert_eq!(got[0].descriptor_set(), 0x82);
    assert_eq!(
        ImuData::decode_packet(&got[0]),
        Err(MipError::WrongDescriptorSet {
            expected: 0x80,
            found: 0x82
        })
    );
}

#[test]
fn whole_packet_errors_name_the_problem() {
    let mut bad = PING;
    bad[7] ^= 1;
    assert!(matches!(
        Packet::parse(&bad),
        Err(MipError::BadChecksum {
            expected: 0xE0C6,
            found: 0xE0C7
        })
    ));
    assert_eq!(Packet::parse(&PING[..5]), Err(MipError::TooShort(5)));
    assert_eq!(
        Packet::parse(&PING[..7]),
        Err(MipError::WrongLength {
            expected: 8,
            found: 7
        })
    );
    let mut b = PacketBuilder::new(0);
    b.field(1, &[]).unwrap();
    assert_eq!(
        Packet::parse(b.build().as_bytes()),
        Err(MipError::ZeroDescriptorSet)
    );
    // A field length of 1 cannot hold its own descriptor (checksum recomputed so only the
    // layout is wrong).
    let mut raw = vec![0x75, 0x65, 0x01, 0x02, 0x01, 0x01];
    let sum = checksum::fletcher16(&raw);
    raw.extend_from_slice(&sum.to_be_bytes());
    assert_eq!(
        Packet::parse(&raw),
        Err(MipError::BadFieldLength { offset: 0, len: 1 })
    );
    let err = MipError::BadFieldLength { offset: 0, len: 1 }.to_string();
    assert!(
        err.contains("payload byte 0") && err.contains("length 1"),
        "{err}"
    );
}

#[test]
fn nack_and_response_replies() {
    let info = DeviceInfo {
        firmware_version: 1141,
        model_name: "3DM-GX5-25".into(),
        model_number: "6251-4220".into(),
        serial_number: "6251.12345".into(),
        lot_number: "I042Y".into(),
        device_options: "8g,300dps".into(),
    };
    let reply = MipReply {
        response: Some(Response::DeviceInfo(info)),
        ..MipReply::ack((0x01, base::GET_DEVICE_INFO), AckCode::Ok)
    };
    let p = reply.to_packet();
    // ack (4 bytes) + device info field (2 + 2 + 5 x 16).
    assert_eq!(p.payload().len(), 4 + 84);
    assert_eq!(MipReply::decode_packet(&p), Ok(vec![reply]));
    let nack = MipReply::ack((0x0C, 0x99), AckCode::UnknownCommand);
    assert_eq!(
        &nack.to_packet().payload(),
        &[0x04, 0xF1, 0x99, 0x01],
        "ack field: length, 0xF1, echoed command, code"
    );
    // A response field with no ack before it is not a reply.
    let mut b = PacketBuilder::new(0x0C);
    b.field(0x83, &[0x03, 0xE8]).unwrap();
    assert_eq!(
        MipReply::decode_packet(&b.build()),
        Err(MipError::MissingAck(0x83))
    );
}

#[test]
fn an_overlong_message_format_is_cut_to_what_command_and_reply_both_carry() {
    let rate = |descriptor| DescriptorRate {
        descriptor,
        decimation: 1,
    };
    let long = MessageFormat {
        fields: (0..=255).map(rate).collect(),
    };
    let cut = MessageFormat {
        fields: long.fields[..MessageFormat::MAX_FIELDS].to_vec(),
    };
    let cmd = MipCommand::ImuMessageFormat(Setting::Write(long.clone()));
    let p = Packet::parse(cmd.to_packet().as_bytes()).unwrap();
    let got: Vec<_> = MipCommand::decode_packet(&p).map(|(_, c)| c).collect();
    assert_eq!(
        got,
        [Ok(MipCommand::ImuMessageFormat(Setting::Write(
            cut.clone()
        )))]
    );
    let reply = MipReply {
        response: Some(Response::ImuMessageFormat(long)),
        ..MipReply::ack((0x0C, 0x08), AckCode::Ok)
    };
    let decoded = MipReply::decode_packet(&reply.to_packet()).unwrap();
    assert_eq!(decoded[0].response, Some(Response::ImuMessageFormat(cut)));
}

#[test]
fn imu_data_skips_known_fields_of_the_wrong_size_and_unknown_fields() {
    let mut b = PacketBuilder::new(0x80);
    b.field(field::SCALED_GYRO, &[0; 8])
        .unwrap()
        .field(0x7A, &[1, 2, 3])
        .unwrap()
        .field(field::INTERNAL_TIMESTAMP, &7u32.to_be_bytes())
        .unwrap();
    let d = ImuData::decode_packet(&b.build()).unwrap();
    assert_eq!(d.skipped_fields, 2);
    assert_eq!((d.gyro_rad_s, d.internal_ticks), (None, Some(7)));
}

#[test]
fn decoder_resyncs_after_garbage_bad_checksum_and_truncation() {
    let good = MipCommand::GetImuBaseRate.to_packet();
    let mut corrupt = *PING.as_slice().first_chunk::<8>().unwrap();
    corrupt[5] = 0x02;
    let mut stream = vec![0x00, 0x75, 0x11];
    stream.extend_from_slice(&corrupt); // bad checksum, no good packet inside
    stream.extend_from_slice(&PING[..5]); // cut short by the next packet
    stream.extend_from_slice(good.as_bytes());
    let mut d = MipDecoder::new();
    for b in &stream {
        d.push(std::slice::from_ref(b));
    }
    let events = drain(&mut d);
    let kinds: Vec<_> = events
        .iter()
        .map(|e| match e {
            MipEvent::Packet { offset, .. } => (*offset, None),
            MipEvent::Rejected { offset, reason, .. } => (*offset, Some(*reason)),
        })
        .collect();
    assert_eq!(
        kinds,
        [
            (0, Some(RejectReason::Garbage)),
            (3, Some(RejectReason::BadChecksum)),
            (11, Some(RejectReason::Truncated)),
            (16, None)
        ]
    );
    let s = d.stats();
    assert_eq!(
        (s.frames, s.resyncs, s.checksum_failures, s.truncated_frames),
        (1, 1, 1, 1)
    );
    assert_eq!(s.garbage_bytes, 3);
    assert_eq!(s.bytes_in, s.frame_bytes + s.rejected_bytes);
}

#[test]
fn decoder_waits_then_flush_reports_a_cut_packet() {
    let mut d = MipDecoder::new();
    d.push(&PING[..6]);
    assert_eq!(d.next_event(), None, "waits for the checksum");
    d.flush();
    assert!(matches!(
        d.next_event(),
        Some(MipEvent::Rejected { reason: RejectReason::Truncated, ref bytes, .. }) if bytes.len() == 6
    ));
    assert_eq!((d.next_event(), d.pending_len()), (None, 0));
    d.push(&PING);
    assert_eq!(
        packets(&drain(&mut d)).len(),
        1,
        "decoding goes on after a flush"
    );
}

fn arb_setting<T: std::fmt::Debug + Clone + 'static>(
    value: impl Strategy<Value = T> + 'static,
) -> impl Strategy<Value = Setting<T>> {
    prop_oneof![
        value.prop_map(Setting::Write),
        Just(Setting::Read),
        Just(Setting::Save),
        Just(Setting::Load),
        Just(Setting::Reset),
    ]
}

fn arb_format() -> impl Strategy<Value = MessageFormat> {
    prop::collection::vec(
        (any::<u8>(), any::<u16>()).prop_map(|(descriptor, decimation)| DescriptorRate {
            descriptor,
            decimation,
        }),
        0..=MessageFormat::MAX_FIELDS,
    )
    .prop_map(|fields| MessageFormat { fields })
}

fn arb_command() -> impl Strategy<Value = MipCommand> {
    prop_oneof![
        Just(MipCommand::Ping),
        Just(MipCommand::SetToIdle),
        Just(MipCommand::GetDeviceInfo),
        Just(MipCommand::Resume),
        Just(MipCommand::GetImuBaseRate),
        arb_setting(arb_format()).prop_map(MipCommand::ImuMessageFormat),
        (any::<u8>(), arb_setting(any::<bool>())).prop_map(|(descriptor_set, setting)| {
            MipCommand::DataStream {
                descriptor_set,
                setting,
            }
        }),
        any::<u8>().prop_map(|descriptor_set| MipCommand::GetBaseRate { descriptor_set }),
        (any::<u8>(), arb_setting(arb_format())).prop_map(|(descriptor_set, setting)| {
            MipCommand::MessageFormat {
                descriptor_set,
                setting,
            }
        }),
    ]
}

fn arb_info_str() -> impl Strategy<Value = String> {
    "[A-Za-z0-9.,-]{0,16}"
}

fn arb_reply() -> impl Strategy<Value = MipReply> {
    let info = (
        any::<u16>(),
        arb_info_str(),
        arb_info_str(),
        arb_info_str(),
        arb_info_str(),
        arb_info_str(),
    )
        .prop_map(|(v, a, b, c, d, e)| DeviceInfo {
            firmware_version: v,
            model_name: a,
            model_number: b,
            serial_number: c,
            lot_number: d,
            device_options: e,
        });
    let response = prop_oneof![
        info.prop_map(Response::DeviceInfo),
        any::<u16>().prop_map(|rate_hz| Response::ImuBaseRate { rate_hz }),
        arb_format().prop_map(Response::ImuMessageFormat),
        (any::<u8>(), any::<bool>()).prop_map(|(descriptor_set, enabled)| Response::DataStream {
            descriptor_set,
            enabled
        }),
        (any::<u8>(), any::<u16>()).prop_map(|(descriptor_set, rate_hz)| Response::BaseRate {
            descriptor_set,
            rate_hz
        }),
        (any::<u8>(), arb_format()).prop_map(|(descriptor_set, format)| Response::MessageFormat {
            descriptor_set,
            format
        }),
    ];
    (any::<u8>(), any::<u8>(), prop::option::of(response)).prop_map(|(command, code, response)| {
        let set = response
            .as_ref()
            .map_or(0x0C, |r: &Response| r.descriptor().0);
        MipReply {
            response,
            ..MipReply::ack((set, command), AckCode::from_code(code))
        }
    })
}

fn arb_vec3() -> impl Strategy<Value = Option<[f32; 3]>> {
    prop::option::of(prop::array::uniform3(-1e6f32..1e6))
}

fn arb_data() -> impl Strategy<Value = ImuData> {
    let vectors = prop::array::uniform8(arb_vec3());
    let times = (
        prop::option::of(any::<u32>()),
        prop::option::of((-1e7f64..1e7, any::<u16>(), any::<u16>())),
        prop::option::of(prop::array::uniform3(-60f32..120.0)),
        prop::option::of(any::<u64>()),
    );
    (vectors, times).prop_map(|(v, (ticks, gps, temp, ns))| ImuData {
        raw_accel: v[0],
        raw_gyro: v[1],
        raw_mag: v[2],
        accel_g: v[3],
        gyro_rad_s: v[4],
        mag_gauss: v[5],
        delta_theta_rad: v[6],
        delta_velocity_g_s: v[7],
        internal_ticks: ticks,
        gps_time: gps.map(|(tow_s, week, valid_flags)| GpsTime {
            tow_s,
            week,
            valid_flags,
        }),
        temperature: temp.map(|[min_c, max_c, mean_c]| TemperatureStats {
            min_c,
            max_c,
            mean_c,
        }),
        reference_time_ns: ns,
        skipped_fields: 0,
    })
}

/// One packet of any kind the codec makes.
fn arb_packet() -> impl Strategy<Value = Packet> {
    prop_oneof![
        arb_command().prop_map(|c| c.to_packet()),
        arb_reply().prop_map(|r| r.to_packet()),
        arb_data().prop_map(|d| d.to_packet()),
    ]
}

proptest! {
    #[test]
    fn command_round_trip(cmd in arb_command()) {
        let p = Packet::parse(cmd.to_packet().as_bytes()).unwrap();
        let got: Vec<_> = MipCommand::decode_packet(&p).collect();
        prop_assert_eq!(got, vec![(cmd.descriptor().1, Ok(cmd))]);
    }

    #[test]
    fn reply_round_trip(reply in arb_reply()) {
        let p = Packet::parse(reply.to_packet().as_bytes()).unwrap();
        prop_assert_eq!(MipReply::decode_packet(&p), Ok(vec![reply]));
    }

    #[test]
    fn imu_data_round_trip(data in arb_data()) {
        let p = Packet::parse(data.to_packet().as_bytes()).unwrap();
        prop_assert_eq!(ImuData::decode_packet(&p), Ok(data));
    }

    /// Good packets interleaved with random garbage, fed in random chunks: every good packet
    /// comes out, in order, and the events rebuild the stream byte for byte.
    #[test]
    fn garbage_interleaving_loses_no_packet(
        parts in prop::collection::vec(
            (arb_packet(), prop::collection::vec(any::<u8>(), 0..40)),
            1..12,
        ),
        chunk in 1usize..64,
    ) {
        let mut stream = Vec::new();
        let mut sent = Vec::new();
        for (packet, garbage) in &parts {
            stream.extend_from_slice(garbage);
            stream.extend_from_slice(packet.as_bytes());
            sent.push(*packet);
        }
        let mut d = MipDecoder::new();
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
        // Every sent packet comes out, in order (random garbage forming a packet of its own
        // with a good Fletcher checksum is possible in principle; it would only add one).
        let got = packets(&events);
        let mut it = got.iter();
        for p in &sent {
            prop_assert!(it.any(|g| g == p), "lost {:?}", p);
        }
        let s = d.stats();
        prop_assert_eq!(s.bytes_in, s.frame_bytes + s.rejected_bytes);
        prop_assert_eq!(d.pending_len(), 0);
    }

    /// Arbitrary bytes: never a panic, every byte reported once.
    #[test]
    fn arbitrary_bytes_are_accounted(
        bytes in prop::collection::vec(
            prop_oneof![Just(0x75u8), Just(0x65u8), any::<u8>()],
            0..600,
        ),
        chunk in 1usize..32,
    ) {
        let mut d = MipDecoder::new();
        let mut rebuilt = Vec::new();
        for piece in bytes.chunks(chunk) {
            d.push(piece);
            for e in drain(&mut d) {
                if let MipEvent::Packet { packet, .. } = &e {
                    prop_assert_eq!(Packet::parse(packet.as_bytes()), Ok(*packet));
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
