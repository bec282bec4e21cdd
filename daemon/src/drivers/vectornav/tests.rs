//! The VectorNav driver at CPU speed: its start-up against the scripted peer (a unit streaming
//! its power-up `$VNYPR` output; late, corrupt and missing replies; a silent unit), the stream
//! that follows and a passive unit.

use std::time::{Duration, Instant};

use imu_proto::DeviceProtocol;
use imu_proto::vectornav::{VnCommand, reg};
use imu_sim::virtual_device::Request;

use super::*;
use crate::config::Config;
use crate::drivers::Driver;
use crate::drivers::scripted::{Fate, Harness, Peer, Script};

fn config(configure: bool) -> DeviceConfig {
    let mut c = Config::default().device;
    c.protocol = Some(DeviceProtocol::Vectornav);
    c.configure = configure;
    c
}

fn harness(script: Script) -> Harness<VnDriver> {
    let origin = Instant::now();
    Harness::new(
        VnDriver::new(&config(true)),
        Peer::new(DeviceProtocol::Vectornav, script, origin),
        origin,
    )
}

/// Whether `r` is a sentence reading or writing register `id`.
fn is_register(r: &Request, id: u8) -> bool {
    match r {
        Request::Vectornav(Ok(VnCommand::Read(i))) => *i == id,
        Request::Vectornav(Ok(VnCommand::Write(w))) => w.id() == id,
        _ => false,
    }
}

/// The `n`-th request (from 0) of register `id` meets `fate`.
fn nth(id: u8, n: usize, fate: Fate) -> Script {
    let mut seen = 0;
    Box::new(move |_, r| {
        if is_register(r, id) {
            seen += 1;
            if seen == n + 1 {
                return fate;
            }
        }
        Fate::Deliver
    })
}

fn detail(id: &DeviceIdentity, key: &str) -> Option<String> {
    id.details
        .iter()
        .find(|(k, _)| k == key)
        .map(|(_, v)| v.clone())
}

#[test]
fn a_clean_start_up_configures_the_binary_output_and_streams() {
    let mut h = harness(Box::new(|_, _| Fate::Deliver));
    h.start_up();
    let id = h
        .seen
        .ready
        .clone()
        .unwrap_or_else(|| panic!("{:?}", h.seen.failed));
    assert_eq!(id.model, imu_sim::vectornav_device::DEFAULT_MODEL);
    assert_eq!(id.protocol, "vectornav");
    assert_eq!(detail(&id, "rate-hz").as_deref(), Some("100"));
    assert_eq!(detail(&id, "rate-divisor").as_deref(), Some("8"));
    assert_eq!(
        detail(&id, "outputs").as_deref(),
        Some("common:0x0001 imu:0x071E")
    );
    assert_eq!(h.seen.sessions, vec![session()]);
    // The power-up YPR output was logged as frames, and no sample came before the output was
    // verified.
    assert!(h.seen.frames > 0);
    assert!(h.seen.readings.is_empty());
    h.run_until(Duration::from_secs(3), |_| false);
    let n = h.seen.readings.len();
    assert!((299..=301).contains(&n), "{n}");
    let rate = h.pipeline.sample_rate_hz().expect("measured");
    assert!((rate - 100.0).abs() < 0.5, "{rate}");
    assert_eq!(h.pipeline.counters().samples_lost, 0);
    let r = &h.seen.readings[0];
    // The uncompensated reading is the raw one; the compensated one is beside it; a VN-100
    // has no GNSS time.
    assert!(r.compensated.is_some());
    assert!(r.measured.mag_gauss.iter().all(|m| m.is_finite()));
    assert_eq!(r.gnss, None);
    assert_eq!(r.command, imu_proto::vectornav::SYNC);
    // Shutdown turns the binary output off.
    let stop = String::from_utf8(h.driver.stop_bytes().unwrap()).unwrap();
    assert!(stop.starts_with("$VNWRG,75,0,8,05,0001,071E*"), "{stop}");
}

#[test]
fn late_and_corrupt_replies_are_retried() {
    // The model comes after its time-out (and is then taken as the retry's reply: register
    // replies name their register); the first "async output off" reply is corrupted.
    let mut late = nth(reg::MODEL, 0, Fate::Late(Duration::from_millis(1500)));
    let mut corrupt = nth(reg::ASYNC_OUTPUT_TYPE, 0, Fate::Corrupt);
    let mut h = harness(Box::new(move |n, r| match corrupt(n, r) {
        Fate::Deliver => late(n, r),
        f => f,
    }));
    h.start_up();
    assert!(h.seen.ready.is_some(), "{:?}", h.seen.failed);
    assert!(h.seen.rejected > 0);
    let offs = h
        .peer
        .requests
        .iter()
        .filter(|r| is_register(r, reg::ASYNC_OUTPUT_TYPE))
        .count();
    assert_eq!(offs, 2, "the corrupted reply made a second try");
}

#[test]
fn a_unit_that_never_confirms_its_output_fails_the_start_up() {
    let mut h = harness(Box::new(move |_, r| {
        if matches!(r, Request::Vectornav(Ok(VnCommand::Read(75)))) {
            return Fate::Missing;
        }
        Fate::Deliver
    }));
    h.start_up();
    let why = h.seen.failed.clone().expect("failed");
    assert!(why.starts_with("no reply to $VNRRG,75*"), "{why}");
    assert!(h.seen.sessions.is_empty() && h.seen.ready.is_none());
}

#[test]
fn a_silent_unit_fails_the_start_up_after_three_tries() {
    let origin = Instant::now();
    let mut peer = Peer::new(
        DeviceProtocol::Vectornav,
        Box::new(|_, _| Fate::Missing),
        origin,
    );
    peer.silent = true;
    let mut h = Harness::new(VnDriver::new(&config(true)), peer, origin);
    h.start_up();
    let why = h.seen.failed.clone().expect("failed");
    assert!(
        why.starts_with("no reply to $VNWRG,06,0*") && why.ends_with("within 1.0 s"),
        "{why}"
    );
    assert_eq!(h.written.len(), 3);
    assert_eq!(h.elapsed(), Duration::from_millis(3600));
}

#[test]
fn a_passive_unit_streaming_its_saved_output_is_taken_and_never_sent_a_byte() {
    let origin = Instant::now();
    let mut h = Harness::new(
        VnDriver::new(&config(false)),
        Peer::streaming(DeviceProtocol::Vectornav, origin),
        origin,
    );
    h.start_up();
    let id = h.seen.ready.clone().expect("ready");
    assert_eq!(
        detail(&id, "configuration-verified").as_deref(),
        Some("false")
    );
    assert_eq!(h.seen.sessions, vec![passive_session()]);
    h.run_until(Duration::from_secs(2), |_| false);
    assert!(h.written.is_empty(), "passive: nothing sent");
    assert_eq!(h.driver.stop_bytes(), None);
    let sent = h.peer.sent;
    let got = h.seen.readings.len() as u64;
    assert!(
        sent >= 190 && got + 1 >= sent && got <= sent,
        "{got} of {sent}"
    );
}

#[test]
fn config_problems_name_the_key() {
    let mut c = config(true);
    c.rate_hz = Some(300.0);
    let (key, why) = config_problem(&c).expect("300 Hz is not 800/n");
    assert_eq!(key, "device.rate-hz");
    assert!(why.contains("800"), "{why}");
    c.rate_hz = Some(400.0);
    assert_eq!(config_problem(&c), None);
}
