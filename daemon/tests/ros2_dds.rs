//! ROS 2 without a bridge, against an independent DDS implementation: `imud --sim --ros2`
//! publishes, Eclipse Cyclone DDS (`tests/python/dds_imu_peer.py`, the C library of the
//! `cyclonedds` wheel) subscribes with ROS 2's wire names, and what it receives is compared with
//! the MCAP file the same run recorded: every sample, the same values, stamps, covariances and
//! frame id. Also: a reliable reader does not match the default best-effort writer (gets nothing,
//! and Cyclone reports the incompatible QoS), a reader that starts late gets every sample from
//! its first one on, with `qos = "reliable"` the reliable reader gets every sample, and a topic
//! nobody reads is not written (counted in `/diagnostics`).
//!
//! Network confinement: daemon and peer run inside a network namespace this test creates
//! (`ros2_common`: `unshare -rn`, a new user and network namespace with only `lo`, up, multicast
//! on, and a multicast route on it), so no DDS packet can reach a real interface. Without `unshare` or
//! `cyclonedds` the test skips, or fails when `IMUD_REQUIRE_PEERS` is set.

mod ros2_common;

use imu_bus::recording::Recording;
use imu_bus::ros2::Imu;
use ros2_common::{End, Options, PeerTopics, Run, Started, samples, stamp_ns};
use serde_json::Value;

const MODEL: &str = r#"
format = "imud-calibration/1"
[accel.bias]
value = [0.15, -0.2, 0.1]
[accel.scale]
value = [0.002, -0.001, 0.003]
[accel.noise]
white-density = [0.0005, 0.0005, 0.0005]
[gyro.bias]
value = [0.01, -0.005, 0.008]
[gyro.noise]
white-density = [0.0002, 0.0002, 0.0002]
"#;

const SCENARIO: &str = r#"
name = "ros2"
rate-hz = 100.0
truth = "truth.toml"
[device]
baud = 115200
[[segment]]
kind = "static"
orientation = { x = "north", z = "up" }
duration-s = 1.5
[[segment]]
kind = "index-table"
axis = "y"
step-deg = 90.0
positions = 2
dwell-s = 0.5
move-s = 0.5
[[segment]]
kind = "static"
duration-s = 2.0
"#;

/// A confined run of the scenario with the `[ros2]` QoS profile `qos` and frame id
/// `imu_front` (the log keeps `imu_link`); `None` (a skip) when confinement or the peer is
/// missing, unless `IMUD_REQUIRE_PEERS` is set.
fn confined_run(qos: &str, topics: PeerTopics) -> Option<Run> {
    let skip = |why: String| {
        assert!(
            std::env::var_os("IMUD_REQUIRE_PEERS").is_none(),
            "{why}, and IMUD_REQUIRE_PEERS is set"
        );
        eprintln!("skipping the Cyclone DDS check: {why}");
        None
    };
    if let Err(why) = ros2_common::confinement_available() {
        return skip(why);
    }
    let options = Options {
        scenario: SCENARIO.into(),
        model: MODEL.into(),
        ros2_config: format!("qos = \"{qos}\"\nframe-id = \"imu_front\""),
        ros2: true,
        peer: true,
        topics,
        late_after_s: 1.5,
        end: End::PeerIdle,
        baud: 115_200,
    };
    match Started::start(&options).finish() {
        Ok(run) => Some(run),
        Err(why) => skip(why),
    }
}

fn f64s(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// A received `sensor_msgs/Imu` equals the recorded one in every field but the frame id, which
/// the `[ros2]` section sets (`imu_front`; the log's is `imu_link`).
fn assert_same_imu(got: &Value, want: &Imu, what: &str) {
    assert_eq!(stamp_ns(got), want.header.stamp.to_ns(), "{what} stamp");
    assert_eq!(got["frame_id"], "imu_front", "{what}");
    assert_eq!(want.header.frame_id, "imu_link");
    let w = |v: imu_bus::ros2::Vector3| vec![v.x, v.y, v.z];
    let o = want.orientation;
    assert_eq!(f64s(&got["orientation"]), [o.x, o.y, o.z, o.w], "{what}");
    assert_eq!(
        f64s(&got["orientation_covariance"]),
        want.orientation_covariance,
        "{what}"
    );
    assert_eq!(
        f64s(&got["angular_velocity"]),
        w(want.angular_velocity),
        "{what}"
    );
    assert_eq!(
        f64s(&got["angular_velocity_covariance"]),
        want.angular_velocity_covariance,
        "{what}"
    );
    assert_eq!(
        f64s(&got["linear_acceleration"]),
        w(want.linear_acceleration),
        "{what}"
    );
    assert_eq!(
        f64s(&got["linear_acceleration_covariance"]),
        want.linear_acceleration_covariance,
        "{what}"
    );
}

/// Every recorded `/imu/data` sample arrived, in order, equal.
fn assert_every_sample(got: &[Value], rec: &Recording, what: &str) {
    if got.len() != rec.imu.len() {
        // Which ones are missing: at the start (before the match) or on the way.
        let received: std::collections::HashSet<u64> = got.iter().map(stamp_ns).collect();
        let missing: Vec<usize> = (0..rec.imu.len())
            .filter(|&k| !received.contains(&rec.imu[k].header.stamp.to_ns()))
            .collect();
        panic!(
            "{what}: {} samples received, {} recorded; missing indexes {missing:?}",
            got.len(),
            rec.imu.len()
        );
    }
    for (k, (g, w)) in got.iter().zip(&rec.imu).enumerate() {
        assert_same_imu(g, w, &format!("{what} sample {k}"));
    }
}

/// A late reader gets a contiguous tail: from its first sample on, every recorded one.
fn assert_late_tail(late: &[Value], rec: &Recording) {
    assert!(!late.is_empty(), "the late reader got nothing");
    let first = stamp_ns(&late[0]);
    let start = rec
        .imu
        .iter()
        .position(|m| m.header.stamp.to_ns() == first)
        .expect("the late reader's first sample is a recorded one");
    assert!(start >= 100, "late: it joined at sample {start}");
    assert_every_sample(
        late,
        &Recording {
            imu: rec.imu[start..].to_vec(),
            ..Recording::default()
        },
        "late reader",
    );
}

/// `imu/data_raw`: the recorded raw counts (raw bits) in physical units with the recorded
/// GainScales, which are the raw samples' device readings, stamped like their corrected samples.
fn assert_raw_topic(early: &Value, rec: &Recording) {
    let device = &rec.metadata["imud.device"];
    let gain = |k: &str| device[k].parse::<u16>().unwrap();
    let (ga, gg) = (gain("gain-scale-accel"), gain("gain-scale-gyro"));
    let units = |c: [i32; 3], g: u16| c.map(|c| imu_proto::scale::raw_bits_to_units(c as u16, g));
    let raw = samples(&early["imu_raw"], "imu_raw");
    assert_eq!(raw.len(), rec.raw.len());
    for ((g, r), imu) in raw.iter().zip(&rec.raw).zip(&rec.imu) {
        let accel = units(r.accel_counts, ga).map(|a| a * imu_model::units::STANDARD_GRAVITY_M_S2);
        let gyro = units(r.gyro_counts, gg);
        assert_eq!((accel, gyro), (r.accel_device_m_s2, r.gyro_device_rad_s));
        assert_eq!(stamp_ns(g), imu.header.stamp.to_ns());
        assert_eq!(f64s(&g["linear_acceleration"]), accel);
        assert_eq!(f64s(&g["angular_velocity"]), gyro);
        // Not the corrected values: the calibration's biases are not applied here.
        assert_ne!(accel, <[f64; 3]>::from(imu.linear_acceleration));
        assert_eq!(f64s(&g["angular_velocity_covariance"]), [0.0; 9]);
    }
}

/// `imu/mag`: the recorded `/imu/mag`, in tesla.
fn assert_mag_topic(early: &Value, rec: &Recording) {
    let mag = samples(&early["mag"], "mag");
    assert_eq!(mag.len(), rec.mag.len());
    for (g, w) in mag.iter().zip(&rec.mag) {
        assert_eq!(stamp_ns(g), w.header.stamp.to_ns());
        assert_eq!(
            f64s(&g["magnetic_field"]),
            <[f64; 3]>::from(w.magnetic_field)
        );
        assert_eq!(
            f64s(&g["magnetic_field_covariance"]),
            w.magnetic_field_covariance
        );
        // Tesla: Earth's field is about 0.5 gauss, 5e-5 T.
        let norm = f64s(&g["magnetic_field"])
            .iter()
            .map(|b| b * b)
            .sum::<f64>()
            .sqrt();
        assert!(norm < 1e-3, "{norm} T");
    }
}

/// `imu/temperature`: the one read at start-up (continuous mode) arrived, and what arrived is
/// what was recorded, in order. (Once the scenario is over imud reconnects and may read another
/// after the peer has gone.)
fn assert_temperature_topic(early: &Value, rec: &Recording) {
    let temps = samples(&early["temperature"], "temperature");
    assert!(!temps.is_empty() && temps.len() <= rec.temperatures.len());
    for (t, &(at, c)) in temps.iter().zip(&rec.temperatures) {
        assert_eq!(stamp_ns(t), at);
        assert_eq!(t["temperature"].as_f64().unwrap(), c);
        assert_eq!(t["frame_id"], "imu_front");
    }
}

/// `/diagnostics`: the status a second, counters included.
fn assert_diagnostics_topic(early: &Value, rec: &Recording) {
    let diag = samples(&early["diagnostics"], "diagnostics");
    assert!(diag.len() >= 3, "{} diagnostics", diag.len());
    let streaming = diag
        .iter()
        .flat_map(|d| d["status"].as_array().unwrap())
        .rfind(|s| s["values"]["device_connected"] == "1")
        .expect("a status while streaming");
    assert!(
        streaming["name"]
            .as_str()
            .unwrap()
            .starts_with("imud: ros2-")
    );
    assert_eq!(streaming["level"], 0, "{streaming}");
    let samples_then: u64 = streaming["values"]["samples"]
        .as_str()
        .unwrap()
        .parse()
        .unwrap();
    assert!(samples_then > 0 && samples_then <= rec.imu.len() as u64);
    // The live calibration health, one entry per triad beside the status.
    let last = diag.last().unwrap()["status"].as_array().unwrap();
    for triad in ["accel", "gyro"] {
        let h = last
            .iter()
            .find(|s| {
                s["name"]
                    .as_str()
                    .unwrap()
                    .ends_with(&format!("calibration {triad}"))
            })
            .unwrap_or_else(|| panic!("no {triad} health in {last:?}"));
        let state = h["values"]["state"].as_str().unwrap();
        assert!(["unknown", "ok"].contains(&state), "{h}");
        assert_eq!(h["level"], 0, "{h}");
    }
}

#[test]
fn cyclone_dds_receives_every_sample_as_ros2_imu() {
    let Some(Run {
        peer,
        rec,
        imud_log,
    }) = confined_run("sensor-data", PeerTopics::Every)
    else {
        return;
    };
    let early = &peer["early"];
    // A full run: the scenario's 5 s at 100 Hz, and covariances once the rate was measured.
    assert!(
        rec.imu.len() >= 450,
        "{} samples: {imud_log}",
        rec.imu.len()
    );
    assert!(
        rec.imu.last().unwrap().angular_velocity_covariance[0] > 0.0,
        "the calibration's noise gives covariances"
    );
    assert_every_sample(samples(&early["imu"], "imu"), &rec, "early reader");

    assert_raw_topic(early, &rec);
    assert_mag_topic(early, &rec);
    assert_temperature_topic(early, &rec);
    assert_diagnostics_topic(early, &rec);

    // QoS: a reliable reader does not match the sensor-data (best-effort) writer.
    let reliable = &peer["reliable"];
    assert_eq!(samples(reliable, "reliable").len(), 0);
    assert!(
        reliable["incompatible_qos"].as_u64().unwrap() >= 1,
        "{reliable}"
    );

    assert_late_tail(samples(&peer["late"], "late"), &rec);

    // Nothing was dropped on the way to the DDS thread.
    let last = rec.statuses.last().unwrap().1;
    assert_eq!(last.publish_drops, 0, "{imud_log}");
}

#[test]
fn a_reliable_writer_serves_reliable_and_late_readers() {
    let Some(Run { peer, rec, .. }) = confined_run("reliable", PeerTopics::Every) else {
        return;
    };
    assert!(rec.imu.len() >= 450);
    let reliable = &peer["reliable"];
    assert_eq!(reliable["incompatible_qos"], 0);
    assert_every_sample(samples(reliable, "reliable"), &rec, "reliable reader");
    // A best-effort reader matches a reliable writer too.
    assert_every_sample(samples(&peer["early"]["imu"], "imu"), &rec, "early reader");
    assert_late_tail(samples(&peer["late"], "late"), &rec);
}

/// A topic nobody reads is not written, and `/diagnostics` counts what was skipped: with readers
/// of `imu/data` and `/diagnostics` only, every sample's `imu/mag` and `imu/data_raw` (and the
/// temperatures) are skipped while `imu/data` still reaches its reader whole.
#[test]
fn topics_without_a_reader_are_not_written_and_are_counted() {
    let Some(Run { peer, rec, .. }) =
        confined_run("sensor-data", PeerTopics::Only(&["imu", "diagnostics"]))
    else {
        return;
    };
    let early = &peer["early"];
    assert!(early.get("mag").is_none() && early.get("imu_raw").is_none());
    assert_every_sample(samples(&early["imu"], "imu"), &rec, "early reader");
    let diag = samples(&early["diagnostics"], "diagnostics");
    // The last status while streaming; it was made on the DDS thread after the samples it
    // counts had been handled there (one queue, in order), and before its own write.
    let (k, streaming) = diag
        .iter()
        .enumerate()
        .filter_map(|(k, d)| {
            d["status"]
                .as_array()
                .unwrap()
                .iter()
                .find(|s| s["values"]["device_connected"] == "1")
                .map(|s| (k, s))
        })
        .next_back()
        .expect("a status while streaming");
    let value = |key: &str| -> u64 {
        streaming["values"][key]
            .as_str()
            .unwrap_or_else(|| panic!("no {key} in {streaming}"))
            .parse()
            .unwrap()
    };
    let samples_then = value("samples");
    assert!(samples_then >= 100, "{streaming}");
    assert_eq!(value("publish_drops"), 0);
    let (written, unmatched) = (value("dds_written"), value("dds_not_sent_unmatched"));
    assert!(
        unmatched >= 2 * samples_then,
        "{unmatched} skipped for {samples_then} samples (mag and data_raw each)"
    );
    // imu/data for each sample, at most, plus the diagnostics written before this one: those
    // received, and up to two more written while discovery was still matching the reader (the
    // writer counts the match before the reader takes data; imud publishes its status from the
    // start of start-up, so one can fall in that window). Writing mag or data_raw would add two
    // messages a sample, far above this bound.
    const WRITTEN_DURING_DISCOVERY: u64 = 2;
    assert!(
        written <= samples_then + k as u64 + WRITTEN_DURING_DISCOVERY,
        "{written} written for {samples_then} samples and {k} diagnostics received"
    );
    assert!(
        written >= samples_then,
        "{written} written for {samples_then} samples"
    );
}
