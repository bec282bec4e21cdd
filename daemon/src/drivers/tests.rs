//! The device layer at CPU speed: probing (a streaming unit recognised without a command, an
//! idle unit asked, a silent one given up on) and the session a probed unit gets.

use std::time::{Duration, Instant};

use imu_proto::DeviceProtocol;
use imu_proto::command::Command;
use imu_proto::mip::MipCommand;
use imu_sim::virtual_device::Request;

use super::scripted::{Fate, Harness, Peer};
use super::*;
use crate::config::AcquisitionMode;
use crate::pipeline::Acquisition;

fn probing(mode: AcquisitionMode, peer: impl FnOnce(Instant) -> Peer) -> Harness<Device> {
    let mut config = Config::default();
    config.device.protocol = None;
    config.device.mode = mode;
    // Unlike the 100 Hz the units stream, so a poll rate reported is told apart.
    config.device.poll_rate_hz = 40.0;
    let origin = Instant::now();
    Harness::new(Device::new(&config), peer(origin), origin)
}

#[test]
fn a_streaming_gx1_is_recognised_without_a_command() {
    let mut h = probing(AcquisitionMode::Continuous, |o| {
        let mut p = Peer::clean(DeviceProtocol::Gx1, o);
        p.start_streaming(
            &Command::SetContinuous {
                command: Command::RawSensorBits.code(),
            }
            .to_bytes(),
            o,
        );
        p
    });
    h.start_up();
    assert!(h.seen.ready.is_some(), "{:?}", h.seen.failed);
    assert_eq!(h.seen.ready.as_ref().unwrap().protocol, "3dm-gx1");
    // The probe asked nothing: the first bytes written are the GX1 start-up's blind stop.
    assert_eq!(
        h.written[0].1,
        Command::SetContinuous { command: 0 }.to_bytes()
    );
    // The frames heard while listening were logged (frames only, no samples of them).
    assert!(h.seen.frames > 3);
}

#[test]
fn an_idle_gx1_answers_the_firmware_query() {
    let mut h = probing(AcquisitionMode::Continuous, |o| {
        Peer::clean(DeviceProtocol::Gx1, o)
    });
    h.start_up();
    assert_eq!(h.seen.ready.as_ref().map(|i| i.protocol), Some("3dm-gx1"));
    assert_eq!(h.written[0].1, Command::FirmwareVersion.to_bytes());
    // It listened first.
    assert_eq!(h.written[0].0 - h.origin, probe::LISTEN);
}

#[test]
fn an_idle_mip_unit_acknowledges_set_to_idle() {
    let mut h = probing(AcquisitionMode::Continuous, |o| {
        Peer::clean(DeviceProtocol::Mip, o)
    });
    h.start_up();
    assert_eq!(h.seen.ready.as_ref().map(|i| i.protocol), Some("mip"));
    assert_eq!(h.written[1].1, MipCommand::SetToIdle.to_packet().as_bytes());
}

#[test]
fn a_silent_port_fails_the_probe_and_a_corrupt_answer_is_asked_again_next_session() {
    let mut h = probing(AcquisitionMode::Continuous, |o| {
        let mut first = true;
        Peer::new(
            DeviceProtocol::Mip,
            Box::new(move |_, r| match r {
                Request::Mip(_) if first => {
                    first = false;
                    Fate::Corrupt
                }
                _ => Fate::Deliver,
            }),
            o,
        )
    });
    h.start_up();
    let why = h.seen.failed.clone().expect("failed");
    assert!(why.contains("answers neither"), "{why}");
    // The next session's probe asks again and finds it.
    h.restart();
    h.start_up();
    assert_eq!(h.seen.ready.as_ref().map(|i| i.protocol), Some("mip"));
}

/// The bug this layer fixed: a probed MIP unit with `mode = "polled"` streams, so its data
/// rate is measured, not the poll rate reported.
#[test]
fn a_probed_mip_unit_configured_polled_reports_its_measured_rate() {
    let mut h = probing(AcquisitionMode::Polled, |o| {
        Peer::clean(DeviceProtocol::Mip, o)
    });
    h.start_up();
    assert_eq!(h.seen.ready.as_ref().map(|i| i.protocol), Some("mip"));
    assert_eq!(h.pipeline.session().acquisition, Acquisition::Streaming);
    h.run_until(Duration::from_secs(3), |_| false);
    let rate = h.pipeline.sample_rate_hz().expect("measured after 2 s");
    assert!((rate - 100.0).abs() < 0.5, "{rate} Hz (poll rate 40)");
    assert_eq!(h.pipeline.counters().samples_lost, 0);
}
