//! The GX1 driver at CPU speed: its start-up against the scripted peer (late, corrupt,
//! missing, duplicated replies; a silent device), polling, and its frames through the pipeline.

use std::time::{Duration, Instant};

use imu_proto::DeviceProtocol;
use imu_proto::command::Command;
use imu_proto::reply::Reply;
use imu_sim::virtual_device::Request;

use super::*;
use crate::config::Config;
use crate::drivers::scripted::{Fate, Harness, Peer};
use crate::pipeline::{GainFallback, Pipeline, Sinks};

fn config(mode: AcquisitionMode) -> DeviceConfig {
    let mut c = Config::default().device;
    c.mode = mode;
    c.protocol = Some(imu_proto::DeviceProtocol::Gx1);
    c
}

fn harness(mode: AcquisitionMode, peer: impl FnOnce(Instant) -> Peer) -> Harness<Gx1Driver> {
    let origin = Instant::now();
    Harness::new(Gx1Driver::new(&config(mode)), peer(origin), origin)
}

/// The simulator's GainScales (the demo scenario's device).
const DEVICE_GAINS: (u16, u16, u16) = (7000, 10000, 2000);

fn gains_of(h: &Harness<Gx1Driver>) -> Gains {
    h.seen.sessions.last().expect("a session").gains
}

fn is_eeprom(r: &Request) -> bool {
    matches!(r, Request::Gx1(Command::ReadEeprom { .. }))
}

#[test]
fn a_clean_start_up_reads_the_device_and_streams() {
    let mut h = harness(AcquisitionMode::Continuous, |o| {
        Peer::clean(DeviceProtocol::Gx1, o)
    });
    h.start_up();
    assert_eq!(h.seen.failed, None);
    let id = h.seen.ready.clone().expect("ready");
    assert_eq!(id.model, "3DM-GX1");
    assert_eq!(id.serial, "1001");
    let g = gains_of(&h);
    assert_eq!((g.accel, g.gyro, g.mag), DEVICE_GAINS);
    assert_eq!(g.fallback, GainFallback::NONE);
    assert_eq!(h.seen.sessions.len(), 1);
    assert_eq!(h.seen.sessions[0].acquisition, Acquisition::Streaming);
    // The one temperature before streaming was taken.
    assert_eq!(h.seen.temperatures, 1);
    // Streaming: samples follow, a reading each, at the scenario's 100 Hz.
    let before = h.seen.readings.len();
    h.run_until(Duration::from_secs(1), |_| false);
    let n = h.seen.readings.len() - before;
    assert!((99..=101).contains(&n), "{n} readings in a second");
    // The stop on shutdown.
    assert_eq!(
        h.driver.stop_bytes(),
        Some(Command::SetContinuous { command: 0 }.to_bytes())
    );
}

#[test]
fn a_late_eeprom_reply_is_never_taken_for_the_next_read() {
    // The first accel read's reply comes 1.5 s late (after its time-out, during the retry):
    // it must not be taken for the retry's reply, nor for the gyro's.
    let mut h = harness(AcquisitionMode::Continuous, |o| {
        let mut eeprom = 0;
        Peer::new(
            DeviceProtocol::Gx1,
            Box::new(move |_, r| {
                if is_eeprom(r) {
                    eeprom += 1;
                    if eeprom == 1 {
                        return Fate::Late(Duration::from_millis(1500));
                    }
                }
                Fate::Deliver
            }),
            o,
        )
    });
    h.start_up();
    let g = gains_of(&h);
    assert_eq!((g.accel, g.gyro, g.mag), DEVICE_GAINS);
    assert_eq!(g.fallback, GainFallback::NONE);
}

#[test]
fn corrupt_and_duplicated_replies_give_the_device_gains() {
    let mut h = harness(AcquisitionMode::Continuous, |o| {
        let mut eeprom = 0;
        Peer::new(
            DeviceProtocol::Gx1,
            Box::new(move |_, r| {
                if !is_eeprom(r) {
                    return Fate::Deliver;
                }
                eeprom += 1;
                match eeprom {
                    1 | 4 => Fate::Corrupt,
                    2 | 5 => Fate::Duplicate,
                    _ => Fate::Deliver,
                }
            }),
            o,
        )
    });
    h.start_up();
    assert!(h.seen.rejected > 0, "the corrupt replies were rejected");
    let g = gains_of(&h);
    assert_eq!((g.accel, g.gyro, g.mag), DEVICE_GAINS);
    assert_eq!(g.fallback, GainFallback::NONE);
}

#[test]
fn replies_out_of_order_are_never_taken_for_another_request() {
    // Every fifth answer is held back and sent after the next one: fence replies after
    // EEPROM replies, EEPROM replies after fence replies, of reads of different words.
    let mut h = harness(AcquisitionMode::Continuous, |o| {
        Peer::new(
            DeviceProtocol::Gx1,
            Box::new(|n, _| {
                if n % 5 == 4 {
                    Fate::Reordered
                } else {
                    Fate::Deliver
                }
            }),
            o,
        )
    });
    h.start_up();
    assert!(h.seen.ready.is_some(), "{:?}", h.seen.failed);
    let g = gains_of(&h);
    assert_eq!((g.accel, g.gyro, g.mag), DEVICE_GAINS);
}

#[test]
fn a_gain_that_never_answers_falls_back_alone() {
    let gyro = imu_proto::device::GYRO_GAIN_SCALE_ADDR;
    let mut h = harness(AcquisitionMode::Continuous, |o| {
        Peer::new(
            DeviceProtocol::Gx1,
            Box::new(move |_, r| match r {
                Request::Gx1(Command::ReadEeprom { address }) if *address == gyro => Fate::Missing,
                _ => Fate::Deliver,
            }),
            o,
        )
    });
    h.start_up();
    assert!(h.seen.ready.is_some(), "{:?}", h.seen.failed);
    let g = gains_of(&h);
    let fb = Config::default().device.fallback_gains;
    assert_eq!(
        (g.accel, g.gyro, g.mag),
        (DEVICE_GAINS.0, fb.gyro, DEVICE_GAINS.2)
    );
    assert_eq!(
        g.fallback,
        GainFallback {
            accel: false,
            gyro: true,
            mag: false
        }
    );
    let id = h.seen.ready.clone().unwrap();
    assert!(
        id.details
            .contains(&("gain-scale-gyro-source".into(), "fallback".into()))
    );
    // Three fenced tries of the read, each a reply time-out: seconds of simulated time.
    assert!(h.elapsed() > Duration::from_secs(3), "{:?}", h.elapsed());
}

#[test]
fn a_silent_device_fails_the_start_up_with_the_reason() {
    let mut h = harness(AcquisitionMode::Continuous, |o| {
        let mut p = Peer::clean(DeviceProtocol::Gx1, o);
        p.silent = true;
        p
    });
    h.start_up();
    let why = h.seen.failed.clone().expect("failed");
    assert!(why.contains("stopping continuous mode"), "{why}");
    assert!(why.contains("no reply to command 0x"), "{why}");
    assert!(h.seen.ready.is_none() && h.seen.sessions.is_empty());
}

#[test]
fn a_lost_stream_acknowledgement_is_proven_by_samples() {
    let mut h = harness(AcquisitionMode::Continuous, |o| {
        Peer::new(
            DeviceProtocol::Gx1,
            Box::new(|_, r| match r {
                Request::Gx1(Command::SetContinuous { command }) if *command != 0 => Fate::Missing,
                _ => Fate::Deliver,
            }),
            o,
        )
    });
    h.start_up();
    assert!(h.seen.ready.is_some(), "{:?}", h.seen.failed);
    assert!(!h.seen.readings.is_empty());
}

#[test]
fn a_unit_found_streaming_is_stopped_first() {
    let mut h = harness(AcquisitionMode::Continuous, |o| {
        Peer::streaming(DeviceProtocol::Gx1, o)
    });
    h.start_up();
    assert!(h.seen.ready.is_some(), "{:?}", h.seen.failed);
    let g = gains_of(&h);
    assert_eq!((g.accel, g.gyro, g.mag), DEVICE_GAINS);
}

#[test]
fn polled_mode_polls_at_its_rate_with_temperatures() {
    let mut h = harness(AcquisitionMode::Polled, |o| {
        Peer::clean(DeviceProtocol::Gx1, o)
    });
    h.start_up();
    assert!(h.seen.ready.is_some(), "{:?}", h.seen.failed);
    assert_eq!(
        h.seen.sessions[0].acquisition,
        Acquisition::Polled { rate_hz: 100.0 }
    );
    assert_eq!(h.driver.stop_bytes(), None);
    let (readings, temps) = (h.seen.readings.len(), h.seen.temperatures);
    h.run_until(Duration::from_millis(2_005), |_| false);
    // 100 polls a second, every 100th a temperature (1 Hz).
    let polls = h.seen.readings.len() - readings + (h.seen.temperatures - temps) as usize;
    assert!((200..=201).contains(&polls), "{polls}");
    assert_eq!(h.seen.temperatures - temps, 2);
}

/// A raw-bits reply with `ticks`.
fn raw(ticks: u16) -> Reply {
    Reply::RawSensorBits {
        mag: [32_768; 3],
        accel: [32_768, 32_768, 32_768 + 4681],
        rate: [32_768; 3],
        ticks,
    }
}

/// The 3DM-GX1's usual GainScales.
fn test_gains(fallback: GainFallback) -> Gains {
    Gains {
        accel: 7000,
        gyro: 10000,
        mag: 2000,
        fallback,
    }
}

/// A session-set driver and its pipeline, as the offline path and a passive unit run them.
fn streaming(mode: AcquisitionMode, fallback: GainFallback) -> (Gx1Driver, Pipeline) {
    let cfg = config(mode);
    let gains = test_gains(fallback);
    let driver = Gx1Driver::with_session(&cfg, gains);
    (driver, Pipeline::new(session(&cfg, gains), None))
}

/// Feeds `bytes` to `driver` and every event to `pipeline` at host time `t_ns`.
fn feed(driver: &mut Gx1Driver, p: &mut Pipeline, bytes: &[u8], t_ns: u64, sinks: &mut Sinks) {
    driver.handle_input(bytes, Instant::now());
    let mut slot = FrameSlot::default();
    while let Some(ev) = driver.poll_event(&mut slot) {
        match ev {
            DriverEvent::Frame => p.on_frame(&mut slot, t_ns, t_ns, sinks),
            DriverEvent::Rejected {
                bytes,
                offset,
                reason,
            } => crate::pipeline::log_rejected(bytes, offset, reason, t_ns, t_ns, sinks),
            other => panic!("unexpected {other:?}"),
        }
    }
}

#[test]
fn continuous_gaps_are_counted_and_flagged() {
    let (mut d, mut p) = streaming(AcquisitionMode::Continuous, GainFallback::NONE);
    let mut sinks = Sinks::default();
    let lost = [300u64, 301, 302, 500];
    for k in 0..1000u64 {
        if lost.contains(&k) {
            continue;
        }
        // 100 Hz on 6.5536 ms ticks: steps of 1 and 2 ticks, and a wrap past 65535.
        let ticks = ((k as f64 * 0.01 / 6.5536e-3).floor() as u64 + 65_000) % 65_536;
        feed(
            &mut d,
            &mut p,
            &raw(ticks as u16).to_bytes(),
            k * 10_000_000,
            &mut sinks,
        );
    }
    assert_eq!(p.counters().samples, 996);
    assert_eq!(p.counters().samples_lost, 4);
    // Without a calibration the corrected stream is the GainScale conversion: z = +1 g.
    assert!(p.calibration().is_none());
}

/// Each frame reaches the log once, in arrival order: a data frame with its sample (one
/// record), a temperature reply's frame before the temperature, rejected bytes as such.
#[test]
fn every_frame_is_logged_once_in_arrival_order() {
    use imu_bus::recording::{
        RecordedMessage, Recorder, RecordingConfig, for_each_record, list_recordings,
    };
    use imu_proto::decoder::ReplyDecoder;

    let dir = tempfile::tempdir().unwrap();
    let recorder = Recorder::start(
        RecordingConfig {
            dir: dir.path().to_path_buf(),
            prefix: "order".into(),
            ..RecordingConfig::default()
        },
        Vec::new(),
    )
    .unwrap();
    let mut sinks = Sinks {
        recorder: Some(recorder),
        ..Sinks::default()
    };
    let (mut d, mut p) = streaming(AcquisitionMode::Polled, GainFallback::NONE);
    let mut bytes = Vec::new();
    raw(10).encode(&mut bytes);
    Reply::Temperature {
        raw: 2000,
        ticks: 11,
    }
    .encode(&mut bytes);
    bytes.extend_from_slice(&[0xAB, 0xCD]); // garbage
    raw(12).encode(&mut bytes);
    // The offsets the codec gives each event.
    let mut decoder = ReplyDecoder::default();
    decoder.push(&bytes);
    decoder.flush();
    let mut offsets = Vec::new();
    while let Some(ev) = decoder.next_event() {
        offsets.push(ev.offset());
    }
    feed(&mut d, &mut p, &bytes, 5, &mut sinks);
    d.flush();
    feed(&mut d, &mut p, &[], 5, &mut sinks);
    let stats = sinks.recorder.take().unwrap().finish().unwrap();
    // Sample + frame, temperature + its frame, garbage, sample + frame.
    assert_eq!((stats.written, stats.dropped_queue_full), (5, 0));
    let file = &list_recordings(dir.path(), "order").unwrap()[0];
    let mut kinds = String::new();
    let mut frame_offsets = Vec::new();
    for_each_record(file, |m| {
        kinds.push(match m {
            RecordedMessage::Frame(f) => {
                frame_offsets.push(f.stream_offset);
                if f.accepted { 'f' } else { 'x' }
            }
            RecordedMessage::Raw(_) => 'r',
            RecordedMessage::Imu(_) => 'i',
            RecordedMessage::MagneticField(_) => 'm',
            RecordedMessage::Temperature(_) => 't',
            _ => '?',
        });
    })
    .unwrap();
    assert_eq!(kinds, "frimftxfrim");
    assert_eq!(frame_offsets, offsets);
    assert_eq!(p.counters().frames, 3);
}

#[test]
fn polled_streams_do_not_count_gaps() {
    let (mut d, mut p) = streaming(AcquisitionMode::Polled, GainFallback::ALL);
    let mut sinks = Sinks::default();
    for k in 0..300u64 {
        let ticks = (k * k) % 65_536; // irregular polls
        feed(&mut d, &mut p, &raw(ticks as u16).to_bytes(), k, &mut sinks);
    }
    assert_eq!(p.counters().samples_lost, 0);
    assert_eq!(p.sample_rate_hz(), Some(100.0));
}
