//! Tests of the VectorNav codec: golden vectors from the public sources, round trips of every
//! typed value, and the streaming decoder's separation of the two streams, resynchronisation and
//! byte accounting.

use proptest::prelude::*;

use super::binary::{common, group, imu, time};
use super::*;
use crate::decoder::RejectReason;

fn fields(common_w: u16, time_w: u16, imu_w: u16) -> OutputFields {
    let mut f = OutputFields::default();
    f.words[group::COMMON] = common_w;
    f.words[group::TIME] = time_w;
    f.words[group::IMU] = imu_w;
    f
}

/// Every event of `bytes` pushed in one go, then flushed.
fn events(bytes: &[u8]) -> (Vec<VnEvent>, VnDecoder) {
    let mut d = VnDecoder::new();
    d.push(bytes);
    let mut out: Vec<_> = std::iter::from_fn(|| d.next_event()).collect();
    d.flush();
    out.extend(std::iter::from_fn(|| d.next_event()));
    (out, d)
}

/// What a calibration stream carries: startup time, GPS time and its status, uncompensated and
/// compensated IMU fields, temperature, deltas.
fn full_fields() -> OutputFields {
    fields(
        common::TIME_STARTUP,
        time::TIME_GPS | time::TIME_STATUS,
        imu::UNCOMP_MAG
            | imu::UNCOMP_ACCEL
            | imu::UNCOMP_GYRO
            | imu::TEMP
            | imu::PRES
            | imu::DELTA_THETA
            | imu::DELTA_VEL
            | imu::MAG
            | imu::ACCEL
            | imu::ANGULAR_RATE,
    )
}

fn full_data(k: f32) -> BinaryData {
    BinaryData {
        startup_ns: Some(1_250_000 * k as u64),
        gps_ns: Some(1_400_000_000_000_000_000 + k as u64),
        time_status: Some(TimeStatus(0b111)),
        uncomp_mag_gauss: Some([0.2, -0.1, 0.45 * k]),
        uncomp_accel_m_s2: Some([0.01, -0.02, -9.81 + k]),
        uncomp_gyro_rad_s: Some([1e-3, -2e-3, 3e-3 * k]),
        temp_c: Some(25.5),
        pres_kpa: Some(101.3),
        delta_theta: Some(DeltaTheta {
            dt_s: 0.00125,
            theta_deg: [1e-4, 2e-4, -3e-4],
        }),
        delta_vel_m_s: Some([0.0, 0.0, -0.0123]),
        mag_gauss: Some([0.21, -0.11, 0.44]),
        accel_m_s2: Some([0.0, 0.0, -9.80665]),
        angular_rate_rad_s: Some([0.0, 1e-5, 0.0]),
        ..BinaryData::default()
    }
}

#[test]
fn ascii_checks_match_the_sources_golden_sentences() {
    // VectorNav's manuals' example read, and ArduPilot's GNSS output register write whose
    // checksum matches its body.
    assert_eq!(
        Sentence::new("VNRRG,11", Check::Checksum8).as_bytes(),
        b"$VNRRG,11*73\r\n"
    );
    let s = Sentence::parse(b"$VNWRG,76,3,80,4E,0002,0010,20B8,0018*63\r\n").unwrap();
    assert_eq!(s.check(), Check::Checksum8);
    let VnCommand::Write(Register::BinaryOutput { index, config }) = VnCommand::decode(&s).unwrap()
    else {
        panic!("not a binary output write");
    };
    assert_eq!((index, config.async_mode, config.rate_divisor), (2, 3, 80));
    assert_eq!(config.fields.groups_byte(), 0x4E);
    assert_eq!(config.fields.words[group::TIME], 0x0002);
    assert_eq!(config.fields.words[group::GPS2], 0x0018);
    // The same command re-encoded is the same bytes.
    assert_eq!(
        VnCommand::Write(Register::BinaryOutput { index, config })
            .to_sentence(Check::Checksum8)
            .as_bytes(),
        s.as_bytes()
    );
}

#[test]
fn ascii_wildcard_crc_and_bad_checks() {
    assert_eq!(
        Sentence::parse(b"$VNRRG,01*XX\r\n").unwrap().check(),
        Check::Wildcard
    );
    let crc = Sentence::new("VNRRG,01", Check::Crc16);
    assert_eq!(crc.as_bytes().len(), "$VNRRG,01*XXXX\r\n".len());
    assert_eq!(
        Sentence::parse(crc.as_bytes()).unwrap().check(),
        Check::Crc16
    );
    assert!(matches!(
        Sentence::parse(b"$VNRRG,11*74\r\n"),
        Err(VnError::BadChecksum { .. })
    ));
    for bad in [
        &b"$VNRRG,11*73\n"[..],
        b"VNRRG,11*73\r\n",
        b"$VNRRG,11*7\r\n",
        b"$XXRRG,11*XX\r\n",
        b"$VNRRG,1\x01*XX\r\n",
    ] {
        assert!(
            matches!(Sentence::parse(bad), Err(VnError::BadSentence(_))),
            "{bad:?}"
        );
    }
}

#[test]
fn binary_lengths_match_the_sources_layouts() {
    // ArduPilot's three packets and their static_assert lengths (header and CRC included).
    let mut ins = OutputFields::default();
    ins.words[group::IMU] = 0x072E;
    ins.words[group::ATTITUDE] = 0x0106;
    ins.words[group::INS] = 0x0612;
    assert_eq!(ins.groups_byte(), 0x34);
    assert_eq!(ins.message_len(), Ok(170));
    let mut gnss = OutputFields::default();
    gnss.words[group::TIME] = 0x0002;
    gnss.words[group::IMU] = 0x0010;
    gnss.words[group::GPS] = 0x20B8;
    gnss.words[group::GPS2] = 0x0018;
    assert_eq!(gnss.message_len(), Ok(92));
    let mut ahrs = OutputFields::default();
    ahrs.words[group::IMU] = 0x073E;
    ahrs.words[group::ATTITUDE] = 0x0004;
    assert_eq!(ahrs.message_len(), Ok(104));
    // The header bytes after the sync are ArduPilot's `vn_ins_pkt1_header`.
    let (f, len) = binary::header(&[0xFA, 0x34, 0x2E, 0x07, 0x06, 0x01, 0x12, 0x06])
        .unwrap()
        .unwrap();
    assert_eq!((f, len), (ins, 170));
}

#[test]
fn binary_message_with_fields_it_skips_decodes_the_ones_it_knows() {
    // ArduPilot's VN-100 AHRS layout: uncompensated mag/accel/gyro, temperature, pressure,
    // compensated mag/accel/rate (group 3), quaternion (group 5, skipped by its size).
    let mut body = vec![0x14, 0x3E, 0x07, 0x04, 0x00];
    let vals: Vec<f32> = (0..20).map(|i| i as f32 * 0.5 - 3.0).collect();
    for v in &vals {
        body.extend_from_slice(&v.to_le_bytes());
    }
    for q in [0.0f32, 0.0, 0.0, 1.0] {
        body.extend_from_slice(&q.to_le_bytes());
    }
    let mut wire = vec![SYNC];
    wire.extend_from_slice(&body);
    wire.extend_from_slice(&checksum::crc16(&body).to_be_bytes());
    assert_eq!(wire.len(), 104);
    let m = BinaryMessage::parse(&wire).unwrap();
    let d = m.data();
    assert_eq!(d.uncomp_mag_gauss, Some([vals[0], vals[1], vals[2]]));
    assert_eq!(d.uncomp_accel_m_s2, Some([vals[3], vals[4], vals[5]]));
    assert_eq!(d.uncomp_gyro_rad_s, Some([vals[6], vals[7], vals[8]]));
    assert_eq!((d.temp_c, d.pres_kpa), (Some(vals[9]), Some(vals[10])));
    assert_eq!(d.mag_gauss, Some([vals[11], vals[12], vals[13]]));
    assert_eq!(d.accel_m_s2, Some([vals[14], vals[15], vals[16]]));
    assert_eq!(d.angular_rate_rad_s, Some([vals[17], vals[18], vals[19]]));
    assert_eq!(d.delta_theta, None);
    // A flipped payload bit fails the CRC.
    let mut bad = wire.clone();
    bad[20] ^= 0x10;
    assert!(matches!(
        BinaryMessage::parse(&bad),
        Err(VnError::BadCrc(_))
    ));
}

#[test]
fn unknown_field_sizes_are_rejected_never_misparsed() {
    // Bit 15 (the extension flag) and group 2 bit 10 have no known size.
    for (g, word) in [(group::IMU, 0x8004u16), (group::TIME, 0x0400)] {
        let mut f = OutputFields::default();
        f.words[g] = word;
        assert!(matches!(f.message_len(), Err(VnError::UnknownField { .. })));
        let mut wire = vec![SYNC, f.groups_byte()];
        wire.extend_from_slice(&word.to_le_bytes());
        wire.extend_from_slice(&[0u8; 14]);
        let (evs, d) = events(&wire);
        assert!(
            matches!(&evs[0], VnEvent::Rejected { reason: RejectReason::Malformed, bytes, .. } if bytes.len() == 4)
        );
        assert!(evs.iter().all(|e| !matches!(e, VnEvent::Binary { .. })));
        assert_eq!(d.stats().malformed_frames, 1);
    }
}

#[test]
fn registers_round_trip_through_commands_and_replies() {
    let regs = [
        Register::Model("VN-200T-CR".into()),
        Register::HardwareRevision(2),
        Register::SerialNumber(100_123_456),
        Register::Firmware("2.1.0.0".into()),
        Register::AsyncOutputType(0),
        Register::AsyncOutputFrequency(40),
        Register::BinaryOutput {
            index: 1,
            config: BinaryOutputConfig {
                async_mode: 1,
                rate_divisor: 1,
                fields: full_fields(),
            },
        },
    ];
    for r in regs {
        for check in [Check::Checksum8, Check::Crc16, Check::Wildcard] {
            let read = VnReply::Read(r.clone()).to_sentence(check);
            assert_eq!(
                VnReply::decode(&Sentence::parse(read.as_bytes()).unwrap()),
                Ok(VnReply::Read(r.clone()))
            );
            let write = VnCommand::Write(r.clone()).to_sentence(check);
            let parsed = Sentence::parse(write.as_bytes()).unwrap();
            assert_eq!(VnCommand::decode(&parsed), Ok(VnCommand::Write(r.clone())));
            assert_eq!(
                VnReply::decode(&VnReply::Written(r.clone()).to_sentence(check)),
                Ok(VnReply::Written(r.clone()))
            );
        }
        let read = VnCommand::Read(r.id()).to_sentence(Check::Checksum8);
        assert_eq!(VnCommand::decode(&read), Ok(VnCommand::Read(r.id())));
    }
    // An error reply, with the unit's hex code, and a YPR output.
    let e = VnReply::Error(error_code::INVALID_REGISTER).to_sentence(Check::Checksum8);
    assert_eq!(e.body(), "VNERR,08");
    assert_eq!(VnReply::decode(&e), Ok(VnReply::Error(8)));
    let ypr = VnReply::Ypr([10.071, 0.278, -2.026]).to_sentence(Check::Checksum8);
    assert_eq!(ypr.body(), "VNYPR,+010.071,+000.278,-002.026");
    assert_eq!(
        VnReply::decode(&ypr),
        Ok(VnReply::Ypr([10.071, 0.278, -2.026]))
    );
    // Too many values, an unknown register, a bad value.
    let s = Sentence::new("VNRRG,03,12,13", Check::Wildcard);
    assert!(matches!(
        VnReply::decode(&s),
        Err(VnError::BadRegister { id: 3, .. })
    ));
    let s = Sentence::new("VNRRG,99,1", Check::Wildcard);
    assert_eq!(VnReply::decode(&s), Err(VnError::UnknownRegister(99)));
    let s = Sentence::new("VNRRG,75,1,1,02,0000", Check::Wildcard);
    assert!(VnReply::decode(&s).is_err());
}

#[test]
fn a_unit_answering_between_binary_messages_is_separated_with_every_byte_accounted() {
    let f = full_fields();
    let m1 = BinaryMessage::encode(f, &full_data(1.0)).unwrap();
    let m2 = BinaryMessage::encode(f, &full_data(2.0)).unwrap();
    let reply = VnReply::Written(Register::AsyncOutputType(0)).to_sentence(Check::Checksum8);
    let mut wire = Vec::new();
    wire.extend_from_slice(m1.as_bytes());
    wire.extend_from_slice(reply.as_bytes());
    wire.extend_from_slice(b"\x00\x13junk");
    wire.extend_from_slice(m2.as_bytes());
    let (evs, d) = events(&wire);
    assert!(matches!(&evs[0], VnEvent::Binary { message, offset: 0 } if *message == m1));
    assert!(matches!(&evs[1], VnEvent::Ascii { sentence, .. } if *sentence == reply));
    assert!(
        matches!(&evs[2], VnEvent::Rejected { reason: RejectReason::Garbage, bytes, .. } if bytes == b"\x00\x13junk")
    );
    assert!(
        matches!(&evs[3], VnEvent::Binary { message, .. } if message.data() == &full_data(2.0))
    );
    let s = d.stats();
    assert_eq!((s.frames, d.sentences(), s.resyncs), (3, 1, 1));
    assert_eq!(s.bytes_in, s.frame_bytes + s.rejected_bytes);
}

#[test]
fn a_message_cut_short_is_truncated_and_the_next_one_found() {
    let f = full_fields();
    let m1 = BinaryMessage::encode(f, &full_data(1.0)).unwrap();
    let m2 = BinaryMessage::encode(f, &full_data(2.0)).unwrap();
    let cut = 30;
    let mut wire = m1.as_bytes()[..cut].to_vec();
    wire.extend_from_slice(m2.as_bytes());
    let (evs, d) = events(&wire);
    assert!(
        matches!(&evs[0], VnEvent::Rejected { reason: RejectReason::Truncated, bytes, .. } if bytes.len() == cut)
    );
    assert!(matches!(&evs[1], VnEvent::Binary { message, .. } if *message == m2));
    assert_eq!(d.stats().truncated_frames, 1);
    // A bad CRC with no good start inside is one BadChecksum of the whole message.
    let mut bad = m1.as_bytes().to_vec();
    let last = bad.len() - 1;
    bad[last] ^= 1;
    let (evs, d) = events(&bad);
    assert_eq!(evs.len(), 1);
    assert!(
        matches!(&evs[0], VnEvent::Rejected { reason: RejectReason::BadChecksum, bytes, .. } if bytes.len() == bad.len())
    );
    assert_eq!(d.stats().checksum_failures, 1);
    // A sentence start that never ends is rejected after the longest sentence.
    let mut long = b"$VN".to_vec();
    long.extend(std::iter::repeat_n(b'A', 300));
    long.extend_from_slice(reply_bytes());
    let (evs, _) = events(&long);
    assert!(
        matches!(&evs[0], VnEvent::Rejected { reason: RejectReason::Malformed, bytes, .. } if bytes.len() == ascii::MAX_SENTENCE_LEN)
    );
    assert!(matches!(evs.last(), Some(VnEvent::Ascii { .. })));
}

fn reply_bytes() -> &'static [u8] {
    b"$VNRRG,11*73\r\n"
}

fn arb_vec3() -> impl Strategy<Value = [f32; 3]> {
    prop::array::uniform3(-1e6f32..1e6)
}

fn arb_data() -> impl Strategy<Value = BinaryData> {
    (
        any::<u64>(),
        any::<u64>(),
        any::<u8>(),
        (arb_vec3(), arb_vec3(), arb_vec3()),
        (arb_vec3(), arb_vec3(), arb_vec3(), arb_vec3()),
        (-50f32..90.0, 50f32..120.0, 0f32..0.1, any::<u16>()),
    )
        .prop_map(
            |(t, g, st, (um, ua, ug), (dth, dv, a, w), (temp, pres, dt, status))| BinaryData {
                startup_ns: Some(t),
                gps_ns: Some(g),
                time_status: Some(TimeStatus(st)),
                time_utc: None,
                imu_status: Some(status),
                uncomp_mag_gauss: Some(um),
                uncomp_accel_m_s2: Some(ua),
                uncomp_gyro_rad_s: Some(ug),
                temp_c: Some(temp),
                pres_kpa: Some(pres),
                delta_theta: Some(DeltaTheta {
                    dt_s: dt,
                    theta_deg: dth,
                }),
                delta_vel_m_s: Some(dv),
                mag_gauss: Some(um),
                accel_m_s2: Some(a),
                angular_rate_rad_s: Some(w),
            },
        )
}

/// Field words over the bits this codec encodes, without the common-group twins of IMU-group
/// fields (a message with both carries the same value twice).
fn arb_fields() -> impl Strategy<Value = OutputFields> {
    (0u16..4, any::<u16>(), any::<u16>()).prop_map(|(c, t, i)| {
        let time_bits = time::TIME_GPS | time::TIME_STATUS;
        let imu_bits = 0x07FF;
        let f = fields(c & common::TIME_STARTUP, t & time_bits, i & imu_bits);
        if f.groups_byte() == 0 {
            fields(common::TIME_STARTUP, 0, 0)
        } else {
            f
        }
    })
}

proptest! {
    #[test]
    fn binary_messages_round_trip(data in arb_data(), f in arb_fields()) {
        let m = BinaryMessage::encode(f, &data).unwrap();
        prop_assert_eq!(m.as_bytes().len(), f.message_len().unwrap());
        prop_assert_eq!(checksum::crc16(&m.as_bytes()[1..]), 0);
        let back = BinaryMessage::parse(m.as_bytes()).unwrap();
        prop_assert_eq!(back.fields(), f);
        // Every enabled field comes back bit for bit.
        let again = BinaryMessage::encode(f, back.data()).unwrap();
        prop_assert_eq!(again.as_bytes(), m.as_bytes());
    }

    #[test]
    fn sentences_round_trip(id in 0u8..100, v in any::<u32>(), check in 0usize..3) {
        let check = [Check::Checksum8, Check::Crc16, Check::Wildcard][check];
        let s = Sentence::new(&format!("VNRRG,{id:02},{v}"), check);
        let back = Sentence::parse(s.as_bytes()).unwrap();
        prop_assert_eq!(back.body(), format!("VNRRG,{id:02},{v}"));
        prop_assert_eq!(back, s);
    }

    #[test]
    fn mixed_streams_decode_in_any_chunking_with_every_byte_once(
        pieces in prop::collection::vec((0u8..3, arb_data(), prop::collection::vec(any::<u8>(), 0..12)), 1..8),
        chunk in 1usize..40,
    ) {
        let f = full_fields();
        let mut wire = Vec::new();
        let mut expected = Vec::new();
        for (kind, data, junk) in &pieces {
            match kind {
                0 => {
                    let m = BinaryMessage::encode(f, data).unwrap();
                    wire.extend_from_slice(m.as_bytes());
                    expected.push(m.as_bytes().to_vec());
                }
                1 => {
                    let s = VnReply::Read(Register::SerialNumber(data.startup_ns.unwrap_or(0) as u32))
                        .to_sentence(Check::Checksum8);
                    wire.extend_from_slice(s.as_bytes());
                    expected.push(s.as_bytes().to_vec());
                }
                _ => wire.extend(junk.iter().map(|b| b & 0x7F).filter(|&b| b != b'$')),
            }
        }
        let mut d = VnDecoder::new();
        let mut rebuilt = Vec::new();
        let mut good = Vec::new();
        for c in wire.chunks(chunk) {
            d.push(c);
            while let Some(e) = d.next_event() {
                prop_assert_eq!(e.offset(), rebuilt.len() as u64);
                rebuilt.extend_from_slice(e.bytes());
                if !matches!(e, VnEvent::Rejected { .. }) {
                    good.push(e.bytes().to_vec());
                }
            }
        }
        d.flush();
        while let Some(e) = d.next_event() {
            rebuilt.extend_from_slice(e.bytes());
            if !matches!(e, VnEvent::Rejected { .. }) {
                good.push(e.bytes().to_vec());
            }
        }
        prop_assert_eq!(&rebuilt, &wire);
        prop_assert_eq!(good, expected);
        let s = d.stats();
        prop_assert_eq!(s.bytes_in, s.frame_bytes + s.rejected_bytes);
    }
}
