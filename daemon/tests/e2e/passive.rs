//! Passive units (`--passive`): a simulated unit that powers up streaming, its protocol unset,
//! is recorded and published sample for sample while imud writes nothing to it.

use super::*;

#[test]
fn a_passive_gx1_powered_up_streaming_is_recorded_sample_for_sample() {
    a_passive_unit_is_recorded_sample_for_sample(DeviceProtocol::Gx1);
}

#[test]
fn a_passive_mip_unit_powered_up_streaming_is_recorded_sample_for_sample() {
    a_passive_unit_is_recorded_sample_for_sample(DeviceProtocol::Mip);
}

#[test]
fn a_passive_xsens_unit_is_recorded_sample_for_sample() {
    a_passive_unit_is_recorded_sample_for_sample(DeviceProtocol::Xsens);
}

#[test]
fn a_passive_vectornav_unit_powered_up_streaming_is_recorded_sample_for_sample() {
    a_passive_unit_is_recorded_sample_for_sample(DeviceProtocol::Vectornav);
}

/// A unit set up and saved with the vendor's tool (the simulator's
/// `device.power-up-streaming`) and a passive imud with the protocol unset: imud sends
/// nothing, recognises the stream, and publishes and records every sample the unit sent, with
/// the sent device times; the status and the metadata say the configuration was not verified.
fn a_passive_unit_is_recorded_sample_for_sample(protocol: DeviceProtocol) {
    let dir = tempfile::tempdir().unwrap();
    let cal_path = dir.path().join("calibration.toml");
    std::fs::write(&cal_path, TRUTH).unwrap();
    let name = unique(&format!("passive-{protocol}"));
    let mut opts = sim_options(dir.path(), false, protocol);
    opts.scenario.device.power_up_streaming = true;
    // imud waits for the device; the unit streams from power-up, so what it sends before imud
    // opens the port waits in the pty for imud to read.
    let imud = Imud::start_with(
        dir.path(),
        &name,
        &dir.path().join("imu0"),
        &cal_path,
        &["--passive"],
    );
    let mut sub = Subscription::<CorrectedSample>::open(&name, Duration::from_secs(10))
        .unwrap_or_else(|e| panic!("{e}: {}", imud.stderr()));
    let (got, report) = collect_run(&mut sub, opts);
    let log = imud.terminate();

    assert!(report.completed);
    assert_eq!(report.bytes_in, 0, "a passive imud writes nothing: {log}");
    let truth = read_truth(&dir.path().join("truth.mcap")).unwrap();
    // Nothing was asked, so every truth record is a streamed sample: the whole 7.5 s scenario
    // at 100 Hz from power-up (less samples a busy link could not carry, which have none).
    assert!(truth.samples.iter().all(|s| is_data_command(s.command)));
    assert!(
        truth.samples.len() + report.samples_skipped_link_busy as usize >= 745,
        "{} samples: {log}",
        truth.samples.len()
    );

    let files = recordings(dir.path());
    assert_eq!(files.len(), 1, "{files:?}");
    let rec = read_recording(&files[0]).unwrap();
    assert!(rec.stopped_early.is_none(), "SIGTERM must finish the file");
    // Sample for sample: every one the unit sent, in order, with the sent device time.
    assert_eq!(rec.raw.len(), truth.samples.len(), "{log}");
    for (i, (r, t)) in rec.raw.iter().zip(&truth.samples).enumerate() {
        assert_eq!(r.seq, i as u64);
        assert_same_device_time(protocol, r, t, i);
    }
    assert!(rec.frames.iter().all(|f| f.accepted), "{log}");
    let device = rec.metadata.get("imud.device").expect("device metadata");
    assert_eq!(
        device.get("protocol").map(String::as_str),
        Some(protocol.name())
    );
    assert_eq!(
        device.get("configuration-verified").map(String::as_str),
        Some("false")
    );
    // Every status says the configuration was not verified, and no sample was lost.
    let (_, last) = rec.statuses.last().expect("statuses");
    assert!(
        rec.statuses
            .iter()
            .all(|(_, s)| s.configuration_unverified == 1)
    );
    assert_eq!(last.samples_lost, 0, "{log}");
    assert_eq!(last.samples, truth.samples.len() as u64, "{log}");
    // ... and the subscriber got every one, in order.
    assert_eq!(got.len(), truth.samples.len(), "{log}");
    assert!(got.iter().enumerate().all(|(i, s)| s.seq == i as u64));
}
