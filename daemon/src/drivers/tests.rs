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
use crate::pipeline::{Acquisition, Sinks};

/// The status's `configuration_unverified` byte as the harness's pipeline would publish it.
fn configuration_unverified(h: &Harness<Device>) -> u8 {
    h.pipeline
        .status(&h.driver.stats(), &Sinks::default(), 0, true, 0)
        .configuration_unverified
}

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
        Peer::streaming(DeviceProtocol::Gx1, o)
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
fn an_mti_streaming_from_power_up_is_recognised_without_a_command() {
    let mut h = probing(AcquisitionMode::Continuous, |o| {
        Peer::clean(DeviceProtocol::Xsens, o)
    });
    h.start_up();
    assert_eq!(h.seen.ready.as_ref().map(|i| i.protocol), Some("xsens"));
    // The probe asked nothing: the first bytes written are the start-up's GoToConfig.
    assert_eq!(
        h.written[0].1,
        imu_proto::xsens::XsensCommand::GoToConfig
            .to_message()
            .as_bytes()
    );
    assert_eq!(configuration_unverified(&h), 0);
}

#[test]
fn an_mti_left_in_config_mode_acknowledges_go_to_config() {
    let go_to_config = imu_proto::xsens::XsensCommand::GoToConfig.to_message();
    let mut h = probing(AcquisitionMode::Continuous, |o| {
        Peer::clean(DeviceProtocol::Xsens, o)
    });
    // The last host left it in config mode (imud's stop on shutdown): no stream to hear.
    let origin = h.origin;
    h.peer.receive(go_to_config.as_bytes(), origin);
    h.start_up();
    assert_eq!(h.seen.ready.as_ref().map(|i| i.protocol), Some("xsens"));
    // Asked in turn: the GX1 firmware query, a MIP "set to idle", then GoToConfig.
    assert_eq!(h.written[0].1, Command::FirmwareVersion.to_bytes());
    assert_eq!(h.written[1].1, MipCommand::SetToIdle.to_packet().as_bytes());
    assert_eq!(h.written[2].1, go_to_config.as_bytes());
}

#[test]
fn an_idle_gx1_answers_the_firmware_query() {
    let mut h = probing(AcquisitionMode::Continuous, |o| {
        Peer::clean(DeviceProtocol::Gx1, o)
    });
    h.start_up();
    assert_eq!(h.seen.ready.as_ref().map(|i| i.protocol), Some("3dm-gx1"));
    assert_eq!(h.written[0].1, Command::FirmwareVersion.to_bytes());
    assert_eq!(configuration_unverified(&h), 0);
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
fn a_vectornav_unit_is_recognised_by_its_power_up_output_and_configured() {
    let mut h = probing(AcquisitionMode::Continuous, |o| {
        Peer::clean(DeviceProtocol::Vectornav, o)
    });
    h.start_up();
    let id = h
        .seen
        .ready
        .clone()
        .unwrap_or_else(|| panic!("{:?}", h.seen.failed));
    assert_eq!(id.protocol, "vectornav");
    // Its $VNYPR output decided while listening: the first bytes written are the start-up's
    // "ASCII output off".
    assert!(h.written[0].1.starts_with(b"$VNWRG,06,0*"));
    assert_eq!(configuration_unverified(&h), 0);
    h.run_until(Duration::from_secs(2), |_| false);
    assert!(h.pipeline.counters().samples >= 190);
    assert_eq!(h.pipeline.counters().samples_lost, 0);
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
    // Set up and read back: verified.
    assert_eq!(configuration_unverified(&h), 0);
}

fn passive(
    protocol: Option<DeviceProtocol>,
    peer: impl FnOnce(Instant) -> Peer,
) -> Harness<Device> {
    let mut config = Config::default();
    config.device.protocol = protocol;
    config.device.configure = false;
    let origin = Instant::now();
    Harness::new(Device::new(&config), peer(origin), origin)
}

/// A unit that powered up streaming: a GX1 in continuous mode, a MIP unit resumed.
fn streaming_peer(protocol: DeviceProtocol, origin: Instant) -> Peer {
    Peer::streaming(protocol, origin)
}

fn detail<'a>(id: &'a DeviceIdentity, key: &str) -> Option<&'a str> {
    id.details
        .iter()
        .find(|(k, _)| k == key)
        .map(|(_, v)| v.as_str())
}

#[test]
fn a_passive_streaming_unit_is_published_sample_for_sample_and_never_sent_a_byte() {
    for (protocol, configured) in [
        (DeviceProtocol::Gx1, None),
        (DeviceProtocol::Gx1, Some(DeviceProtocol::Gx1)),
        (DeviceProtocol::Mip, None),
        (DeviceProtocol::Mip, Some(DeviceProtocol::Mip)),
        (DeviceProtocol::Xsens, None),
        (DeviceProtocol::Xsens, Some(DeviceProtocol::Xsens)),
        (DeviceProtocol::Vectornav, None),
        (DeviceProtocol::Vectornav, Some(DeviceProtocol::Vectornav)),
    ] {
        let mut h = passive(configured, |o| streaming_peer(protocol, o));
        h.start_up();
        let id = h
            .seen
            .ready
            .clone()
            .unwrap_or_else(|| panic!("{:?}", h.seen.failed));
        assert_eq!(id.protocol, protocol.name());
        assert_eq!(detail(&id, "configuration-verified"), Some("false"));
        h.run_until(Duration::from_secs(3), |_| false);
        let what = format!("{protocol}, configured {configured:?}");
        assert!(h.written.is_empty(), "{what}: wrote {:?}", h.written);
        assert_eq!(h.driver.stop_bytes(), None, "{what}");
        // Every sample the unit sent became one, the probe's included.
        assert_eq!(h.pipeline.counters().samples, h.peer.sent, "{what}");
        assert_eq!(h.pipeline.counters().samples_lost, 0, "{what}");
        // Measured, not configured. The samples the probe heard are handed over at once when it
        // decides, so the first stamps are late by up to its 30 ms and approach the clock fit at
        // 0.5 % a spacing: within 1 % over these 3 s.
        let rate = h.pipeline.sample_rate_hz().expect("measured");
        assert!((rate - 100.0).abs() < 1.0, "{what}: {rate}");
        assert_eq!(h.pipeline.session().acquisition, Acquisition::Streaming);
        // Asked nothing: the status says so.
        assert_eq!(configuration_unverified(&h), 1, "{what}");
    }
}

#[test]
fn a_passive_mip_unit_with_gnss_time_hands_it_over_and_the_gnss_stamps_lock() {
    let epoch_utc_s = 1_767_225_600.0;
    let mut h = passive(Some(DeviceProtocol::Mip), |o| {
        Peer::streaming_with(DeviceProtocol::Mip, o, |s| {
            s.device.gnss_time = true;
            s.device.gnss_epoch_utc_s = epoch_utc_s;
        })
    });
    h.pipeline.set_time_source(crate::config::TimeSource::Gnss);
    h.start_up();
    let id = h.seen.ready.clone().unwrap();
    assert_eq!(detail(&id, "gps-timestamp"), Some("true"));
    h.run_until(Duration::from_secs(4), |_| false);
    // Every reading carries valid GNSS time: the scenario's epoch plus whole 10 ms samples
    // (the peer's scenario clock starts at power-up, on the sample grid).
    assert!(h.seen.readings.len() > 300);
    for r in &h.seen.readings {
        let g = r.gnss.expect("GNSS time");
        assert!(g.valid);
        let since_ns = g.utc_ns - (epoch_utc_s * 1e9) as i64;
        assert_eq!(since_ns % 10_000_000, 0, "{since_ns}");
    }
    let s = h
        .pipeline
        .status(&h.driver.stats(), &Sinks::default(), 0, true, 0);
    assert_eq!(s.time_source, imu_bus::sample::time_source::GNSS);
    assert_eq!(s.time_sync, imu_bus::sample::time_sync::GNSS_LOCKED);
    assert_eq!((s.gnss_valid_transitions, s.gnss_lost_transitions), (1, 0));
}

#[test]
fn a_passive_gx1_takes_the_configured_gains_flagged_as_fallbacks() {
    let mut h = passive(Some(DeviceProtocol::Gx1), |o| {
        streaming_peer(DeviceProtocol::Gx1, o)
    });
    h.start_up();
    let g = h.pipeline.gains();
    let fb = Config::default().device.fallback_gains;
    assert_eq!((g.accel, g.gyro, g.mag), (fb.accel, fb.gyro, fb.mag));
    assert!(g.fallback.accel && g.fallback.gyro && g.fallback.mag);
    let id = h.seen.ready.clone().unwrap();
    assert_eq!(detail(&id, "gain-scale-accel-source"), Some("fallback"));
}

#[test]
fn a_passive_port_that_stays_silent_fails_without_a_byte_sent() {
    for configured in [None, Some(DeviceProtocol::Mip)] {
        let mut h = passive(configured, |o| Peer::clean(DeviceProtocol::Mip, o));
        h.start_up();
        let why = h.seen.failed.clone().expect("failed");
        assert!(why.contains("passive"), "{why}");
        assert!(h.written.is_empty());
        // The silence time-out (2 s by default) is how long it listened.
        assert_eq!(h.elapsed(), Duration::from_secs(2));
    }
}

#[test]
fn a_passive_gx1_cannot_be_polled() {
    let mut c = Config::default().device;
    c.configure = false;
    c.mode = AcquisitionMode::Polled;
    assert_eq!(config_problem(&c).map(|p| p.0), Some("device.mode"));
}

/// A 7-series stream: IMU packets with the shared reference time (0xD5) and its delta (0xD6),
/// interleaved with estimation-filter (0x82) and system (0xA0) packets carrying the same shared
/// fields. Every IMU packet is a sample on the reference time; the other sets are logged and
/// counted; the IMU packets' delta fields are skipped and counted.
#[test]
fn a_passive_seven_series_stream_interleaving_filter_and_system_sets() {
    use imu_proto::mip::PacketBuilder;
    let vec3 = |v: [f32; 3]| -> Vec<u8> { v.iter().flat_map(|x| x.to_be_bytes()).collect() };
    let mut bytes = Vec::new();
    let n = 250u64;
    for k in 0..n {
        let t_ns = 5_000_000_000 + k * 4_000_000; // 250 Hz
        let mut imu = PacketBuilder::new(0x80);
        imu.field(0x04, &vec3([0.0, 0.0, -1.0])).unwrap();
        imu.field(0x05, &vec3([0.01, 0.0, 0.0])).unwrap();
        imu.field(0xD5, &t_ns.to_be_bytes()).unwrap();
        imu.field(0xD6, &4_000_000u64.to_be_bytes()).unwrap();
        bytes.extend_from_slice(imu.build().as_bytes());
        if k % 5 == 0 {
            // Filter: attitude quaternion (0x03, 4 floats + valid flags), then the shared times.
            let mut filter = PacketBuilder::new(0x82);
            let mut q = vec3([1.0, 0.0, 0.0]);
            q.extend_from_slice(&0f32.to_be_bytes());
            q.extend_from_slice(&1u16.to_be_bytes());
            filter.field(0x03, &q).unwrap();
            filter.field(0xD5, &t_ns.to_be_bytes()).unwrap();
            filter.field(0xD6, &20_000_000u64.to_be_bytes()).unwrap();
            bytes.extend_from_slice(filter.build().as_bytes());
        }
        if k % 50 == 0 {
            let mut system = PacketBuilder::new(0xA0);
            system.field(0xD5, &t_ns.to_be_bytes()).unwrap();
            bytes.extend_from_slice(system.build().as_bytes());
        }
    }
    let mut config = Config::default().device;
    config.protocol = Some(DeviceProtocol::Mip);
    config.configure = false;
    let mut d = mip::MipDriver::new(&config);
    let now = Instant::now();
    d.start(now);
    d.handle_input(&bytes, now);
    let mut p = crate::pipeline::Pipeline::new(d.initial_session(), None);
    let mut sinks = crate::pipeline::Sinks::default();
    let mut ready = false;
    let mut slot = FrameSlot::default();
    while let Some(ev) = d.poll_event(&mut slot) {
        match ev {
            DriverEvent::Frame => p.on_frame(&mut slot, 1, 1, &mut sinks),
            DriverEvent::Session(s) => p.new_session(s),
            DriverEvent::Ready => ready = true,
            DriverEvent::Identified(_) => {}
            other => panic!("{other:?}"),
        }
    }
    assert!(ready);
    let c = p.counters();
    assert_eq!(c.samples, n);
    assert_eq!(c.frames, n + n / 5 + n / 50);
    assert_eq!(c.fields_skipped, n, "one 0xD6 a packet");
    assert_eq!((c.samples_lost, c.undecodable), (0, 0));
    assert_eq!(
        d.other_sets()
            .iter()
            .map(|(s, n)| (*s, *n))
            .collect::<Vec<_>>(),
        [(0x82, n / 5), (0xA0, n / 50)]
    );
    // On the reference time: the device's own ns.
    assert_eq!(
        p.session().timebase,
        mip::MipTimebase::ReferenceTime.timebase()
    );
}
