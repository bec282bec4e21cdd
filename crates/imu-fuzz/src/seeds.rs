//! Seed inputs a corpus starts from (`imu-fuzz seed`), made by our own encoders and writers: for
//! the stream decoders valid frames of every kind the codec knows, alone, in runs, between
//! garbage, cut short and with a bad checksum, each under a few chunk layouts; for the message
//! decoders each message type; for the MCAP reader small truth files, whole and cut. The ROS 1
//! bag and rosbag2 sqlite3 seeds were written by Python `rosbags` (`tests/python/
//! write_ros_logs.py`, imud writes neither format) and are committed as they are. The fuzzers
//! grow the corpus from there.

use imu_proto::Command;
use imu_proto::checksum::checksum;
use imu_proto::mip::{PacketBuilder, descriptor_set};
use imu_proto::reply::{KNOWN_REPLY_CODES, reply_len_for_code};
use imu_proto::vectornav::binary::{common, group, imu, time};
use imu_proto::vectornav::{
    BinaryData, BinaryMessage, BinaryOutputConfig, Check, DeltaTheta, OutputFields, Register,
    TimeStatus, VnCommand, VnReply,
};
use imu_proto::xsens::{Message, mid};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use imu_proto::ros2_frame;

/// Chunk layouts the seeds are pushed in: whole, byte by byte, and two uneven cycles.
const LAYOUTS: [&[u8]; 4] = [&[], &[1], &[3, 7], &[2, 5, 1]];

/// Seeds of `reply_decoder`: every reply the codec knows.
pub(crate) fn reply_decoder() -> Vec<Vec<u8>> {
    let mut rng = ChaCha8Rng::seed_from_u64(0x5eed);
    let frames = reply_frames(&mut rng);
    stream_seeds(&frames, &mut rng, |stream, i| {
        // Every other seed declares the codes it expects (what the daemon does while streaming).
        if i.is_multiple_of(2) {
            vec![0]
        } else {
            vec![1, stream.first().copied().unwrap_or(0x31)]
        }
    })
}

/// Seeds of `command_decoder`: every command the codec knows.
pub(crate) fn command_decoder() -> Vec<Vec<u8>> {
    let mut rng = ChaCha8Rng::seed_from_u64(0x5eed);
    stream_seeds(&command_frames(), &mut rng, |_, _| Vec::new())
}

/// Seeds of `mip_decoder`: IMU data, commands and replies.
pub(crate) fn mip_decoder() -> Vec<Vec<u8>> {
    let mut rng = ChaCha8Rng::seed_from_u64(0x5eed);
    let frames = mip_frames(&mut rng);
    stream_seeds(&frames, &mut rng, |_, _| Vec::new())
}

/// Seeds of `xsens_decoder`: MTData2 in every number format, requests, acknowledgements and
/// replies, one extended-length message.
pub(crate) fn xsens_decoder() -> Vec<Vec<u8>> {
    let mut rng = ChaCha8Rng::seed_from_u64(0x5eed);
    let frames = xsens_frames(&mut rng);
    stream_seeds(&frames, &mut rng, |_, _| Vec::new())
}

/// Seeds of `vectornav_decoder`: binary messages of a VN-100 and a VN-200, the register
/// sentences of a start-up, an error and the power-up YPR output.
pub(crate) fn vectornav_decoder() -> Vec<Vec<u8>> {
    let mut rng = ChaCha8Rng::seed_from_u64(0x5eed);
    let frames = vectornav_frames(&mut rng);
    stream_seeds(&frames, &mut rng, |_, _| Vec::new())
}

/// Seeds of `ros2_frame`: frames of the ROS 2 input carrying `sensor_msgs/msg/Imu` messages.
pub(crate) fn ros2_frame() -> Vec<Vec<u8>> {
    let mut rng = ChaCha8Rng::seed_from_u64(0x5eed);
    let frames: Vec<Vec<u8>> = ros2_messages()
        .iter()
        .map(|cdr| {
            let mut frame = Vec::new();
            ros2_frame::encode(cdr, &mut frame);
            frame
        })
        .collect();
    stream_seeds(&frames, &mut rng, |_, _| Vec::new())
}

/// Seeds of `cdr`: each message type imud writes, made by its encoder, after the selector that
/// names its type (see `targets::cdr`).
pub(crate) fn cdr() -> Vec<Vec<u8>> {
    crate::targets::cdr::samples()
}

/// Seeds of `mcap`: truth files made by the simulator's writer, complete and cut short (the
/// writer killed before its footer), each read whole and cut at a few places.
pub(crate) fn mcap() -> Vec<Vec<u8>> {
    let mut seeds = Vec::new();
    for n_samples in [0, 3, 12] {
        let file = truth_file(n_samples);
        let len = file.len();
        for cut in [len, len - 1, len / 2, len.saturating_sub(40)] {
            seeds.push(crate::targets::with_cut(cut, &file));
        }
    }
    seeds
}

/// `sensor_msgs/msg/Imu` messages in CDR: a few stamps, frames and values.
pub(crate) fn ros2_messages() -> Vec<Vec<u8>> {
    use imu_rec::ros2::{Header, Imu, RosMessage, Time};
    [
        (0u64, ""),
        (1_700_000_000_123_456_789, "imu_link"),
        (5, "x"),
    ]
    .iter()
    .enumerate()
    .map(|(i, &(t_ns, frame_id))| {
        let x = i as f64;
        Imu {
            header: Header {
                stamp: Time::from_ns(t_ns),
                frame_id: frame_id.to_owned(),
            },
            angular_velocity: [0.01 * x, -0.02, 0.5].into(),
            linear_acceleration: [0.1, 0.2 * x, -9.81].into(),
            ..Imu::default()
        }
        .to_cdr()
    })
    .collect()
}

/// A truth file of `n_samples` samples and one segment, in memory.
fn truth_file(n_samples: u32) -> Vec<u8> {
    use imu_rec::truth::{TruthSample, TruthSegment, TruthWriter};
    let run = std::collections::BTreeMap::from([("seed".to_owned(), "1".to_owned())]);
    let mut sink = std::io::Cursor::new(Vec::new());
    let path = std::path::Path::new("seed.mcap");
    let mut w = TruthWriter::new(path, &mut sink, &run, "[scenario]", "[model]")
        .expect("writing to memory cannot fail");
    let seg = TruthSegment {
        index: 0,
        kind: "static".into(),
        label: "level".into(),
        start_s: 0.0,
        end_s: None,
        gravity_dir_sensor: [0.0, 0.0, -1.0],
        axis_sensor: None,
        table_rate_rad_s: None,
    };
    w.write_segment(&seg).expect("in memory");
    for k in 0..n_samples {
        let t_s = f64::from(k) * 0.01;
        let v = [0.1 * t_s, -0.2, 9.8];
        w.write_sample(&TruthSample {
            seq: u64::from(k),
            command: 0x31,
            ticks: (k * 2) as u16,
            ticks_unwrapped: u64::from(k) * 2,
            t_s,
            time_since_power_on_s: 10.0 + t_s,
            segment: 0,
            specific_force_m_s2: v,
            angular_rate_rad_s: v,
            angular_accel_rad_s2: v,
            mag_field_gauss: v,
            temp_c: 25.0,
            enu_from_sensor: [1.0, 0.0, 0.0, 0.0],
            table_angle_rad: 0.0,
            table_rate_rad_s: 0.0,
            measured_accel_m_s2: v,
            measured_gyro_rad_s: v,
            measured_mag_gauss: v,
            saturated: false,
        })
        .expect("in memory");
    }
    w.finish().expect("in memory");
    sink.into_inner()
}

/// A stream decoder's seeds: the frames alone, in runs, between garbage, cut short and with a
/// bad checksum, each under one of the chunk layouts; `params(stream, i)` gives the target
/// parameters that go between the chunk sizes and the stream.
fn stream_seeds(
    frames: &[Vec<u8>],
    rng: &mut ChaCha8Rng,
    params: impl Fn(&[u8], usize) -> Vec<u8>,
) -> Vec<Vec<u8>> {
    let mut streams: Vec<Vec<u8>> = frames.to_vec();
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
        .map(|(i, stream)| {
            let sizes = LAYOUTS[i % LAYOUTS.len()];
            let mut input = vec![sizes.len() as u8];
            input.extend_from_slice(sizes);
            input.extend(params(&stream, i));
            input.extend_from_slice(&stream);
            input
        })
        .collect()
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
    // (data id, item size) lists: MTData2 as a unit streams it (float32, fp1220, fp1632 and
    // float64 items, an unknown id).
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
