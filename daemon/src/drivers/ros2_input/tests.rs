//! The ROS 2 input at CPU speed: messages framed as the DDS reader frames them, fed in any
//! chunking, become readings with the sent values and stamps; damaged bytes and messages are
//! counted, never a panic; a silent topic fails the start-up; and through the pipeline a
//! publisher that skips messages yields exactly that loss count.

use std::time::{Duration, Instant};

use imu_bus::ros2::{Header, Imu, RosMessage, Time, Vector3};
use imu_proto::decoder::RejectReason;

use super::frame::{self, FrameDecoder, FrameEvent};
use super::*;
use crate::pipeline::{Pipeline, Sinks};

/// An event the test keeps: a frame taken out of the driver's slot with its content.
#[derive(Debug)]
enum Ev {
    Frame(Box<FrameSlot>),
    Other(DriverEvent),
}

/// The driver's next event, a frame moved out of the slot the driver wrote it in.
fn poll(d: &mut Ros2InputDriver) -> Option<Ev> {
    let mut slot = FrameSlot::default();
    d.poll_event(&mut slot).map(|ev| match ev {
        DriverEvent::Frame => Ev::Frame(Box::new(slot)),
        other => Ev::Other(other),
    })
}

/// A 200 Hz message `k` stamped from `t0_ns`, with values that identify it.
fn message(k: u64, t0_ns: u64) -> Imu {
    let kf = k as f64;
    Imu {
        header: Header {
            stamp: Time::from_ns(t0_ns + k * 5_000_000),
            frame_id: "camera_imu_optical_frame".into(),
        },
        angular_velocity: Vector3 {
            x: 0.001 * kf,
            y: -0.002 * kf,
            z: 0.5,
        },
        linear_acceleration: Vector3 {
            x: 0.1,
            y: -0.01 * kf,
            z: 9.81,
        },
        ..Imu::default()
    }
}

/// The byte stream the DDS reader would hand the session for `msgs`.
fn stream(msgs: &[Imu]) -> Vec<u8> {
    let mut out = Vec::new();
    for m in msgs {
        frame::encode(&m.to_cdr(), &mut out);
    }
    out
}

fn config() -> Config {
    Config::from_toml_str("[input]\nros2-topic = \"/camera/imu\"\n", "t.toml").unwrap()
}

const T0_NS: u64 = 1_767_225_600_000_000_000;

#[test]
fn every_message_becomes_a_reading_with_its_values_and_stamp_in_any_chunking() {
    let msgs: Vec<Imu> = (0..50).map(|k| message(k, T0_NS)).collect();
    let bytes = stream(&msgs);
    for chunk in [1usize, 7, 333, bytes.len()] {
        let now = Instant::now();
        let mut d = Ros2InputDriver::new(&config(), "/camera/imu");
        d.start(now);
        let mut events = Vec::new();
        for c in bytes.chunks(chunk) {
            d.handle_input(c, now);
            while let Some(ev) = poll(&mut d) {
                events.push(ev);
            }
        }
        assert!(matches!(&events[0], Ev::Other(DriverEvent::Session(s)) if *s == session()));
        let Ev::Other(DriverEvent::Identified(id)) = &events[1] else {
            panic!("{:?}", events[1]);
        };
        assert_eq!(id.protocol, NAME);
        assert!(
            id.details
                .contains(&("dds-topic".into(), "rt/camera/imu".into()))
        );
        assert!(matches!(events[2], Ev::Other(DriverEvent::Ready)));
        let readings: Vec<_> = events[3..]
            .iter()
            .map(|ev| match ev {
                Ev::Frame(slot) => slot.content.reading.unwrap(),
                other => panic!("{other:?}"),
            })
            .collect();
        assert_eq!(readings.len(), msgs.len(), "chunk {chunk}");
        for (r, m) in readings.iter().zip(&msgs) {
            assert_eq!(r.ticks_unwrapped, m.header.stamp.to_ns());
            let a = m.linear_acceleration;
            let g = m.angular_velocity;
            assert_eq!(r.measured.accel_m_s2.as_slice(), [a.x, a.y, a.z]);
            assert_eq!(r.measured.gyro_rad_s.as_slice(), [g.x, g.y, g.z]);
            assert!(r.measured.mag_gauss.iter().all(|v| v.is_nan()));
            assert_eq!(r.counts, None);
        }
        let s = d.stats();
        assert_eq!(s.frames, 50);
        assert_eq!(s.bytes_in, bytes.len() as u64);
        assert_eq!(s.frame_bytes, bytes.len() as u64);
        assert_eq!(s.rejected_bytes, 0);
        // Nothing is ever sent to the topic.
        assert!(!d.poll_transmit(&mut Vec::new()));
        assert_eq!(d.stop_bytes(), None);
    }
}

#[test]
fn bad_cdr_is_counted_as_unusable_and_damaged_bytes_rejected_never_a_panic() {
    let now = Instant::now();
    let mut d = Ros2InputDriver::new(&config(), "/camera/imu");
    d.start(now);
    let good = message(0, T0_NS).to_cdr();
    let mut bytes = Vec::new();
    // A message cut short, a big-endian header, a stamp before 1970 and an unset one.
    frame::encode(&good[..good.len() - 9], &mut bytes);
    let mut be = good.clone();
    be[1] = 0x00;
    frame::encode(&be, &mut bytes);
    let mut before_1970 = message(0, 0);
    before_1970.header.stamp = Time {
        sec: -5,
        nanosec: 0,
    };
    frame::encode(&before_1970.to_cdr(), &mut bytes);
    frame::encode(&message(0, 0).to_cdr(), &mut bytes);
    // Garbage between frames, then a good message, then a header claiming 1 GB, then a good
    // one, then a frame cut by the end of the line.
    bytes.extend_from_slice(b"noise");
    frame::encode(&good, &mut bytes);
    bytes.extend_from_slice(&frame::MAGIC);
    bytes.extend_from_slice(&(1u32 << 30).to_le_bytes());
    frame::encode(&message(1, T0_NS).to_cdr(), &mut bytes);
    let mut cut = Vec::new();
    frame::encode(&good, &mut cut);
    bytes.extend_from_slice(&cut[..40]);
    d.handle_input(&bytes, now);
    d.flush();
    let (mut unusable, mut readings, mut rejected) = (0, 0, Vec::new());
    while let Some(ev) = poll(&mut d) {
        match ev {
            Ev::Frame(slot) => {
                unusable += u32::from(slot.content.unusable);
                readings += u32::from(slot.content.reading.is_some());
            }
            Ev::Other(DriverEvent::Rejected { bytes, reason, .. }) => {
                rejected.push((reason, bytes.len()))
            }
            _ => {}
        }
    }
    assert_eq!(unusable, 4);
    assert_eq!(d.unusable(), 4);
    assert_eq!(readings, 2);
    // The garbage (with the bogus header's length bytes), the bogus magic, the cut frame.
    assert_eq!(
        rejected,
        [
            (RejectReason::Garbage, 5),
            (RejectReason::Malformed, 2),
            (RejectReason::Garbage, 4),
            (RejectReason::Truncated, 40)
        ]
    );
    let s = d.stats();
    assert_eq!(s.bytes_in, s.frame_bytes + s.rejected_bytes);
    assert_eq!(s.frames, 6);
    assert_eq!(s.truncated_frames, 1);
    assert_eq!(s.malformed_frames, 1);
}

#[test]
fn the_decoder_accounts_for_every_byte_of_random_input() {
    let mut rng = 0x2545_f491_4f6c_dd1du64;
    let mut d = FrameDecoder::default();
    let mut seen = 0u64;
    for round in 0..200 {
        let mut chunk = Vec::new();
        for _ in 0..(round % 37) {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            // Often the magic's bytes, so headers of every length turn up.
            chunk.push(match rng % 4 {
                0 => b'R',
                1 => b'2',
                _ => (rng >> 8) as u8,
            });
        }
        if round % 50 == 0 {
            frame::encode(&message(round, T0_NS).to_cdr(), &mut chunk);
        }
        d.push(&chunk);
        while let Some(ev) = d.next_event() {
            seen += match ev {
                FrameEvent::Frame { bytes, .. } | FrameEvent::Rejected { bytes, .. } => {
                    bytes.len() as u64
                }
            };
        }
        let s = d.stats();
        assert_eq!(
            s.bytes_in,
            s.frame_bytes + s.rejected_bytes + d.pending_len() as u64
        );
        assert_eq!(seen, s.frame_bytes + s.rejected_bytes);
    }
    d.flush();
    while d.next_event().is_some() {}
    assert_eq!(d.pending_len(), 0);
}

#[test]
fn a_silent_topic_fails_the_start_up_after_the_silence_timeout() {
    let t0 = Instant::now();
    let mut d = Ros2InputDriver::new(&config(), "/camera/imu");
    d.start(t0);
    let due = d.poll_timeout().unwrap();
    assert_eq!(due - t0, Duration::from_secs_f64(2.0));
    d.handle_timeout(t0 + Duration::from_secs(1));
    assert!(poll(&mut d).is_none());
    d.handle_timeout(due);
    let Some(Ev::Other(DriverEvent::Failed(e))) = poll(&mut d) else {
        panic!("no failure");
    };
    let m = e.to_string();
    assert!(
        m.contains("/camera/imu") && m.contains("rt/camera/imu"),
        "{m}"
    );
}

/// A publisher whose clock jumps back (a restarted simulation time) starts the loss
/// accounting again: no loss counted, no panic, every message a sample with increasing stamps.
#[test]
fn stamps_that_jump_back_start_the_clock_again_without_losses() {
    let mut msgs: Vec<Imu> = (0..100).map(|k| message(k, T0_NS)).collect();
    msgs.extend((0..100).map(|k| message(k, T0_NS - 3_600_000_000_000)));
    let now = Instant::now();
    let mut d = Ros2InputDriver::new(&config(), "/camera/imu");
    d.start(now);
    let mut pipeline = Pipeline::new(d.initial_session(), None);
    let mut sinks = Sinks::default();
    let mut last_stamp = 0;
    for (i, m) in msgs.iter().enumerate() {
        let mono = 1_000_000_000_000 + i as u64 * 5_000_000;
        d.handle_input(&stream(std::slice::from_ref(m)), now);
        while let Some(ev) = poll(&mut d) {
            match ev {
                Ev::Frame(mut slot) => {
                    pipeline.on_frame(&mut slot, mono, mono, &mut sinks);
                    let stamp = pipeline.last_stamp_ns().unwrap();
                    assert!(stamp > last_stamp, "message {i}");
                    last_stamp = stamp;
                }
                Ev::Other(DriverEvent::Session(s)) => pipeline.new_session(s),
                _ => {}
            }
        }
    }
    let c = pipeline.counters();
    assert_eq!(c.samples, 200);
    assert_eq!(c.samples_lost, 0);
}

/// The pipeline fed by the driver: 600 messages at 200 Hz with 7 of them never published (one
/// among the learning intervals, a single one, a burst of 5), host times jittered by up to
/// 3 ms: exactly 7 lost, every other message one sample, none unusable.
#[test]
fn skipped_messages_are_counted_as_losses_at_the_learned_rate() {
    let skipped = [10u64, 200, 400, 401, 402, 403, 404];
    let msgs: Vec<Imu> = (0..600)
        .filter(|k| !skipped.contains(k))
        .map(|k| message(k, T0_NS))
        .collect();
    let now = Instant::now();
    let mut d = Ros2InputDriver::new(&config(), "/camera/imu");
    d.start(now);
    let mut pipeline = Pipeline::new(d.initial_session(), None);
    let mut sinks = Sinks::default();
    let mut rng = 7u64;
    for m in &msgs {
        rng = rng
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let stamp_ns = m.header.stamp.to_ns();
        // Received 1 to 4 ms after its stamp, on a monotonic clock 1000 s behind.
        let mono = stamp_ns - T0_NS + 1_000_000_000_000 + 1_000_000 + (rng >> 33) % 3_000_000;
        d.handle_input(&stream(std::slice::from_ref(m)), now);
        while let Some(ev) = poll(&mut d) {
            match ev {
                Ev::Frame(mut slot) => {
                    pipeline.on_frame(&mut slot, mono, stamp_ns, &mut sinks);
                }
                Ev::Other(DriverEvent::Session(s)) => pipeline.new_session(s),
                _ => {}
            }
        }
    }
    let c = pipeline.counters();
    assert_eq!(c.samples, msgs.len() as u64);
    assert_eq!(c.samples_lost, skipped.len() as u64);
    assert_eq!(c.undecodable, 0);
    // Samples received over the span of the stamps (losses included), as the status says.
    let rate_hz = pipeline.measured_rate_hz().unwrap();
    let want_hz = (msgs.len() - 1) as f64 / (599.0 * 0.005);
    assert!(
        (rate_hz / want_hz - 1.0).abs() < 1e-3,
        "{rate_hz} vs {want_hz}"
    );
}
