//! A live ROS 2 IMU as imud's device, against an independent DDS implementation: Eclipse
//! Cyclone DDS (`tests/python/dds_imu_publisher.py`, the C library of the `cyclonedds` wheel)
//! publishes `sensor_msgs/msg/Imu` with ROS 2's wire names at a known rate, and
//! `imud --ros2-input /camera/imu` with a known calibration takes it as its device. Checked
//! against what the publisher sent: every message is a sample (zero loss), its stamp is the
//! device time, its values the raw reading bit for bit, the corrected values the calibration
//! applied to them; a publisher that skips messages yields exactly that loss count; and
//! `imud replay` of the recording reproduces its `/imu/data` from the logged frames.
//!
//! Network confinement as in `ros2_dds.rs` (`ros2_common`: a network namespace of the test's
//! own with only `lo`). Without `unshare` or `cyclonedds` the test skips, or fails when
//! `IMUD_REQUIRE_PEERS` is set.

mod ros2_common;

use std::path::{Path, PathBuf};
use std::process::Command;

use imu_bus::recording::{Recording, read_recording};
use serde_json::Value;

/// Bias-only: corrected = sent - bias, whatever the rest of the model's conventions.
const CALIBRATION: &str = r#"
format = "imud-calibration/1"
[accel.bias]
value = [0.15, -0.2, 0.1]
[gyro.bias]
value = [0.01, -0.005, 0.008]
"#;
const ACCEL_BIAS_M_S2: [f64; 3] = [0.15, -0.2, 0.1];
const GYRO_BIAS_RAD_S: [f64; 3] = [0.01, -0.005, 0.008];

/// One confined run's results.
struct Run {
    /// The publisher's JSON: what it sent.
    sent: Vec<Value>,
    /// What a Cyclone subscriber of imud's own `/imud/imu/data` received (with `--ros2`).
    output: Option<Value>,
    /// imud's recording and its path.
    rec: Recording,
    file: PathBuf,
    dir: tempfile::TempDir,
}

fn skip(why: String) -> Option<Run> {
    assert!(
        std::env::var_os("IMUD_REQUIRE_PEERS").is_none(),
        "{why}, and IMUD_REQUIRE_PEERS is set"
    );
    eprintln!("skipping the Cyclone DDS input check: {why}");
    None
}

/// imud with `--ros2-input /camera/imu` and the publisher in a namespace of their own: `n`
/// messages at `rate_hz`, the indices in `skipped` not published. With `output`, imud also
/// publishes its ROS 2 topics in the namespace `/imud` (`--ros2`) and the Cyclone subscriber
/// (`dds_imu_peer.py`) reads its `/imud/imu/data`.
fn confined_run(n: u32, rate_hz: f64, skipped: &[u32], qos: &str, output: bool) -> Option<Run> {
    if let Err(why) = ros2_common::confinement_available() {
        return skip(why);
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("cal.toml"), CALIBRATION).unwrap();
    std::fs::write(
        d.join("imud.toml"),
        format!(
            // A long silence timeout: the publisher waits for imud's reader before it
            // starts, and the session must not time out (and make a new reader) meanwhile.
            "[device]\nsilence-timeout-s = 60.0\n[calibration]\npath = \"{cal}\"\n\
             [log]\ndir = \"{logs}\"\n[publish]\nenabled = false\n[health]\nenabled = false\n\
             [ros2]\nnamespace = \"/imud\"\n",
            cal = d.join("cal.toml").display(),
            logs = d.join("logs").display(),
        ),
    )
    .unwrap();
    let publisher =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/python/dds_imu_publisher.py");
    let subscriber = publisher.with_file_name("dds_imu_peer.py");
    let skip_list: Vec<String> = skipped.iter().map(u32::to_string).collect();
    let (start_output, end_output) = if output {
        (
            format!(
                r#"python3 {subscriber} --ready {d}/ready --namespace imud --topics imu --idle-s 2 --timeout-s 120 > {d}/out.json 2> {d}/out.stderr &
O=$!
i=0
while [ ! -f {d}/ready ]; do
  kill -0 $O 2>/dev/null || {{ wait $O; exit $?; }}
  i=$((i+1)); [ $i -lt 600 ] || exit 71
  sleep 0.05
done
"#,
                subscriber = subscriber.display(),
                d = d.display(),
            ),
            "wait $O; orc=$?; [ $orc -eq 0 ] || exit $orc\n",
        )
    } else {
        (String::new(), "")
    };
    let script = format!(
        r#"ip link set lo up && ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo || exit 70
{start_output}IMUD_LOG=info,rustdds=error {imud} --config {d}/imud.toml --name ros2in-{pid} --ros2-input /camera/imu {ros2} 2> {d}/imud.stderr &
I=$!
python3 {publisher} --topic rt/camera/imu --n {n} --rate-hz {rate_hz} --qos {qos} --skip "{skips}" > {d}/peer.json 2> {d}/peer.stderr
rc=$?
kill -TERM $I; wait $I; irc=$?
{end_output}[ $rc -eq 0 ] || exit $rc
exit $irc
"#,
        ros2 = if output { "--ros2" } else { "" },
        imud = env!("CARGO_BIN_EXE_imud"),
        pid = std::process::id(),
        publisher = publisher.display(),
        d = d.display(),
        skips = skip_list.join(","),
    );
    let status = Command::new("unshare")
        .args(["-rn", "sh", "-c", &script])
        .status()
        .unwrap();
    let read = |f: &str| std::fs::read_to_string(d.join(f)).unwrap_or_default();
    if status.code() == Some(77) {
        return skip(format!("the publisher is missing: {}", read("peer.stderr")));
    }
    assert!(
        status.success(),
        "{status}\npublisher: {}\nimud: {}",
        read("peer.stderr"),
        read("imud.stderr")
    );
    let peer: Value = serde_json::from_str(&read("peer.json")).expect("publisher JSON");
    let sent = peer["sent"].as_array().unwrap().clone();
    let files: Vec<PathBuf> = std::fs::read_dir(d.join("logs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "mcap"))
        .collect();
    assert_eq!(files.len(), 1, "{files:?}");
    let rec = read_recording(&files[0]).unwrap();
    assert!(rec.stopped_early.is_none(), "SIGTERM must finish the file");
    let output = output.then(|| serde_json::from_str(&read("out.json")).expect("subscriber JSON"));
    Some(Run {
        sent,
        output,
        rec,
        file: files[0].clone(),
        dir,
    })
}

fn f64s(v: &Value) -> [f64; 3] {
    let a = v.as_array().unwrap();
    [0, 1, 2].map(|i| a[i].as_f64().unwrap())
}

/// Every sent message is one sample in order, with its stamp as the device time, its values
/// as the raw reading bit for bit and the calibration applied in `/imu/data`.
fn assert_every_message_arrived_corrected(run: &Run) {
    let rec = &run.rec;
    assert_eq!(rec.raw.len(), run.sent.len(), "every message is a sample");
    assert_eq!(rec.imu.len(), run.sent.len());
    for ((raw, imu), sent) in rec.raw.iter().zip(&rec.imu).zip(&run.sent) {
        let what = format!("message {}", sent["k"]);
        assert_eq!(
            raw.t_device_ns,
            sent["stamp_ns"].as_u64().unwrap(),
            "{what}"
        );
        let accel = f64s(&sent["linear_acceleration"]);
        let gyro = f64s(&sent["angular_velocity"]);
        assert_eq!(raw.accel_device_m_s2, accel, "{what}");
        assert_eq!(raw.gyro_device_rad_s, gyro, "{what}");
        let a = imu.linear_acceleration;
        let g = imu.angular_velocity;
        for (i, (got, want)) in [a.x, a.y, a.z]
            .into_iter()
            .zip((0..3).map(|i| accel[i] - ACCEL_BIAS_M_S2[i]))
            .enumerate()
        {
            assert!(
                (got - want).abs() < 1e-12,
                "{what} accel {i}: {got} vs {want}"
            );
        }
        for (i, (got, want)) in [g.x, g.y, g.z]
            .into_iter()
            .zip((0..3).map(|i| gyro[i] - GYRO_BIAS_RAD_S[i]))
            .enumerate()
        {
            assert!(
                (got - want).abs() < 1e-12,
                "{what} gyro {i}: {got} vs {want}"
            );
        }
    }
    // Every message is logged once as an accepted raw frame (the replayable byte stream).
    assert_eq!(
        rec.frames.iter().filter(|f| f.accepted).count(),
        run.sent.len()
    );
    assert!(rec.frames.iter().all(|f| f.accepted));
    let device = &rec.metadata["imud.device"];
    assert_eq!(device["protocol"], "ros2-input");
    assert_eq!(device["dds-topic"], "rt/camera/imu");
    assert!(device["clock"].contains("header.stamp"), "{device:?}");
}

#[test]
fn imuds_own_output_topic_is_refused_as_its_input() {
    let out = Command::new(env!("CARGO_BIN_EXE_imud"))
        .args(["--ros2", "--ros2-input", "/imu/data", "--print-config"])
        .env("IMUD_CONFIG", "/dev/null")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("`input.ros2-topic`") && err.contains("imud's own ROS 2 output topic"),
        "{err}"
    );
}

fn last_status(rec: &Recording) -> imu_bus::DaemonStatus {
    rec.statuses.last().expect("a status").1
}

#[test]
fn every_message_of_a_cyclone_dds_publisher_arrives_corrected_and_replays() {
    let Some(run) = confined_run(400, 100.0, &[], "reliable", true) else {
        return;
    };
    assert_eq!(run.sent.len(), 400);
    assert_every_message_arrived_corrected(&run);
    let status = last_status(&run.rec);
    assert_eq!(status.samples, 400);
    assert_eq!(status.samples_lost, 0);
    assert_eq!(status.packets_unusable, 0);
    assert_eq!(
        status.protocol,
        imu_bus::sample::device_protocol::ROS2_INPUT
    );

    // imud's own ROS 2 output carries the corrected stream: every sample, as logged.
    let out = run.output.as_ref().unwrap();
    let received = ros2_common::samples(&out["early"]["imu"], "imud's /imud/imu/data");
    assert_eq!(received.len(), run.rec.imu.len());
    for (got, want) in received.iter().zip(&run.rec.imu) {
        assert_eq!(ros2_common::stamp_ns(got), want.header.stamp.to_ns());
        let a = want.linear_acceleration;
        let g = want.angular_velocity;
        assert_eq!(f64s(&got["linear_acceleration"]), [a.x, a.y, a.z]);
        assert_eq!(f64s(&got["angular_velocity"]), [g.x, g.y, g.z]);
    }

    // The logged frames replayed through the same driver give the same /imu/data.
    let out = run.dir.path().join("replay");
    let replay = Command::new(env!("CARGO_BIN_EXE_imud"))
        .args([
            "replay",
            "--speed",
            "max",
            "--name",
            "ros2in-replay",
            "--log-dir",
        ])
        .arg(&out)
        .arg(&run.file)
        .env("IMUD_LOG", "warn")
        .output()
        .unwrap();
    assert!(
        replay.status.success(),
        "{}",
        String::from_utf8_lossy(&replay.stderr)
    );
    let replayed: Vec<PathBuf> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(replayed.len(), 1, "{replayed:?}");
    let again = read_recording(&replayed[0]).unwrap();
    assert_eq!(again.imu, run.rec.imu);
}

#[test]
fn messages_a_best_effort_publisher_skips_are_counted_as_losses() {
    let skipped = [60, 150, 151, 152, 300];
    let Some(run) = confined_run(400, 100.0, &skipped, "best-effort", false) else {
        return;
    };
    assert_eq!(run.sent.len(), 400 - skipped.len());
    assert_every_message_arrived_corrected(&run);
    let status = last_status(&run.rec);
    assert_eq!(status.samples, run.sent.len() as u64);
    assert_eq!(status.samples_lost, skipped.len() as u64);
}
