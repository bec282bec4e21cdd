//! The Xsens driver at CPU speed: its start-up against the scripted peer (a unit streaming
//! from power-up, late, corrupt and missing replies, a refused output set, a silent unit) and
//! the stream that follows.

use std::time::{Duration, Instant};

use imu_proto::DeviceProtocol;
use imu_proto::xsens::data::id;
use imu_proto::xsens::{Message, XsensReply};
use imu_sim::virtual_device::Request;
use imu_sim::xsens_device::PRODUCT_CODE;

use super::startup::CHOICES;
use super::*;
use crate::config::Config;
use crate::drivers::scripted::{Fate, Harness, Peer, Script};
use crate::drivers::streaming::StartupMachine;

fn harness(script: Script) -> Harness<XsensDriver> {
    let mut c = Config::default().device;
    c.protocol = Some(DeviceProtocol::Xsens);
    let origin = Instant::now();
    Harness::new(
        XsensDriver::new(&c),
        Peer::new(DeviceProtocol::Xsens, script, origin),
        origin,
    )
}

/// The `n`-th request (from 0) with message id `m` meets `fate`.
fn nth(m: u8, n: usize, fate: Fate) -> Script {
    let mut seen = 0;
    Box::new(move |_, r| {
        if let Request::Xsens(req) = r
            && req.mid() == m
        {
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
fn a_clean_start_up_of_a_streaming_unit_configures_the_preferred_outputs_and_streams() {
    let mut h = harness(Box::new(|_, _| Fate::Deliver));
    h.start_up();
    let id = h
        .seen
        .ready
        .clone()
        .unwrap_or_else(|| panic!("{:?}", h.seen.failed));
    assert_eq!(id.model, PRODUCT_CODE);
    assert_eq!(id.protocol, "xsens");
    assert_eq!(detail(&id, "rate-hz").as_deref(), Some("100"));
    assert_eq!(
        detail(&id, "outputs"),
        Some(CHOICES[0].describe()),
        "the first output set is taken"
    );
    assert!(
        detail(&id, "raw-reading")
            .unwrap()
            .starts_with("AccelerationHR")
    );
    // The magnetic field is a ratio to the calibration's field, and the metadata says so.
    assert_eq!(
        detail(&id, "magnetometer-unit").as_deref(),
        Some(MAGNETOMETER_UNIT)
    );
    assert!(MAGNETOMETER_UNIT.contains("not gauss"));
    assert_eq!(h.seen.sessions, vec![session()]);
    // The unit streamed from power-up: its data before the GoToConfig ack was logged as
    // frames, never made samples, and nothing was rejected.
    assert!(h.seen.frames > 6);
    assert!(h.seen.readings.is_empty());
    assert_eq!(h.seen.rejected, 0);
    h.run_until(Duration::from_secs(3), |_| false);
    let n = h.seen.readings.len();
    assert!((299..=301).contains(&n), "{n}");
    let rate = h.pipeline.sample_rate_hz().expect("measured");
    assert!((rate - 100.0).abs() < 0.5, "{rate}");
    assert_eq!(h.pipeline.counters().samples_lost, 0);
    // HR outputs as the reading, compensated beside them, valid UTC time, temperature.
    let r = &h.seen.readings[10];
    assert!(r.compensated.is_some());
    assert!(r.gnss.is_some_and(|g| g.valid));
    assert!(r.measured.mag_gauss.iter().all(|v| v.is_finite()));
    assert!(h.seen.temperatures >= 299);
    // SampleTimeFine: 100 counts of 10 kHz a sample at 100 Hz (the demo's clock drift is
    // well under a count a sample).
    let dt = h.seen.readings[11].ticks_unwrapped - h.seen.readings[10].ticks_unwrapped;
    assert!((99..=101).contains(&dt), "{dt}");
}

#[test]
fn late_and_corrupt_replies_are_retried() {
    // The first GoToConfig ack is corrupted; the device id comes after its time-out (and is
    // then taken as the retry's answer: answers name their request by id).
    let mut corrupt = nth(mid::GO_TO_CONFIG, 0, Fate::Corrupt);
    let mut late = nth(mid::REQ_DID, 0, Fate::Late(Duration::from_millis(1500)));
    let mut h = harness(Box::new(move |n, r| match corrupt(n, r) {
        Fate::Deliver => late(n, r),
        f => f,
    }));
    h.start_up();
    assert!(h.seen.ready.is_some(), "{:?}", h.seen.failed);
    assert!(h.seen.rejected > 0);
    let configs = h
        .peer
        .requests
        .iter()
        .filter(|r| matches!(r, Request::Xsens(m) if m.mid() == mid::GO_TO_CONFIG))
        .count();
    assert_eq!(configs, 2, "the corrupted ack made a second try");
}

#[test]
fn a_unit_that_never_enters_measurement_mode_fails_the_start_up() {
    // Every try goes missing.
    let mut h = harness(Box::new(|_, r| match r {
        Request::Xsens(m) if m.mid() == mid::GO_TO_MEASUREMENT => Fate::Missing,
        _ => Fate::Deliver,
    }));
    h.start_up();
    let why = h.seen.failed.clone().expect("failed");
    assert!(
        why.starts_with("entering measurement mode: no answer to Xsens message 0x10"),
        "{why}"
    );
    // The session was set before GoToMeasurement; no ready.
    assert_eq!(h.seen.sessions.len(), 1);
    assert!(h.seen.ready.is_none());
}

#[test]
fn a_silent_unit_fails_the_start_up_after_three_tries() {
    let mut h = harness(Box::new(|_, _| Fate::Missing));
    h.peer.silent = true;
    h.start_up();
    let why = h.seen.failed.clone().expect("failed");
    assert_eq!(
        why,
        "entering config mode: no answer to Xsens message 0x30 within 1.0 s"
    );
    // Three tries: 1 s each, 0.2 s and 0.4 s of back-off between.
    assert_eq!(h.written.len(), 3);
    assert_eq!(h.elapsed(), Duration::from_millis(3600));
}

/// Feeds `startup` the answer `reply` and returns the next message it writes.
fn answer(s: &mut Startup, reply: XsensReply, now: Instant) -> (Option<Outcome>, Message) {
    let outcome = s.on_frame(&reply.to_message(), now);
    let bytes = s.tx.pop_back().expect("a request out");
    (outcome, Message::parse(&bytes).unwrap())
}

#[test]
fn a_refused_output_set_falls_back_to_the_next_and_a_different_read_back_fails() {
    let now = Instant::now();
    let mut s = Startup::new(Duration::from_secs(1), Some(400.0), now);
    s.tx.clear();
    // A stream error while entering config mode is no refusal of GoToConfig.
    assert!(
        s.on_frame(&XsensReply::Error(41).to_message(), now)
            .is_none()
    );
    assert!(s.tx.is_empty());
    answer(&mut s, XsensReply::GoToConfigAck, now);
    answer(&mut s, XsensReply::DeviceId(0x0370_03F8), now);
    answer(&mut s, XsensReply::ProductCode("MTi-300-2A5G4".into()), now);
    let (_, write) = answer(&mut s, XsensReply::FirmwareRev(Default::default()), now);
    assert_eq!(write.mid(), mid::SET_OUTPUT_CONFIGURATION);
    assert!(
        write.data().is_empty(),
        "the configuration in force is read first"
    );
    let (_, write) = answer(
        &mut s,
        XsensReply::OutputConfiguration(Default::default()),
        now,
    );
    assert_eq!(
        XsensCommand::decode(&write).unwrap(),
        XsensCommand::SetOutputConfiguration(CHOICES[0].outputs(400))
    );
    // Refused: the next set.
    let (_, write) = answer(&mut s, XsensReply::Error(33), now);
    assert_eq!(
        XsensCommand::decode(&write).unwrap(),
        XsensCommand::SetOutputConfiguration(CHOICES[1].outputs(400))
    );
    let (_, read) = answer(
        &mut s,
        XsensReply::OutputConfiguration(CHOICES[1].outputs(400)),
        now,
    );
    assert_eq!(
        XsensCommand::decode(&read).unwrap(),
        XsensCommand::ReqOutputConfiguration
    );
    // It reads back something else: start-up fails, naming it.
    let outcome = s.on_frame(
        &XsensReply::OutputConfiguration(CHOICES[2].outputs(400)).to_message(),
        now,
    );
    let Some(Outcome::Failed(e)) = outcome else {
        panic!("{outcome:?}")
    };
    assert!(e.to_string().contains("reads back other outputs"), "{e}");
}

#[test]
fn the_hr_outputs_alone_are_tried_before_the_compensated_ones_stand_in() {
    let ids = |k: usize| -> Vec<u16> {
        CHOICES[k]
            .outputs(1000)
            .0
            .iter()
            .map(|o| o.data_id)
            .collect()
    };
    let hr_only = CHOICES
        .iter()
        .position(|c| c.raw == reading::RawSource::HighRate && !c.compensated)
        .expect("an HR-only set");
    let first_compensated_raw = CHOICES
        .iter()
        .position(|c| c.raw == reading::RawSource::Compensated)
        .unwrap();
    assert!(hr_only < first_compensated_raw);
    let set = ids(hr_only);
    assert!(set.contains(&id::ACCELERATION_HR) && set.contains(&id::RATE_OF_TURN_HR));
    for filtered in [id::ACCELERATION, id::RATE_OF_TURN, id::MAGNETIC_FIELD] {
        assert!(!set.contains(&filtered), "{set:x?}");
    }
    assert!(
        !CHOICES[hr_only]
            .describe()
            .split(',')
            .any(|name| name == "Acceleration")
    );
    // Every other HR set carries the compensated outputs beside.
    for k in (0..first_compensated_raw).filter(|&k| k != hr_only) {
        assert!(ids(k).contains(&id::ACCELERATION), "set {k}");
    }
}

#[test]
fn config_problems_name_the_key() {
    let mut c = Config::default().device;
    c.protocol = Some(DeviceProtocol::Xsens);
    assert_eq!(config_problem(&c), None);
    c.rate_hz = Some(99.5);
    assert_eq!(config_problem(&c).map(|p| p.0), Some("device.rate-hz"));
    c.rate_hz = Some(400.0);
    c.mode = AcquisitionMode::Polled;
    assert_eq!(config_problem(&c).map(|p| p.0), Some("device.mode"));
}

#[test]
fn readings_take_the_hr_outputs_as_raw_the_compensated_beside_and_utc_as_gnss() {
    use imu_proto::xsens::data::UTC_VALID;
    use imu_proto::xsens::{Format, MtData2, UtcTime};

    let utc = UtcTime {
        ns: 500_000_000,
        year: 2026,
        month: 3,
        day: 1,
        hour: 12,
        minute: 0,
        second: 0,
        flags: UTC_VALID,
    };
    let first = MtData2 {
        sample_time_fine: Some(u32::MAX - 95),
        acceleration_hr_m_s2: Some([0.1, 0.2, -9.8]),
        rate_of_turn_hr_rad_s: Some([0.01, 0.02, 0.03]),
        acceleration_m_s2: Some([0.0, 0.0, -9.81]),
        rate_of_turn_rad_s: Some([0.0, 0.0, 0.001]),
        magnetic_field_normalised: Some([0.2, 0.0, 0.4]),
        temperature_c: Some(30.5),
        utc: Some(utc),
        ..MtData2::default()
    };
    let mut readings = reading::Readings::new();
    let c = readings.content(&first.to_message(Format::Float64));
    let r = c.reading.expect("a sample");
    assert_eq!(r.measured.accel_m_s2.as_slice(), [0.1, 0.2, -9.8]);
    assert_eq!(r.measured.gyro_rad_s.as_slice(), [0.01, 0.02, 0.03]);
    let comp = r.compensated.expect("compensated beside");
    assert_eq!(comp.accel_m_s2.as_slice(), [0.0, 0.0, -9.81]);
    assert_eq!(comp.gyro_rad_s.as_slice(), [0.0, 0.0, 0.001]);
    let gnss = r.gnss.expect("UTC time");
    assert!(gnss.valid);
    assert_eq!(
        gnss.utc_ns,
        imu_proto::gnss_time::utc_fields_to_unix_ns(2026, 3, 1, 12, 0, 0, 500_000_000).unwrap()
    );
    assert_eq!(c.temperature.map(|t| t.0), Some(30.5));
    assert_eq!(r.command, mid::MT_DATA2);
    assert!(!r.saturated, "no status word: not clipping");

    // The status word's clipping bits are the sample's saturation, whichever sensor's axis
    // clipped; its other bits (here the filter valid bit 1 and the sync-in bit 21) are not.
    for (word, clipped) in [
        (0x0000_0002 | 1 << 21, false),
        (1 << 8, true),
        (1 << 10, true),
        (1 << 11, true),
        (1 << 13, true),
        (1 << 16, true),
        (1 << 17, false),
    ] {
        let m = MtData2 {
            status_word: Some(word),
            ..first
        };
        let r = reading::Readings::new()
            .content(&m.to_message(Format::Float64))
            .reading
            .expect("a sample");
        assert_eq!(r.saturated, clipped, "status word 0x{word:08X}");
    }

    // SampleTimeFine wraps its u32 and is unwrapped; a UTC time without the valid flag is
    // still reported, as invalid.
    let next = MtData2 {
        sample_time_fine: Some(4),
        utc: Some(UtcTime { flags: 0, ..utc }),
        ..first
    };
    let r = readings
        .content(&next.to_message(Format::Float32))
        .reading
        .expect("a sample");
    assert_eq!(r.ticks_unwrapped, (1u64 << 32) + 4);
    assert!(r.gnss.is_some_and(|g| !g.valid));

    // No HR outputs: the compensated ones are the reading, nothing beside them.
    let no_hr = MtData2 {
        acceleration_hr_m_s2: None,
        rate_of_turn_hr_rad_s: None,
        utc: None,
        ..next
    };
    let r = readings
        .content(&no_hr.to_message(Format::Float32))
        .reading
        .expect("a sample");
    assert_eq!(r.measured.accel_m_s2.z, -9.81f32 as f64);
    assert!(r.compensated.is_none() && r.gnss.is_none());

    // The HR outputs alone (the fourth output set, for a unit that refuses its filter's
    // outputs at the HR rate): the HR reading, nothing recorded beside it.
    let hr_only = MtData2 {
        acceleration_m_s2: None,
        rate_of_turn_rad_s: None,
        magnetic_field_normalised: None,
        ..next
    };
    let r = readings
        .content(&hr_only.to_message(Format::Float32))
        .reading
        .expect("a sample");
    assert_eq!(r.measured.accel_m_s2.z, -9.8f32 as f64);
    assert!(r.compensated.is_none() && r.measured.mag_gauss.x.is_nan());

    // No clock: unusable, its temperature still taken; another message: nothing.
    let no_clock = MtData2 {
        sample_time_fine: None,
        ..no_hr
    };
    let c = readings.content(&no_clock.to_message(Format::Float32));
    assert!(c.unusable && c.reading.is_none() && c.temperature.is_some());
    let c = readings.content(&XsensCommand::GoToConfig.to_message());
    assert!(!c.unusable && c.reading.is_none());
}
