//! The MIP driver at CPU speed: its start-up against the scripted peer (late, corrupt and
//! missing replies; a silent unit) and the stream that follows.

use std::time::{Duration, Instant};

use imu_proto::DeviceProtocol;
use imu_proto::mip::MipCommand;
use imu_sim::virtual_device::Request;

use super::*;
use crate::config::Config;
use crate::drivers::scripted::{Fate, Harness, Peer, Script};

fn harness(script: Script) -> Harness<MipDriver> {
    let mut c = Config::default().device;
    c.protocol = Some(DeviceProtocol::Mip);
    let origin = Instant::now();
    Harness::new(
        MipDriver::new(&c),
        Peer::new(DeviceProtocol::Mip, script, origin),
        origin,
    )
}

/// The `n`-th request (from 0) of the command `(set, descriptor)` meets `fate`.
fn nth(cmd: MipCommand, n: usize, fate: Fate) -> Script {
    let mut seen = 0;
    Box::new(move |_, r| {
        if let Request::Mip(req) = r
            && req.descriptor() == cmd.descriptor()
        {
            seen += 1;
            if seen == n + 1 {
                return fate;
            }
        }
        Fate::Deliver
    })
}

#[test]
fn firmware_numbers_read_as_the_vendor_writes_them() {
    assert_eq!(format_mip_firmware(1141), "1.1.41");
    assert_eq!(format_mip_firmware(2004), "2.0.04");
}

#[test]
fn a_clean_start_up_configures_the_preferred_format_and_streams() {
    let mut h = harness(Box::new(|_, _| Fate::Deliver));
    h.start_up();
    let id = h
        .seen
        .ready
        .clone()
        .unwrap_or_else(|| panic!("{:?}", h.seen.failed));
    let detail = |k: &str| {
        id.details
            .iter()
            .find(|(key, _)| key == k)
            .map(|(_, v)| v.clone())
    };
    assert_eq!(detail("rate-hz").as_deref(), Some("100"));
    assert!(detail("clock").unwrap().starts_with("reference time"));
    assert_eq!(h.seen.sessions, vec![session(MipTimebase::ReferenceTime)]);
    // No samples during start-up; then the stream at 100 Hz.
    assert!(h.seen.readings.is_empty());
    h.run_until(Duration::from_secs(3), |_| false);
    let n = h.seen.readings.len();
    assert!((299..=301).contains(&n), "{n}");
    let rate = h.pipeline.sample_rate_hz().expect("measured");
    assert!((rate - 100.0).abs() < 0.5, "{rate}");
    assert_eq!(h.pipeline.counters().samples_lost, 0);
}

#[test]
fn late_and_corrupt_replies_are_retried() {
    // The device information comes after its time-out (and is then taken as the retry's
    // reply: MIP replies name their command); the first "set to idle" ack is corrupted.
    let late = nth(
        MipCommand::GetDeviceInfo,
        0,
        Fate::Late(Duration::from_millis(1500)),
    );
    let mut corrupt = nth(MipCommand::SetToIdle, 0, Fate::Corrupt);
    let mut late = late;
    let mut h = harness(Box::new(move |n, r| match corrupt(n, r) {
        Fate::Deliver => late(n, r),
        f => f,
    }));
    h.start_up();
    assert!(h.seen.ready.is_some(), "{:?}", h.seen.failed);
    assert!(h.seen.rejected > 0);
    let idles = h
        .peer
        .requests
        .iter()
        .filter(|r| matches!(r, Request::Mip(m) if m.descriptor() == MipCommand::SetToIdle.descriptor()))
        .count();
    assert_eq!(idles, 2, "the corrupted ack made a second try");
}

#[test]
fn a_unit_that_never_resumes_fails_the_start_up() {
    let mut h = harness(Box::new(move |_, r| {
        if let Request::Mip(req) = r
            && req.descriptor() == MipCommand::Resume.descriptor()
        {
            return Fate::Missing;
        }
        Fate::Deliver
    }));
    h.start_up();
    let why = h.seen.failed.clone().expect("failed");
    assert!(
        why.starts_with("resuming the unit: no reply to MIP command 01 06"),
        "{why}"
    );
    // The session was set before the resume; no identity.
    assert_eq!(h.seen.sessions.len(), 1);
    assert!(h.seen.ready.is_none());
}

#[test]
fn a_silent_unit_fails_the_start_up_after_three_tries() {
    let mut h = harness(Box::new(|_, _| Fate::Missing));
    h.start_up();
    let why = h.seen.failed.clone().expect("failed");
    assert_eq!(
        why,
        "setting the unit to idle: no reply to MIP command 01 02 within 1.0 s"
    );
    // Three tries: 1 s each, 0.2 s and 0.4 s of back-off between.
    assert_eq!(h.written.len(), 3);
    assert_eq!(h.elapsed(), Duration::from_millis(3600));
}
