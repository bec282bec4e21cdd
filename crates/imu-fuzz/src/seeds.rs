//! Seed inputs a corpus starts from (`imu-fuzz seed`): valid frames of every kind the codec knows,
//! built by the codec's own encoders, alone, in runs, between garbage, cut short and with a bad
//! checksum, each under a few chunk layouts. The fuzzers grow the corpus from there.

use imu_proto::Command;
use imu_proto::checksum::checksum;
use imu_proto::mip::{PacketBuilder, descriptor_set};
use imu_proto::reply::{KNOWN_REPLY_CODES, reply_len_for_code};
use imu_proto::vectornav::binary::{common, group, imu, time};
use imu_proto::vectornav::{
    BinaryData, BinaryMessage, BinaryOutputConfig, Check, DeltaTheta, OutputFields, Register,
    TimeStatus, VnCommand, VnReply,
};
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
        Target::VectornavDecoder => vectornav_frames(&mut rng),
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

fn vectornav_frames(rng: &mut ChaCha8Rng) -> Vec<Vec<u8>> {
    let mut v3 = || -> [f32; 3] { [rng.random(), rng.random(), rng.random()] };
    let data = BinaryData {
        startup_ns: Some(123_456_789),
        gps_ns: Some(1_400_000_000_000_000_000),
        time_status: Some(TimeStatus(7)),
        uncomp_mag_gauss: Some(v3()),
        uncomp_accel_m_s2: Some(v3()),
        uncomp_gyro_rad_s: Some(v3()),
        temp_c: Some(25.0),
        pres_kpa: Some(101.0),
        delta_theta: Some(DeltaTheta {
            dt_s: 0.00125,
            theta_deg: v3(),
        }),
        delta_vel_m_s: Some(v3()),
        mag_gauss: Some(v3()),
        accel_m_s2: Some(v3()),
        angular_rate_rad_s: Some(v3()),
        ..BinaryData::default()
    };
    // Binary messages as a unit streams them (a VN-100's IMU fields, a VN-200's with GPS time),
    // then the register sentences of a start-up, an error and the power-up YPR output.
    let layouts: [(u16, u16, u16); 3] = [
        (common::TIME_STARTUP, 0, 0x070E),
        (
            common::TIME_STARTUP,
            time::TIME_GPS | time::TIME_STATUS,
            0x07FE,
        ),
        (
            common::IMU | common::DELTA_THETA_VEL | common::MAG_PRES,
            0,
            0,
        ),
    ];
    let mut frames: Vec<Vec<u8>> = layouts
        .iter()
        .filter_map(|&(c, t, i)| {
            let mut f = OutputFields::default();
            f.words[group::COMMON] = c;
            f.words[group::TIME] = t;
            f.words[group::IMU] = i;
            BinaryMessage::encode(f, &data)
                .ok()
                .map(|m| m.as_bytes().to_vec())
        })
        .collect();
    let mut fields = OutputFields::default();
    fields.words[group::IMU] = imu::UNCOMP_ACCEL | imu::UNCOMP_GYRO;
    let binary_output = Register::BinaryOutput {
        index: 1,
        config: BinaryOutputConfig {
            async_mode: 1,
            rate_divisor: 4,
            fields,
        },
    };
    let sentences = [
        VnCommand::Read(1).to_sentence(Check::Checksum8),
        VnCommand::Write(Register::AsyncOutputType(0)).to_sentence(Check::Crc16),
        VnCommand::Write(binary_output.clone()).to_sentence(Check::Wildcard),
        VnReply::Read(Register::Model("VN-100T-CR".into())).to_sentence(Check::Checksum8),
        VnReply::Read(Register::SerialNumber(100_012_345)).to_sentence(Check::Checksum8),
        VnReply::Written(binary_output).to_sentence(Check::Checksum8),
        VnReply::Error(8).to_sentence(Check::Checksum8),
        VnReply::Ypr([10.5, -0.25, 3.0]).to_sentence(Check::Checksum8),
    ];
    frames.extend(sentences.iter().map(|s| s.as_bytes().to_vec()));
    frames
}
