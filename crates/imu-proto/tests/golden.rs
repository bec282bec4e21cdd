//! Golden byte vectors: hand-written frames for every reply and command, checksums worked by hand.

use imu_proto::checksum::{checksum, verify};
use imu_proto::reply::Filter::{Instantaneous, Stabilized};
use imu_proto::{Command, FrameError, Reply};

/// Each reply vector: the bytes as they travel, with the checksum sum written out, and the value.
fn golden_replies() -> Vec<(&'static str, Vec<u8>, Reply)> {
    vec![
        (
            // 0x01 + (0x8001 + 0x8002 + 0x8003) + (0x8010 + 0x8020 + 0x8030)
            //      + (0x7FF0 + 0x7FE0 + 0x7FD0) + 0x1234
            // = 0x01 + 0x18006 + 0x18060 + 0x17FA0 + 0x1234 = 0x4923B -> 92 3B
            "0x01 raw sensor bits",
            vec![
                0x01, 0x80, 0x01, 0x80, 0x02, 0x80, 0x03, 0x80, 0x10, 0x80, 0x20, 0x80, 0x30, 0x7F,
                0xF0, 0x7F, 0xE0, 0x7F, 0xD0, 0x12, 0x34, 0x92, 0x3B,
            ],
            Reply::RawSensorBits {
                mag: [0x8001, 0x8002, 0x8003],
                accel: [0x8010, 0x8020, 0x8030],
                rate: [0x7FF0, 0x7FE0, 0x7FD0],
                ticks: 0x1234,
            },
        ),
        (
            // 0x02 + 0x0100 + 0xFF00 + 0x0010 + 0x0001 + 0x0002 + 0x0003 + 0xFFFF + 0xFFFE
            //      + 0x0000 + 0x0102 = 0x30117 -> 01 17
            "0x02 stabilized vectors",
            vec![
                0x02, 0x01, 0x00, 0xFF, 0x00, 0x00, 0x10, 0x00, 0x01, 0x00, 0x02, 0x00, 0x03, 0xFF,
                0xFF, 0xFF, 0xFE, 0x00, 0x00, 0x01, 0x02, 0x01, 0x17,
            ],
            Reply::Vectors {
                kind: Stabilized,
                mag: [256, -256, 16],
                accel: [1, 2, 3],
                rate: [-1, -2, 0],
                ticks: 0x0102,
            },
        ),
        (
            // same words as 0x02, header 0x03: 0x30118 -> 01 18
            "0x03 instantaneous vectors",
            vec![
                0x03, 0x01, 0x00, 0xFF, 0x00, 0x00, 0x10, 0x00, 0x01, 0x00, 0x02, 0x00, 0x03, 0xFF,
                0xFF, 0xFF, 0xFE, 0x00, 0x00, 0x01, 0x02, 0x01, 0x18,
            ],
            Reply::Vectors {
                kind: Instantaneous,
                mag: [256, -256, 16],
                accel: [1, 2, 3],
                rate: [-1, -2, 0],
                ticks: 0x0102,
            },
        ),
        (
            // 0x04 + 0x2000 + 0 + 0 + 0 + 0xFFFF = 0x12003 -> 20 03
            "0x04 instantaneous quaternion",
            vec![
                0x04, 0x20, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF, 0xFF, 0x20, 0x03,
            ],
            Reply::Quaternion {
                kind: Instantaneous,
                q: [8192, 0, 0, 0],
                ticks: 0xFFFF,
            },
        ),
        (
            // 0x05 + 0x0000 + 0xE000 + 0x1000 + 0xF000 + 0x0000 = 0x1E005 -> E0 05
            "0x05 stabilized quaternion",
            vec![
                0x05, 0x00, 0x00, 0xE0, 0x00, 0x10, 0x00, 0xF0, 0x00, 0x00, 0x00, 0xE0, 0x05,
            ],
            Reply::Quaternion {
                kind: Stabilized,
                q: [0, -8192, 4096, -4096],
                ticks: 0,
            },
        ),
        (
            // 0x06 + 0xABCD = 0xABD3 -> AB D3
            "0x06 capture gyro bias",
            vec![0x06, 0xAB, 0xCD, 0xAB, 0xD3],
            Reply::CaptureGyroBias { ticks: 0xABCD },
        ),
        (
            // 0x07 + 0x1234 + 0x0042 = 0x127D -> 12 7D
            "0x07 temperature",
            vec![0x07, 0x12, 0x34, 0x00, 0x42, 0x12, 0x7D],
            Reply::Temperature {
                raw: 0x1234,
                ticks: 0x0042,
            },
        ),
        (
            // identity: 0x0A + 3 * 0x2000 + 0x0010 = 0x601A -> 60 1A
            "0x0A instantaneous orientation matrix",
            vec![
                0x0A, 0x20, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x20, 0x00, 0x00, 0x00, 0x00,
                0x00, 0x00, 0x00, 0x20, 0x00, 0x00, 0x10, 0x60, 0x1A,
            ],
            Reply::OrientationMatrix {
                kind: Instantaneous,
                m: [8192, 0, 0, 0, 8192, 0, 0, 0, 8192],
                ticks: 0x0010,
            },
        ),
        (
            // 0x0B + 0xE000 + 0x2000 + 0x2000 + 0x8000 = 0x1A00B -> A0 0B
            "0x0B stabilized orientation matrix",
            vec![
                0x0B, 0x00, 0x00, 0xE0, 0x00, 0x00, 0x00, 0x20, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
                0x00, 0x00, 0x00, 0x20, 0x00, 0x80, 0x00, 0xA0, 0x0B,
            ],
            Reply::OrientationMatrix {
                kind: Stabilized,
                m: [0, -8192, 0, 8192, 0, 0, 0, 0, 8192],
                ticks: 0x8000,
            },
        ),
        (
            // 0x0C + 0x2000 + (1 + 2 + 3) + 0x1000 + 0xFFFF + 0x0001 + 0x0300 = 0x13312 -> 33 12
            "0x0C stabilized quaternion + vectors",
            vec![
                0x0C, 0x20, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, // q
                0x00, 0x01, 0x00, 0x02, 0x00, 0x03, // mag
                0x00, 0x00, 0x00, 0x00, 0x10, 0x00, // accel
                0xFF, 0xFF, 0x00, 0x00, 0x00, 0x01, // rate
                0x03, 0x00, 0x33, 0x12, // ticks, checksum
            ],
            Reply::QuaternionVectors {
                kind: Stabilized,
                q: [8192, 0, 0, 0],
                mag: [1, 2, 3],
                accel: [0, 0, 4096],
                rate: [-1, 0, 1],
                ticks: 0x0300,
            },
        ),
        (
            // same words as 0x0C, header 0x12: 0x13306 + 0x12 = 0x13318 -> 33 18
            "0x12 instantaneous quaternion + vectors",
            vec![
                0x12, 0x20, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, // q
                0x00, 0x01, 0x00, 0x02, 0x00, 0x03, // mag
                0x00, 0x00, 0x00, 0x00, 0x10, 0x00, // accel
                0xFF, 0xFF, 0x00, 0x00, 0x00, 0x01, // rate
                0x03, 0x00, 0x33, 0x18, // ticks, checksum
            ],
            Reply::QuaternionVectors {
                kind: Instantaneous,
                q: [8192, 0, 0, 0],
                mag: [1, 2, 3],
                accel: [0, 0, 4096],
                rate: [-1, 0, 1],
                ticks: 0x0300,
            },
        ),
        (
            // roll 90°, pitch -90°, yaw -180°: 0x0D + 0x4000 + 0xC000 + 0x8000 + 0x0001
            // = 0x1800E -> 80 0E
            "0x0D instantaneous euler",
            vec![
                0x0D, 0x40, 0x00, 0xC0, 0x00, 0x80, 0x00, 0x00, 0x01, 0x80, 0x0E,
            ],
            Reply::Euler {
                kind: Instantaneous,
                rpy: [16384, -16384, -32768],
                ticks: 1,
            },
        ),
        (
            // 0x0E + 1 + 2 + 3 + 4 = 0x0018 -> 00 18
            "0x0E stabilized euler",
            vec![
                0x0E, 0x00, 0x01, 0x00, 0x02, 0x00, 0x03, 0x00, 0x04, 0x00, 0x18,
            ],
            Reply::Euler {
                kind: Stabilized,
                rpy: [1, 2, 3],
                ticks: 4,
            },
        ),
        (
            // 0x31 + (0x1000 + 0x2000 + 0x3000) + 0x1000 + (0x10 + 0x20 + 0x30) + 0x0400
            // = 0x7491 -> 74 91
            "0x31 stabilized euler + vectors",
            vec![
                0x31, 0x10, 0x00, 0x20, 0x00, 0x30, 0x00, // rpy
                0x00, 0x00, 0x00, 0x00, 0x10, 0x00, // accel
                0x00, 0x10, 0x00, 0x20, 0x00, 0x30, // rate
                0x04, 0x00, 0x74, 0x91, // ticks, checksum
            ],
            Reply::EulerVectors {
                rpy: [0x1000, 0x2000, 0x3000],
                accel: [0, 0, 0x1000],
                rate: [0x10, 0x20, 0x30],
                ticks: 0x0400,
            },
        ),
        (
            // 10 00 02 | ticks 0x1000: 0x10 + 0x0002 + 0x1000 = 0x1012 -> 10 12
            "0x10 continuous mode on (0x02)",
            vec![0x10, 0x00, 0x02, 0x10, 0x00, 0x10, 0x12],
            Reply::Continuous {
                command: 0x02,
                ticks: 0x1000,
            },
        ),
        (
            // stop: 0x10 + 0x0000 + 0x0005 = 0x0015 -> 00 15
            "0x10 continuous mode stopped",
            vec![0x10, 0x00, 0x00, 0x00, 0x05, 0x00, 0x15],
            Reply::Continuous {
                command: 0,
                ticks: 5,
            },
        ),
        (
            // 0x0F + 0x0102 = 0x0111 -> 01 11
            "0x0F tare",
            vec![0x0F, 0x01, 0x02, 0x01, 0x11],
            Reply::Tare { ticks: 0x0102 },
        ),
        (
            // 0x11 + 0x0000 = 0x0011 -> 00 11
            "0x11 remove tare",
            vec![0x11, 0x00, 0x00, 0x00, 0x11],
            Reply::RemoveTare { ticks: 0 },
        ),
        (
            // accel GainScale 7000 = 0x1B58: 0x28 + 0x1B58 + 0x0100 = 0x1C80 -> 1C 80
            "0x28 read EEPROM",
            vec![0x28, 0x1B, 0x58, 0x01, 0x00, 0x1C, 0x80],
            Reply::EepromRead {
                value: 7000,
                ticks: 0x0100,
            },
        ),
        (
            // 10000 = 0x2710: 0x29 + 0x2710 + 0x0200 = 0x2939 -> 29 39
            "0x29 write EEPROM",
            vec![0x29, 0x27, 0x10, 0x02, 0x00, 0x29, 0x39],
            Reply::EepromWrite {
                value: 10_000,
                ticks: 0x0200,
            },
        ),
        (
            // 3102 = 0x0C1E: 0xF0 + 0x0C1E = 0x0D0E -> 0D 0E
            "0xF0 firmware version",
            vec![0xF0, 0x0C, 0x1E, 0x0D, 0x0E],
            Reply::FirmwareVersion { version: 3102 },
        ),
        (
            // 0xF0 + 0xFFFF = 0x100EF -> 00 EF (wraps)
            "0xF0 firmware version, wrapping sum",
            vec![0xF0, 0xFF, 0xFF, 0x00, 0xEF],
            Reply::FirmwareVersion { version: 0xFFFF },
        ),
        (
            // 0xF1 + 0x1234 = 0x1325 -> 13 25
            "0xF1 serial number",
            vec![0xF1, 0x12, 0x34, 0x13, 0x25],
            Reply::SerialNumber { serial: 0x1234 },
        ),
    ]
}

#[test]
fn every_reply_decodes_and_encodes_to_its_golden_bytes() {
    let vectors = golden_replies();
    for (name, bytes, reply) in &vectors {
        assert_eq!(Reply::decode(bytes).as_ref(), Ok(reply), "decode {name}");
        assert_eq!(&reply.to_bytes(), bytes, "encode {name}");
        assert_eq!(reply.encoded_len(), bytes.len(), "length {name}");
        assert!(verify(bytes), "verify {name}");
        // any single flipped bit in the body or checksum must be caught
        let mut bad = bytes.clone();
        bad[bytes.len() - 1] ^= 0x01;
        assert!(
            matches!(Reply::decode(&bad), Err(FrameError::BadChecksum { .. })),
            "{name}"
        );
    }
    // Every known reply code has at least one golden vector.
    let mut codes: Vec<u8> = vectors.iter().map(|(_, b, _)| b[0]).collect();
    codes.sort_unstable();
    codes.dedup();
    let mut known = imu_proto::reply::KNOWN_REPLY_CODES.to_vec();
    known.sort_unstable();
    assert_eq!(codes, known);
}

/// The checksum a driver computes if it reads the header as a signed char (the bug).
fn signed_header_checksum(body: &[u8]) -> u16 {
    let header = i32::from(body[0] as i8);
    let words: i32 = body[1..]
        .chunks(2)
        .map(|w| i32::from(u16::from_be_bytes([w[0], w[1]])))
        .sum();
    (header + words).rem_euclid(65_536) as u16
}

#[test]
fn high_headers_need_the_unsigned_checksum() {
    // F0 0C 1E: unsigned 0xF0 + 0x0C1E = 0x0D0E; signed -0x10 + 0x0C1E = 0x0C0E.
    // F1 12 34: unsigned 0xF1 + 0x1234 = 0x1325; signed -0x0F + 0x1234 = 0x1225.
    // F0 FF FF: unsigned 0x100EF -> 0x00EF; signed 0xFFFF - 0x10 = 0xFFEF.
    let cases: [(&[u8], u16, u16); 3] = [
        (&[0xF0, 0x0C, 0x1E], 0x0D0E, 0x0C0E),
        (&[0xF1, 0x12, 0x34], 0x1325, 0x1225),
        (&[0xF0, 0xFF, 0xFF], 0x00EF, 0xFFEF),
    ];
    for (body, unsigned, signed) in cases {
        assert_eq!(checksum(body), unsigned);
        assert_eq!(signed_header_checksum(body), signed);
        assert_ne!(unsigned, signed);
        // a frame carrying the signed sum is rejected
        let mut frame = body.to_vec();
        frame.extend_from_slice(&signed.to_be_bytes());
        assert_eq!(
            Reply::decode(&frame),
            Err(FrameError::BadChecksum {
                expected: unsigned,
                found: signed
            })
        );
    }
    // Below 0x80 the two readings agree, which is why the bug hides.
    assert_eq!(
        signed_header_checksum(&[0x07, 0x12, 0x34, 0x00, 0x42]),
        0x127D
    );
}

#[test]
fn every_command_encodes_to_its_golden_bytes() {
    let vectors: Vec<(Command, Vec<u8>)> = vec![
        (Command::RawSensorBits, vec![0x01]),
        (Command::StabilizedVectors, vec![0x02]),
        (Command::InstantaneousVectors, vec![0x03]),
        (Command::InstantaneousQuaternion, vec![0x04]),
        (Command::StabilizedQuaternion, vec![0x05]),
        (Command::CaptureGyroBias, vec![0x06]),
        (Command::Temperature, vec![0x07]),
        (Command::InstantaneousOrientationMatrix, vec![0x0A]),
        (Command::StabilizedOrientationMatrix, vec![0x0B]),
        (Command::StabilizedQuaternionVectors, vec![0x0C]),
        (Command::InstantaneousQuaternionVectors, vec![0x12]),
        (Command::InstantaneousEuler, vec![0x0D]),
        (Command::StabilizedEuler, vec![0x0E]),
        (Command::StabilizedEulerVectors, vec![0x31]),
        (
            Command::SetContinuous { command: 0x31 },
            vec![0x10, 0x00, 0x31],
        ),
        (
            Command::SetContinuous { command: 0 },
            vec![0x10, 0x00, 0x00],
        ),
        (Command::Tare, vec![0x0F, 0xC1, 0xC3, 0xC5]),
        (Command::RemoveTare, vec![0x11, 0xC1, 0xC3, 0xC5]),
        // accel GainScale at 230 = 0x00E6
        (Command::ReadEeprom { address: 230 }, vec![0x28, 0x00, 0xE6]),
        // gyro GainScale address 130 = 0x0082, value 10000 = 0x2710
        (
            Command::WriteEeprom {
                address: 130,
                value: 10_000,
            },
            vec![0x29, 0x71, 0x00, 0x82, 0x27, 0x10, 0xAA],
        ),
        (Command::FirmwareVersion, vec![0xF0]),
        (Command::SerialNumber, vec![0xF1]),
    ];
    for (cmd, bytes) in &vectors {
        assert_eq!(&cmd.to_bytes(), bytes, "{cmd:?}");
        assert_eq!(cmd.encoded_len(), bytes.len(), "{cmd:?}");
        assert_eq!(Command::decode(bytes).as_ref(), Ok(cmd), "{cmd:?}");
        let mut out = vec![0xEE];
        cmd.encode(&mut out);
        assert_eq!(out[0], 0xEE, "encode appends");
        assert_eq!(&out[1..], bytes.as_slice());
    }
    let mut codes: Vec<u8> = vectors.iter().map(|(c, _)| c.code()).collect();
    codes.sort_unstable();
    codes.dedup();
    assert_eq!(codes.len(), imu_proto::command::KNOWN_COMMAND_CODES.len());
}

#[test]
fn reply_lengths_follow_the_table() {
    let table: [(Command, usize); 21] = [
        (Command::RawSensorBits, 23),
        (Command::StabilizedVectors, 23),
        (Command::InstantaneousVectors, 23),
        (Command::InstantaneousQuaternion, 13),
        (Command::StabilizedQuaternion, 13),
        (Command::CaptureGyroBias, 5),
        (Command::Temperature, 7),
        (Command::InstantaneousOrientationMatrix, 23),
        (Command::StabilizedOrientationMatrix, 23),
        (Command::StabilizedQuaternionVectors, 31),
        (Command::InstantaneousQuaternionVectors, 31),
        (Command::InstantaneousEuler, 11),
        (Command::StabilizedEuler, 11),
        (Command::StabilizedEulerVectors, 23),
        (Command::SetContinuous { command: 1 }, 7),
        (Command::Tare, 5),
        (Command::RemoveTare, 5),
        (Command::ReadEeprom { address: 0 }, 7),
        (
            Command::WriteEeprom {
                address: 0,
                value: 0,
            },
            7,
        ),
        (Command::FirmwareVersion, 5),
        (Command::SerialNumber, 5),
    ];
    for (cmd, len) in table {
        assert_eq!(cmd.reply_len(), len, "{cmd:?}");
        assert_eq!(imu_proto::reply_len_for_code(cmd.code()), Some(len));
    }
    assert_eq!(imu_proto::reply_len_for_code(0x08), None);
    assert_eq!(imu_proto::reply_len_for_code(0x09), None);
}
