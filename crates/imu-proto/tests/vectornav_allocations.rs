//! The VectorNav decoder's hot path allocates nothing: a stream of calibration binary messages
//! (with and without GPS time) interleaved with register replies and `$VNYPR` outputs is
//! framed, checked and decoded, and the replies typed, with no heap allocation once the
//! decoder's buffer has grown to the stream's chunk size; corrupt messages and sentences met
//! while resynchronising allocate only the rejected bytes they hand back.

use imu_proto::vectornav::binary::{common, group, imu, time};
use imu_proto::vectornav::{
    BinaryData, BinaryMessage, Check, OutputFields, Register, VnDecoder, VnEvent, VnReply,
    calibration_fields,
};

fn data(k: u64) -> BinaryData {
    let x = k as f32;
    BinaryData {
        startup_ns: Some(1_250_000 * k),
        gps_ns: Some(1_400_000_000_000_000_000 + 1_250_000 * k),
        time_status: Some(imu_proto::vectornav::TimeStatus(0b111)),
        uncomp_mag_gauss: Some([0.2, -0.1, 0.45]),
        uncomp_accel_m_s2: Some([0.01 * x, -0.02, -9.81]),
        uncomp_gyro_rad_s: Some([1e-3, -2e-3 * x, 3e-3]),
        temp_c: Some(25.5),
        mag_gauss: Some([0.21, -0.11, 0.44]),
        accel_m_s2: Some([0.0, 0.0, -9.81]),
        angular_rate_rad_s: Some([0.0, 0.0, 1e-3 * x]),
        ..BinaryData::default()
    }
}

/// One second of a VN-200's stream at 800 Hz with a reply and an ASCII output every 100
/// messages: the bytes, and how many messages and sentences they hold.
fn stream() -> (Vec<u8>, usize, usize) {
    let (mut bytes, mut messages, mut sentences) = (Vec::new(), 0, 0);
    for k in 0..800u64 {
        let fields = calibration_fields(k % 2 == 0);
        let m = BinaryMessage::encode(fields, &data(k)).expect("encodable");
        bytes.extend_from_slice(m.as_bytes());
        messages += 1;
        if k % 100 == 0 {
            let reply = VnReply::Read(Register::SerialNumber(100_000 + k as u32));
            bytes.extend_from_slice(reply.to_sentence(Check::Checksum8).as_bytes());
            let ypr = VnReply::Ypr([10.0, -2.5, k as f32]);
            bytes.extend_from_slice(ypr.to_sentence(Check::Crc16).as_bytes());
            sentences += 2;
        }
    }
    (bytes, messages, sentences)
}

/// Pushes `bytes` in 64-byte reads (as a serial port hands them over) and takes every event,
/// typing each sentence as a reply; returns the counts of messages, sentences and rejections
/// and the sum of a decoded value (so nothing is optimised away).
fn decode(d: &mut VnDecoder, bytes: &[u8]) -> (usize, usize, usize, f64) {
    let (mut messages, mut sentences, mut rejected, mut sum) = (0, 0, 0, 0.0);
    for chunk in bytes.chunks(64) {
        d.push(chunk);
        while let Some(ev) = d.next_event() {
            match ev {
                VnEvent::Binary { message, .. } => {
                    messages += 1;
                    sum += f64::from(message.data().uncomp_accel_m_s2.expect("accel")[0]);
                }
                VnEvent::Ascii { sentence, .. } => {
                    sentences += 1;
                    match VnReply::decode(&sentence).expect("a reply") {
                        VnReply::Ypr(ypr) => sum += f64::from(ypr[2]),
                        VnReply::Read(Register::SerialNumber(n)) => sum += f64::from(n),
                        other => panic!("unexpected reply {other:?}"),
                    }
                }
                VnEvent::Rejected { .. } => rejected += 1,
            }
        }
    }
    (messages, sentences, rejected, sum)
}

#[test]
fn decoding_a_stream_of_messages_and_sentences_allocates_nothing() {
    let (bytes, messages, sentences) = stream();
    let mut d = VnDecoder::new();
    // The first pass grows the decoder's buffer to what one read leaves in it.
    let first = decode(&mut d, &bytes);
    assert_eq!((first.0, first.1, first.2), (messages, sentences, 0));
    let mut second = (0, 0, 0, 0.0);
    let info = allocation_counter::measure(|| second = decode(&mut d, &bytes));
    assert_eq!((second.0, second.1, second.2), (messages, sentences, 0));
    assert_eq!(second.3, first.3);
    assert_eq!(
        info.count_total, 0,
        "{} allocations ({} bytes) decoding {messages} messages and {sentences} sentences",
        info.count_total, info.bytes_total
    );
}

#[test]
fn resynchronising_allocates_only_the_rejected_bytes_handed_back() {
    let (mut bytes, messages, _) = stream();
    // A flipped byte in every 50th message's payload and in every sentence's check: each is
    // one rejection (its bytes handed back in a Vec), and no error text is built.
    let (mut corrupted_messages, mut corrupted_sentences) = (0, 0);
    let mut at = 0;
    let mut k = 0;
    while at < bytes.len() {
        let len = match bytes[at] {
            0xFA => {
                let (_, len) = imu_proto::vectornav::binary::header(&bytes[at..])
                    .expect("header")
                    .expect("whole");
                if k % 50 == 7 {
                    bytes[at + len / 2] ^= 0x40;
                    corrupted_messages += 1;
                }
                k += 1;
                len
            }
            _ => {
                let end = at + bytes[at..].iter().position(|&b| b == b'\n').expect("end") + 1;
                bytes[end - 3] ^= 0x01;
                corrupted_sentences += 1;
                end - at
            }
        };
        at += len;
    }
    let mut d = VnDecoder::new();
    let first = decode(&mut d, &bytes);
    let mut second = (0, 0, 0, 0.0);
    let info = allocation_counter::measure(|| second = decode(&mut d, &bytes));
    assert_eq!((second.0, second.1, second.2), (first.0, first.1, first.2));
    assert_eq!((corrupted_messages, corrupted_sentences), (16, 16));
    assert_eq!(
        (second.0, second.1, second.2),
        (
            messages - corrupted_messages,
            0,
            corrupted_messages + corrupted_sentences
        ),
        "every good message decoded, one rejection per corrupted frame"
    );
    assert_eq!(info.count_total, second.2 as u64, "one Vec per rejection");
}

#[test]
fn a_message_longer_than_the_inline_size_is_still_decoded() {
    // Every IMU field and the deltas: longer than a message held inline.
    let mut fields = OutputFields::default();
    fields.words[group::COMMON] = common::TIME_STARTUP | common::DELTA_THETA_VEL;
    fields.words[group::TIME] = time::TIME_GPS | time::TIME_STATUS | time::TIME_UTC;
    fields.words[group::IMU] = imu::IMU_STATUS
        | imu::UNCOMP_MAG
        | imu::UNCOMP_ACCEL
        | imu::UNCOMP_GYRO
        | imu::TEMP
        | imu::PRES
        | imu::DELTA_THETA
        | imu::DELTA_VEL
        | imu::MAG
        | imu::ACCEL
        | imu::ANGULAR_RATE;
    let mut d = data(3);
    d.pres_kpa = Some(101.3);
    d.delta_theta = Some(imu_proto::vectornav::DeltaTheta {
        dt_s: 0.00125,
        theta_deg: [1e-4, 2e-4, -3e-4],
    });
    d.delta_vel_m_s = Some([1e-3, 0.0, -1.2e-2]);
    d.time_utc = Some(imu_proto::vectornav::TimeUtc::default());
    d.imu_status = Some(0);
    let m = BinaryMessage::encode(fields, &d).expect("encodable");
    assert!(m.as_bytes().len() > imu_proto::vectornav::binary::MAX_INLINE_MESSAGE_LEN);
    let parsed = BinaryMessage::parse(m.as_bytes()).expect("parsed");
    assert_eq!(parsed, m);
    assert_eq!(parsed.data(), &d);
}
