//! Seed inputs a corpus starts from (`imu-fuzz seed`): valid frames of every kind the codec knows,
//! built by the codec's own encoders, alone, in runs, between garbage, cut short and with a bad
//! checksum, each under a few chunk layouts. The fuzzers grow the corpus from there.

use imu_proto::Command;
use imu_proto::checksum::checksum;
use imu_proto::mip::{PacketBuilder, descriptor_set};
use imu_proto::reply::{KNOWN_REPLY_CODES, reply_len_for_code};
use imu_proto::xsens::{Message, mid};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::Target;

/// Chunk layouts the seeds are pushed in: whole, byte by byte, and two uneven cycles.
const LAYOUTS: [&[u8]; 4] = [&[], &[1], &[3, 7], &[2, 5, 1]];

/// The seed inputs of `target`, deterministic.
pub fn seeds(target: Target) -> Vec<Vec<u8>> {
    let mut rng = ChaCha8Rng::seed_from_u64(0x5eed);
    let frames = match target {
        Target::ReplyDecoder => reply_frames(&mut rng),
        Target::CommandDecoder => command_frames(),
        Target::MipDecoder => mip_frames(&mut rng),
        Target::XsensDecoder => xsens_frames(&mut rng),
    };
    let mut streams: Vec<Vec<u8>> = frames.clone();
    // Runs of frames, garbage between them, a frame cut short and one with its last byte changed.
    for (i, frame) in frames.iter().enumerate() {
        let next = &frames[(i + 1) % frames.len()];
        let mut s = frame.clone();
        s.extend_from_slice(next);
        s.extend_from_slice(frame);
        streams.push(s);
        let mut s: Vec<u8> = (0..rng.random_range(1..9)).map(|_| rng.random()).collect();
        s.extend_from_slice(frame);
        s.push(rng.random());
        s.extend_from_slice(next);
        streams.push(s);
        let mut s = frame[..frame.len() / 2].to_vec();
        s.extend_from_slice(next);
        streams.push(s);
        let mut s = frame.clone();
        if let Some(last) = s.last_mut() {
            *last ^= 0x5A;
        }
        s.extend_from_slice(next);
        streams.push(s);
    }
    streams
        .into_iter()
        .enumerate()
        .map(|(i, stream)| with_layout(target, LAYOUTS[i % LAYOUTS.len()], &stream, i))
        .collect()
}

/// The input a target takes: chunk sizes, target parameters, then the stream.
fn with_layout(target: Target, sizes: &[u8], stream: &[u8], i: usize) -> Vec<u8> {
    let mut input = vec![sizes.len() as u8];
    input.extend_from_slice(sizes);
    if target == Target::ReplyDecoder {
        // Every other seed declares the codes it expects (what the daemon does while streaming).
        if i.is_multiple_of(2) {
            input.push(0);
        } else {
            input.extend_from_slice(&[1, stream.first().copied().unwrap_or(0x31)]);
        }
    }
    input.extend_from_slice(stream);
    input
}

fn reply_frames(rng: &mut ChaCha8Rng) -> Vec<Vec<u8>> {
    KNOWN_REPLY_CODES
        .iter()
        .filter_map(|&code| {
            let len = reply_len_for_code(code)?;
            let mut frame = vec![code];
            // The 0x10 reply's first data byte is a fixed 00.
            frame.extend((1..len - 2).map(|j| {
                if code == 0x10 && j == 1 {
                    0
                } else {
                    rng.random()
                }
            }));
            let sum = checksum(&frame);
            frame.extend_from_slice(&sum.to_be_bytes());
            Some(frame)
        })
        .collect()
}

fn command_frames() -> Vec<Vec<u8>> {
    [
        Command::RawSensorBits,
        Command::StabilizedVectors,
        Command::InstantaneousVectors,
        Command::InstantaneousQuaternion,
        Command::StabilizedQuaternion,
        Command::CaptureGyroBias,
        Command::Temperature,
        Command::InstantaneousOrientationMatrix,
        Command::StabilizedOrientationMatrix,
        Command::StabilizedQuaternionVectors,
        Command::InstantaneousQuaternionVectors,
        Command::InstantaneousEuler,
        Command::StabilizedEuler,
        Command::StabilizedEulerVectors,
        Command::SetContinuous { command: 0x31 },
        Command::SetContinuous { command: 0 },
        Command::Tare,
        Command::RemoveTare,
        Command::ReadEeprom { address: 230 },
        Command::WriteEeprom {
            address: 130,
            value: 10_000,
        },
        Command::FirmwareVersion,
        Command::SerialNumber,
    ]
    .iter()
    .map(Command::to_bytes)
    .collect()
}

fn mip_frames(rng: &mut ChaCha8Rng) -> Vec<Vec<u8>> {
    // (descriptor set, [(field descriptor, data length)]): IMU data as a unit streams it, base and
    // 3DM commands and their replies (an ack field 0xF1 and a response field).
    let shapes: [(u8, &[(u8, usize)]); 7] = [
        (
            descriptor_set::IMU_DATA,
            &[(0x04, 12), (0x05, 12), (0xD5, 8)],
        ),
        (
            descriptor_set::IMU_DATA,
            &[(0x01, 12), (0x02, 12), (0x03, 12), (0x0E, 4), (0x14, 6)],
        ),
        (
            descriptor_set::IMU_DATA,
            &[(0x07, 12), (0x08, 12), (0x12, 12), (0x99, 3)],
        ),
        (descriptor_set::BASE_COMMAND, &[(0x01, 0)]),
        (descriptor_set::BASE_COMMAND, &[(0xF1, 2), (0x81, 80)]),
        (descriptor_set::COMMAND_3DM, &[(0x0F, 9)]),
        (descriptor_set::COMMAND_3DM, &[(0xF1, 2), (0x86, 2)]),
    ];
    shapes
        .iter()
        .map(|(set, fields)| {
            let mut b = PacketBuilder::new(*set);
            for &(descriptor, len) in fields.iter() {
                let data: Vec<u8> = (0..len).map(|_| rng.random()).collect();
                // Every shape above fits a packet's payload.
                let _ = b.field(descriptor, &data);
            }
            b.build().as_bytes().to_vec()
        })
        .collect()
}

fn xsens_frames(rng: &mut ChaCha8Rng) -> Vec<Vec<u8>> {
    // (message id, [(data id, item size)]): MTData2 as a unit streams it (float32, fp1220,
    // fp1632 and float64 items, an unknown id), requests, acknowledgements, replies with data
    // and one extended-length message.
    let items: [&[(u16, u8)]; 4] = [
        &[
            (0x1020, 2),
            (0x1060, 4),
            (0x4040, 12),
            (0x8040, 12),
            (0xE020, 4),
        ],
        &[
            (0x1010, 12),
            (0x4021, 12),
            (0x8022, 18),
            (0xC023, 24),
            (0x0810, 4),
        ],
        &[(0xA010, 20), (0x4010, 12), (0x8030, 16), (0x2010, 16)],
        &[(0x1060, 4), (0x4020, 12), (0x8020, 12), (0xC020, 12)],
    ];
    let mut messages = Vec::new();
    for items in items {
        let mut data = Vec::new();
        for &(id, size) in items {
            data.extend_from_slice(&id.to_be_bytes());
            data.push(size);
            data.extend((0..size).map(|_| rng.random::<u8>()));
        }
        messages.push(Message::new(mid::MT_DATA2, &data));
    }
    let others = [
        (mid::GO_TO_CONFIG, 0),
        (mid::GO_TO_CONFIG_ACK, 0),
        (mid::WAKE_UP, 0),
        (mid::DEVICE_ID, 4),
        (mid::PRODUCT_CODE, 14),
        (mid::FIRMWARE_REV, 11),
        (mid::SET_OUTPUT_CONFIGURATION, 20),
        (mid::OUTPUT_CONFIGURATION, 20),
        (mid::ERROR, 1),
        (0x0D, 300),
    ];
    for (m, n) in others {
        let data: Vec<u8> = (0..n).map(|_| rng.random()).collect();
        messages.push(Message::new(m, &data));
    }
    messages
        .into_iter()
        .filter_map(Result::ok)
        .map(|m| m.as_bytes().to_vec())
        .collect()
}
