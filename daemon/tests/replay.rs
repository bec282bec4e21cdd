//! `imud replay` against live runs: a recording of `imud --sim` (a real pty, real time)
//! replayed reproduces its `/imu/data` and `/imu/raw` bit for bit, for every protocol, and so
//! does the recording of a live run whose device was unplugged and reconnected (two device
//! sessions); its bytes as a raw capture (`.bin`) and as a hex dump give the same device
//! readings; a new calibration re-corrects the stream without changing the raw samples.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use imu_bus::DaemonStatus;
use imu_bus::recording::{Recording, read_recording};
use imu_bus::shm::Subscription;
use imu_proto::DeviceProtocol;
use imu_sim::{Pacing, Scenario, SimOptions};

/// A child process killed (and reaped) when dropped.
struct Killed(Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// An instance name no other test's imud has (its temporary directory's).
fn unique(dir: &Path) -> String {
    let tmp = dir.file_name().unwrap().to_string_lossy();
    format!("replay{}", tmp.trim_start_matches('.').replace('.', ""))
}

fn imud() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_imud"));
    c.env("IMUD_LOG", "info").env_remove("IMUD_CONFIG");
    c
}

fn recording_in(dir: &Path) -> PathBuf {
    let files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            let n = p.file_name().unwrap().to_string_lossy().into_owned();
            n.ends_with(".mcap") && !n.contains("truth")
        })
        .collect();
    assert_eq!(files.len(), 1, "{files:?}");
    files[0].clone()
}

/// `imud --sim --protocol PROTOCOL` for about two seconds of streaming; its recording.
fn live(dir: &Path, protocol: &str) -> PathBuf {
    let log = dir.join("live.stderr");
    let name = format!("{}-{protocol}", unique(dir));
    let child = imud()
        .args(["--sim", "--protocol", protocol, "--name", &name])
        .arg("--log-dir")
        .arg(dir.join("live"))
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&log).unwrap())
        .spawn()
        .unwrap();
    let child = Killed(child);
    let text = || std::fs::read_to_string(&log).unwrap_or_default();
    // Stream until the status shows what the replay must reproduce: the clock fit, a
    // temperature and a few hundred samples.
    let mut status = Subscription::<DaemonStatus>::open(&name, Duration::from_secs(10)).unwrap();
    wait_for_status(&mut status, &log, "stream", |s| {
        s.samples >= 300 && s.clock_offset_s.is_finite() && s.temp_c.is_finite()
    });
    let ok = Command::new("kill")
        .args(["-TERM", &child.0.id().to_string()])
        .status()
        .unwrap()
        .success();
    assert!(ok);
    let mut child = child;
    assert!(child.0.wait().unwrap().success(), "{}", text());
    recording_in(&dir.join("live"))
}

/// `imud replay FILE --speed max` with `args`; its recording.
fn replay(dir: &Path, file: &Path, out: &str, args: &[&str]) -> Recording {
    let name = format!("{}-{out}", unique(dir));
    let o = imud()
        .arg("replay")
        .arg(file)
        .args(["--speed", "max", "--name", &name])
        .arg("--log-dir")
        .arg(dir.join(out))
        .args(args)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    read_recording(&recording_in(&dir.join(out))).unwrap()
}

#[test]
fn a_replayed_recording_reproduces_its_imu_data_bit_for_bit() {
    for protocol in ["3dm-gx1", "mip", "xsens", "vectornav"] {
        let dir = tempfile::tempdir().unwrap();
        let file = live(dir.path(), protocol);
        let original = read_recording(&file).unwrap();
        assert!(
            original.imu.len() > 150,
            "{protocol}: {}",
            original.imu.len()
        );
        let again = replay(dir.path(), &file, "again", &[]);
        assert_eq!(again.imu.len(), original.imu.len(), "{protocol}");
        assert!(again.imu == original.imu, "{protocol}: /imu/data differs");
        assert!(again.raw == original.raw, "{protocol}: /imu/raw differs");
        assert!(again.frames == original.frames, "{protocol}: frames differ");
        assert!(
            again.device_compensated == original.device_compensated,
            "{protocol}: /imu/device_compensated differs"
        );
        assert_eq!(again.temperatures, original.temperatures, "{protocol}");
        assert_eq!(
            again.metadata["imud.replay"]["source"],
            file.display().to_string()
        );
        assert_eq!(
            again.metadata["imud.device"]["configuration-verified"],
            "false"
        );

        // The same bytes without their times: a raw capture and a hex dump give the same
        // device readings, sample for sample (their stamps are the replay's own).
        let bytes: Vec<u8> = original
            .frames
            .iter()
            .flat_map(|f| f.bytes.clone())
            .collect();
        let bin = dir.path().join("capture.bin");
        std::fs::write(&bin, &bytes).unwrap();
        let hex = dir.path().join("capture.hex");
        let mut text = String::from("# the live run's bytes\n");
        for (i, line) in bytes.chunks(16).enumerate() {
            text.push_str(&format!("{:08x}: ", i * 16));
            for b in line {
                text.push_str(&format!("{b:02x} "));
            }
            text.push('\n');
        }
        std::fs::write(&hex, text).unwrap();
        for (capture, out) in [(&bin, "bin"), (&hex, "hex")] {
            let r = replay(dir.path(), capture, out, &["--protocol", protocol]);
            let device = |rec: &Recording| -> Vec<_> {
                rec.raw
                    .iter()
                    .map(|s| {
                        (
                            s.ticks_unwrapped,
                            s.accel_counts,
                            s.gyro_counts,
                            s.accel_device_m_s2,
                            s.gyro_device_rad_s,
                        )
                    })
                    .collect()
            };
            let (got, want) = (device(&r), device(&original));
            // An MTi streams from power-up: what it sent before imud's GoToConfig was logged
            // as frames only live, and is samples in a capture without its times.
            let skip = match protocol {
                "xsens" => got.len().saturating_sub(want.len()),
                _ => 0,
            };
            assert!(
                got[skip..] == want[..],
                "{protocol} {out}: {} samples of {}",
                r.raw.len(),
                original.raw.len()
            );
        }
    }
}

#[test]
fn a_replay_with_a_new_calibration_re_corrects_the_same_raw_samples() {
    let dir = tempfile::tempdir().unwrap();
    let file = live(dir.path(), "3dm-gx1");
    let original = read_recording(&file).unwrap();
    let model = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../config/models/example-3dm-gx1.toml"
    );
    let r = replay(dir.path(), &file, "recal", &["--calibration", model]);
    let id = |rec: &Recording| rec.calibrations.first().map(|c| c.id.clone());
    assert!(original.calibrations.is_empty());
    assert!(id(&r).is_some());
    assert!(r.raw == original.raw, "the raw samples are the recording's");
    assert_eq!(r.imu.len(), original.imu.len());
    // Corrected with the model: every acceleration moves (its biases are not zero).
    let moved = r
        .imu
        .iter()
        .zip(&original.imu)
        .all(|(a, b)| a.linear_acceleration != b.linear_acceleration);
    assert!(moved);
}

/// Statuses from `sub` until one satisfies `until` (or 30 s pass: the test fails, with `log`).
fn wait_for_status(
    sub: &mut Subscription<DaemonStatus>,
    log: &Path,
    what: &str,
    until: impl Fn(&DaemonStatus) -> bool,
) -> DaemonStatus {
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        if let Some(s) = sub
            .wait(Duration::from_millis(100))
            .unwrap()
            .into_iter()
            .find(|s| until(s))
        {
            return s;
        }
        assert!(
            Instant::now() < deadline,
            "{what}: {}",
            std::fs::read_to_string(log).unwrap_or_default()
        );
    }
}

/// A live imud (start-up, protocol configured) on the simulator's pty, the device unplugged
/// once after 1.5 s of stream and reconnected; its recording, two device sessions.
fn live_with_reconnect(dir: &Path, protocol: DeviceProtocol) -> PathBuf {
    let text = format!(
        r#"
name = "replay-reconnect"
rate-hz = 100.0
[device]
baud = 115200
protocol = "{protocol}"
[[segment]]
kind = "static"
orientation = {{ x = "north", z = "up" }}
duration-s = 600.0
"#
    );
    let opts = SimOptions {
        scenario: Scenario::from_toml_str(&text, "reconnect scenario").unwrap(),
        scenario_text: text,
        truth: imu_model::Calibration::identity(),
        seed: 3,
        truth_out: None,
        link: Some(dir.join("imu0")),
        pacing: Pacing::RealTime,
        linger: Duration::ZERO,
    };
    let log = dir.join("live.stderr");
    let name = format!("{}-reconnect-{protocol}", unique(dir));
    let child = imud()
        .args([
            "--name",
            &name,
            "--baud",
            "115200",
            "--protocol",
            protocol.name(),
        ])
        .arg("--device")
        .arg(dir.join("imu0"))
        .arg("--log-dir")
        .arg(dir.join("live"))
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&log).unwrap())
        .spawn()
        .unwrap();
    let mut child = Killed(child);
    let mut status = Subscription::<DaemonStatus>::open(&name, Duration::from_secs(10)).unwrap();
    let sim = imu_sim::spawn(opts).unwrap();
    let first = wait_for_status(&mut status, &log, "first session", |s| {
        s.device_connected == 1 && s.samples >= 150
    });
    sim.unplug(Duration::from_millis(300));
    wait_for_status(&mut status, &log, "reconnected", |s| {
        s.reconnects == 1 && s.device_connected == 1 && s.samples >= first.samples + 150
    });
    let ok = Command::new("kill")
        .args(["-TERM", &child.0.id().to_string()])
        .status()
        .unwrap()
        .success();
    assert!(ok);
    assert!(
        child.0.wait().unwrap().success(),
        "{}",
        std::fs::read_to_string(&log).unwrap_or_default()
    );
    sim.stop();
    sim.join().unwrap();
    recording_in(&dir.join("live"))
}

#[test]
fn a_recording_that_spans_a_reconnect_replays_as_two_sessions_bit_for_bit() {
    for protocol in [
        DeviceProtocol::Gx1,
        DeviceProtocol::Mip,
        DeviceProtocol::Xsens,
        DeviceProtocol::Vectornav,
    ] {
        let dir = tempfile::tempdir().unwrap();
        let file = live_with_reconnect(dir.path(), protocol);
        let original = read_recording(&file).unwrap();
        let reconnects = |rec: &Recording| rec.statuses.iter().map(|(_, s)| s.reconnects).max();
        assert_eq!(reconnects(&original), Some(1), "{protocol}");
        assert!(
            original.imu.len() > 300,
            "{protocol}: {}",
            original.imu.len()
        );
        let again = replay(dir.path(), &file, "again", &[]);
        assert_eq!(again.imu.len(), original.imu.len(), "{protocol}");
        assert!(again.imu == original.imu, "{protocol}: /imu/data differs");
        assert!(again.raw == original.raw, "{protocol}: /imu/raw differs");
        assert!(again.frames == original.frames, "{protocol}: frames differ");
        assert!(
            again.device_compensated == original.device_compensated,
            "{protocol}: /imu/device_compensated differs"
        );
        // The replay had the live run's sessions: one reconnect, no samples lost across it.
        assert_eq!(reconnects(&again), Some(1), "{protocol}");
        let lost = |rec: &Recording| rec.statuses.last().map(|(_, s)| s.samples_lost);
        assert_eq!(lost(&again), lost(&original), "{protocol}");
    }
}
