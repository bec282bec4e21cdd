//! `device.time-source` end to end: a simulated unit (MIP, Xsens MTi, VectorNav VN-200) whose
//! clock runs 150 ppm fast and whose GNSS time comes and goes, through a real pty and the imud
//! binary; the recorded stamps
//! against the true GNSS time of each sample (the truth's `t_s` plus the scenario's GNSS
//! epoch), and the status's time-sync state in the MCAP.

use std::time::{Duration, Instant};

use imu_bus::recording::{Recording, read_recording};
use imu_bus::sample::{time_source, time_sync};
use imu_bus::truth::{TruthSample, is_data_command, read_truth};
use imu_model::Calibration;
use imu_proto::DeviceProtocol;
use imu_sim::{Pacing, Scenario, SimOptions};

use super::{Imud, TRUTH, imuds_truth, recordings, unique};

/// The device clock's error, ppm (fast).
const DRIFT_PPM: f64 = 150.0;
/// UTC of scenario time 0, s.
const EPOCH_UTC_S: f64 = 1_767_225_600.0;
/// The GNSS outage, s of scenario time.
const OUTAGE_S: (f64, f64) = (7.0, 11.0);

fn scenario(duration_s: f64, gnss: bool, protocol: DeviceProtocol) -> String {
    let gnss = if gnss {
        format!(
            "gnss-time = true\ngnss-epoch-utc-s = {EPOCH_UTC_S}\n\
             [[device.gnss-outage]]\nstart-s = {}\nend-s = {}\n",
            OUTAGE_S.0, OUTAGE_S.1
        )
    } else {
        String::new()
    };
    // A VectorNav unit with GNSS is a VN-200.
    let model = if protocol == DeviceProtocol::Vectornav {
        "model = \"VN-200T-CR\"\n"
    } else {
        ""
    };
    format!(
        "name = \"time-sync\"\nrate-hz = 100.0\n[device]\nprotocol = \"{protocol}\"\n{model}\
         clock-drift-ppm = {DRIFT_PPM}\n{gnss}\
         [[segment]]\nkind = \"static\"\norientation = {{ x = \"north\", z = \"up\" }}\n\
         duration-s = {duration_s}\n"
    )
}

/// Runs the scenario through imud with `--time-source source`; returns the recording and the
/// truth's data samples (one for one: the link is lossless).
fn run(
    name: &str,
    source: &str,
    duration_s: f64,
    gnss: bool,
    protocol: DeviceProtocol,
) -> (Recording, Vec<TruthSample>) {
    let dir = tempfile::tempdir().unwrap();
    let cal_path = dir.path().join("calibration.toml");
    std::fs::write(&cal_path, TRUTH).unwrap();
    let text = scenario(duration_s, gnss, protocol);
    let opts = SimOptions {
        scenario: Scenario::from_toml_str(&text, "time-sync scenario").unwrap(),
        scenario_text: text,
        truth: Calibration::from_toml_str(TRUTH, "truth").unwrap(),
        seed: 9,
        truth_out: Some(dir.path().join("truth.mcap")),
        link: Some(dir.path().join("imu0")),
        pacing: Pacing::RealTime,
        linger: Duration::from_secs(2),
    };
    let imud = Imud::start_with(
        dir.path(),
        &unique(name),
        &dir.path().join("imu0"),
        &cal_path,
        &["--protocol", protocol.name(), "--time-source", source],
    );
    let sim = imu_sim::spawn(opts).unwrap();
    let deadline = Instant::now() + Duration::from_secs(duration_s as u64 + 60);
    while !sim.is_finished() && Instant::now() < deadline {
        std::thread::park_timeout(Duration::from_millis(100));
    }
    let report = sim.join().unwrap();
    assert!(report.completed);
    let log = imud.terminate();
    let truth = read_truth(&dir.path().join("truth.mcap")).unwrap();
    assert_eq!(truth.run.get("gnss-time"), Some(&gnss.to_string()));
    // The truth file says when scenario time 0 was in UTC.
    let epoch_utc_s: f64 = truth.run["gnss-epoch-utc-s"].parse().unwrap();
    assert_eq!(epoch_utc_s, EPOCH_UTC_S);
    let truth_data: Vec<TruthSample> = imuds_truth(
        protocol,
        &report,
        truth
            .samples
            .iter()
            .filter(|s| is_data_command(s.command))
            .collect(),
    )
    .into_iter()
    .cloned()
    .collect();
    let files = recordings(dir.path());
    assert_eq!(files.len(), 1, "{files:?}");
    let rec = read_recording(&files[0]).unwrap();
    assert_eq!(rec.raw.len(), truth_data.len(), "lossless: {log}");
    assert_eq!(rec.imu.len(), rec.raw.len());
    for stamps in [
        rec.raw.iter().map(|r| r.t_sample_ns).collect::<Vec<_>>(),
        rec.imu.iter().map(|m| m.header.stamp.to_ns()).collect(),
    ] {
        assert!(
            stamps.windows(2).all(|w| w[1] > w[0]),
            "{source}: stamps strictly increasing"
        );
    }
    if protocol == DeviceProtocol::Mip {
        let device = rec.metadata.get("imud.device").expect("device metadata");
        assert_eq!(
            device.get("gps-timestamp").map(String::as_str),
            Some("true")
        );
    }
    (rec, truth_data)
}

/// The true GNSS (UTC) time of a sample, ns.
fn true_gnss_ns(t: &TruthSample) -> i64 {
    (EPOCH_UTC_S * 1e9).round() as i64 + (t.t_s * 1e9).round() as i64
}

/// The time-sync states of the statuses in order, repeats removed.
fn sync_states(rec: &Recording) -> Vec<u8> {
    let mut states: Vec<u8> = rec.statuses.iter().map(|(_, s)| s.time_sync).collect();
    states.dedup();
    states
}

#[test]
fn gnss_stamps_follow_a_mip_units_gnss_time_through_an_outage() {
    gnss_stamps_follow_the_units_gnss_time_through_an_outage(DeviceProtocol::Mip, 1e-9);
}

/// An MTi's device clock is `SampleTimeFine`, 100 us counts.
#[test]
fn gnss_stamps_follow_an_xsens_units_utc_time_through_an_outage() {
    gnss_stamps_follow_the_units_gnss_time_through_an_outage(DeviceProtocol::Xsens, 100e-6);
}

/// A VN-200's device clock is its startup time, ns.
#[test]
fn gnss_stamps_follow_a_vectornav_units_gps_time_through_an_outage() {
    gnss_stamps_follow_the_units_gnss_time_through_an_outage(DeviceProtocol::Vectornav, 1e-9);
}

/// `tick_s`: the resolution of the unit's device clock.
fn gnss_stamps_follow_the_units_gnss_time_through_an_outage(protocol: DeviceProtocol, tick_s: f64) {
    let (rec, truth) = run(&format!("gnss-{protocol}"), "gnss", 15.0, true, protocol);
    let first_s = truth[0].t_s;
    // Locked: from 3 s after the first sample (the rate is fitted over 2 s of GNSS points;
    // before, an offset alone lags the 150 ppm by up to 150 us) to the outage, and after it.
    // The GNSS field is exact to the ns and the stamps follow the device clock, so the fit's
    // stamps equal the true times within 20 us plus that clock's resolution.
    let locked_bound_s = 20e-6 + tick_s;
    // Held over on the fitted rate: bounded by drift x outage (600 us), far less in fact.
    let holdover_bound_s = DRIFT_PPM * 1e-6 * (OUTAGE_S.1 - OUTAGE_S.0) + tick_s;
    let (mut locked, mut held, mut worst_locked_s, mut worst_held_s) = (0, 0, 0.0f64, 0.0f64);
    for (m, t) in rec.imu.iter().zip(&truth) {
        let err_s = (m.header.stamp.to_ns() as i64 - true_gnss_ns(t)) as f64 * 1e-9;
        if (OUTAGE_S.0..OUTAGE_S.1).contains(&t.t_s) {
            assert!(
                err_s.abs() <= holdover_bound_s,
                "holdover at {} s: {err_s} s",
                t.t_s
            );
            held += 1;
            worst_held_s = worst_held_s.max(err_s.abs());
        } else if t.t_s >= first_s + 3.0 {
            assert!(
                err_s.abs() <= locked_bound_s,
                "locked at {} s: {err_s} s",
                t.t_s
            );
            locked += 1;
            worst_locked_s = worst_locked_s.max(err_s.abs());
        }
    }
    eprintln!(
        "{protocol} GNSS stamps: {locked} locked within {worst_locked_s:e} s, {held} held over within \
         {worst_held_s:e} s"
    );
    assert!(locked > 500 && held > 350, "{locked} locked, {held} held");
    // The status in the MCAP: gnss source; locked, held over, locked again; the drift.
    assert!(
        rec.statuses
            .iter()
            .all(|(_, s)| s.time_source == time_source::GNSS)
    );
    let states = sync_states(&rec);
    let locked_held_locked = states.windows(3).any(|w| {
        w == [
            time_sync::GNSS_LOCKED,
            time_sync::GNSS_HOLDOVER,
            time_sync::GNSS_LOCKED,
        ]
    });
    assert!(locked_held_locked, "states {states:?}");
    let last = rec.statuses.last().unwrap().1;
    assert_eq!(
        (last.gnss_valid_transitions, last.gnss_lost_transitions),
        (2, 1)
    );
    assert!(
        (last.gnss_drift_ppm - DRIFT_PPM).abs() < 1.0,
        "GNSS drift {} ppm",
        last.gnss_drift_ppm
    );
    assert!(last.gnss_minus_wall_s.is_finite());
}

#[test]
fn host_stamps_are_the_receive_times_and_device_stamps_the_fit() {
    let (rec, _) = run("host", "host", 4.0, false, DeviceProtocol::Mip);
    for r in &rec.raw {
        // The receive time, only kept apart from the previous frame's (read together).
        let d = r.t_sample_ns - r.t_host_monotonic_ns;
        assert!(d < 1_000_000, "host stamp {d} ns after receipt");
    }
    assert!(
        rec.statuses
            .iter()
            .all(|(_, s)| { s.time_source == time_source::HOST && s.time_sync == time_sync::NONE })
    );

    let (rec, truth) = run("device", "device", 6.0, false, DeviceProtocol::Mip);
    assert!(
        rec.statuses
            .iter()
            .all(|(_, s)| s.time_source == time_source::DEVICE)
    );
    // The fit is trusted after 3 s, and stays so while the unit is connected (the status
    // recorded after the simulated unit goes away says none).
    let connected: Vec<u8> = rec
        .statuses
        .iter()
        .filter(|(_, s)| s.device_connected == 1)
        .map(|(_, s)| s.time_sync)
        .collect();
    let trusted = connected
        .iter()
        .position(|&s| s == time_sync::DEVICE_FIT)
        .expect("the fit is trusted after 3 s");
    assert!(
        connected[trusted..]
            .iter()
            .all(|&s| s == time_sync::DEVICE_FIT),
        "states while connected {connected:?}"
    );
    // Device stamps are spaced as the device clock says (the sim's 10 ms on a 150 ppm fast
    // clock), within the fit's slew, once fitted: never the host's receive jitter.
    let fitted = truth
        .iter()
        .position(|t| t.t_s >= truth[0].t_s + 4.0)
        .unwrap();
    for w in rec.raw[fitted..].windows(2) {
        let dt_s = (w[1].t_sample_ns - w[0].t_sample_ns) as f64 * 1e-9;
        assert!((dt_s - 0.01).abs() < 0.01 * 0.006, "spacing {dt_s} s");
    }
}
