//! End-to-end: imu-sim on a real pty -> the imud binary -> a real iceoryx2 subscriber and the MCAP
//! file, checked against the simulator's truth: no frame lost, values correct, hot reload,
//! reconnect after unplug, garbage skipped and counted, a readable file after kill -9. The
//! streaming tests run over both protocols (the simulated unit speaking 3DM-GX1 or MIP; imud
//! probes which), the offline one too.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use imu_bus::CorrectedSample;
use imu_bus::recording::read_recording;
use imu_bus::shm::Subscription;
use imu_bus::truth::is_data_command;
use imu_bus::truth::read_truth;
use imu_model::Calibration;
use imu_proto::DeviceProtocol;
use imu_sim::{Pacing, Scenario, SimOptions};

const TRUTH: &str = r#"
format = "imud-calibration/1"
[accel.bias]
value = [0.15, -0.2, 0.1]
[accel.scale]
value = [0.002, -0.001, 0.003]
[accel.misalignment]
xy = 0.002
zx = -0.001
[accel.noise]
white-density = [0.0005, 0.0005, 0.0005]
[gyro.bias]
value = [0.01, -0.005, 0.008]
[gyro.scale]
value = [0.003, 0.001, -0.002]
[gyro.noise]
white-density = [0.0002, 0.0002, 0.0002]
"#;

fn scenario(endless: bool, protocol: DeviceProtocol) -> String {
    format!(
        r#"
name = "e2e"
rate-hz = 100.0
[device]
baud = 115200
protocol = "{protocol}"
[[segment]]
kind = "static"
orientation = {{ x = "north", z = "up" }}
duration-s = 1.0
[[segment]]
kind = "index-table"
axis = "y"
step-deg = 60.0
positions = 4
dwell-s = 1.0
move-s = 0.5
[[segment]]
kind = "static"
{}
"#,
        if endless { "" } else { "duration-s = 1.0" }
    )
}

/// One data sample of the device equals one truth data record: the same device time.
fn assert_same_device_time(
    protocol: DeviceProtocol,
    raw: &imu_bus::RawSample,
    truth: &imu_bus::truth::TruthSample,
    i: usize,
) {
    match protocol {
        DeviceProtocol::Gx1 => assert_eq!(raw.ticks, truth.ticks, "sample {i}"),
        // The truth holds the 62.5 kHz internal timestamp, imud the ns reference time: both
        // floor the same device time.
        DeviceProtocol::Mip => {
            let truth_ns = truth.ticks_unwrapped as f64 * 16_000.0;
            let d = raw.t_device_ns as f64 - truth_ns;
            // -1: the ns floor of a time just above a whole ns in f64.
            assert!((-1.0..16_001.0).contains(&d), "sample {i}: {d} ns");
        }
    }
}

struct Imud {
    child: Child,
    log_path: PathBuf,
}

impl Imud {
    fn start(dir: &Path, name: &str, device: &Path, calibration: &Path) -> Self {
        Self::start_with(dir, name, device, calibration, &[])
    }

    /// The same with `extra` arguments.
    fn start_with(
        dir: &Path,
        name: &str,
        device: &Path,
        calibration: &Path,
        extra: &[&str],
    ) -> Self {
        let log_path = dir.join("imud.stderr");
        let child = Command::new(env!("CARGO_BIN_EXE_imud"))
            .args(["--name", name, "--baud", "115200"])
            .args(extra)
            .arg("--device")
            .arg(device)
            .arg("--calibration")
            .arg(calibration)
            .arg("--log-dir")
            .arg(dir.join("logs"))
            .env("IMUD_LOG", "info")
            .env_remove("IMUD_CONFIG")
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&log_path).unwrap())
            .spawn()
            .unwrap();
        Self { child, log_path }
    }

    fn stderr(&self) -> String {
        std::fs::read_to_string(&self.log_path).unwrap_or_default()
    }

    fn signal(&self, sig: &str) {
        let ok = Command::new("kill")
            .args([sig, &self.child.id().to_string()])
            .status()
            .unwrap()
            .success();
        assert!(ok);
    }

    fn terminate(mut self) -> String {
        self.signal("-TERM");
        let status = self.child.wait().unwrap();
        let log = self.stderr();
        assert!(status.success(), "imud exited with {status}: {log}");
        log
    }
}

impl Drop for Imud {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn sim_options(dir: &Path, endless: bool, protocol: DeviceProtocol) -> SimOptions {
    let text = scenario(endless, protocol);
    SimOptions {
        scenario: Scenario::from_toml_str(&text, "e2e scenario").unwrap(),
        scenario_text: text,
        truth: Calibration::from_toml_str(TRUTH, "truth").unwrap(),
        seed: 5,
        truth_out: Some(dir.join("truth.mcap")),
        link: Some(dir.join("imu0")),
        pacing: Pacing::RealTime,
        linger: Duration::from_secs(2),
    }
}

fn recordings(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir.join("logs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            let n = p.file_name().unwrap().to_string_lossy().into_owned();
            n.ends_with(".mcap") && !n.contains("truth")
        })
        .collect();
    files.sort();
    files
}

/// Runs a Python peer script from tests/python on `file` and parses its JSON. A missing peer
/// (exit 77) skips locally but fails under CI (`IMUD_REQUIRE_PEERS`).
fn python_peer(script: &str, file: &Path) -> Option<serde_json::Value> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/python")
        .join(script);
    let out = Command::new("python3").arg(&path).arg(file).output();
    match out {
        Ok(o) if o.status.success() => Some(serde_json::from_slice(&o.stdout).expect("peer JSON")),
        other => {
            let why = format!("{other:?}");
            assert!(
                std::env::var_os("IMUD_REQUIRE_PEERS").is_none(),
                "{script} failed: {why}"
            );
            eprintln!("skipping the {script} peer check: {why}");
            None
        }
    }
}

fn unique(name: &str) -> String {
    format!("e2e-{name}-{}", std::process::id())
}

/// Drains a subscriber until `until` returns true or the deadline passes.
fn drain(
    sub: &mut Subscription<CorrectedSample>,
    got: &mut Vec<CorrectedSample>,
    deadline: Instant,
    mut until: impl FnMut(&[CorrectedSample]) -> bool,
) {
    while Instant::now() < deadline && !until(got) {
        got.extend(sub.wait(Duration::from_millis(100)).unwrap());
    }
}

#[test]
fn every_frame_reaches_log_and_subscriber_and_matches_truth() {
    every_frame_reaches_log_and_subscriber(DeviceProtocol::Gx1);
}

#[test]
fn every_mip_frame_reaches_log_and_subscriber_and_matches_truth() {
    every_frame_reaches_log_and_subscriber(DeviceProtocol::Mip);
}

fn every_frame_reaches_log_and_subscriber(protocol: DeviceProtocol) {
    let dir = tempfile::tempdir().unwrap();
    let cal_path = dir.path().join("calibration.toml");
    std::fs::write(&cal_path, TRUTH).unwrap();
    let name = unique(&format!("lossless-{protocol}"));
    let opts = sim_options(dir.path(), false, protocol);
    // The daemon starts before the device exists and retries; the subscriber connects before any
    // sample is published, so it must see every one.
    let imud = Imud::start(dir.path(), &name, &dir.path().join("imu0"), &cal_path);
    let mut sub = Subscription::<CorrectedSample>::open(&name, Duration::from_secs(10))
        .unwrap_or_else(|e| panic!("{e}: {}", imud.stderr()));
    let sim = imu_sim::spawn(opts).unwrap();
    let mut got = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(60);
    drain(&mut sub, &mut got, deadline, |_| sim.is_finished());
    let report = sim.join().unwrap();
    drain(
        &mut sub,
        &mut got,
        Instant::now() + Duration::from_secs(1),
        |_| false,
    );
    let log = imud.terminate();

    let truth = read_truth(&dir.path().join("truth.mcap")).unwrap();
    let truth_data: Vec<_> = truth
        .samples
        .iter()
        .filter(|s| is_data_command(s.command))
        .collect();
    assert!(report.completed);
    // 750 samples in the scenario, less the start-up (about 0.5-1 s on a loaded machine, the
    // protocol probe included): the session spans every segment.
    assert!(
        truth_data.len() > 600,
        "{} samples: {log}",
        truth_data.len()
    );

    // Every frame the simulator sent is in the MCAP file, in order, with the sent ticks.
    let files = recordings(dir.path());
    assert_eq!(files.len(), 1, "{files:?}");
    let rec = read_recording(&files[0]).unwrap();
    assert!(rec.stopped_early.is_none(), "SIGTERM must finish the file");
    assert_eq!(rec.raw.len(), truth_data.len(), "{log}");
    for (i, (r, t)) in rec.raw.iter().zip(&truth_data).enumerate() {
        assert_eq!(r.seq, i as u64);
        assert_same_device_time(protocol, r, t, i);
    }
    let device = rec.metadata.get("imud.device").expect("device metadata");
    assert_eq!(
        device.get("protocol").map(String::as_str),
        Some(protocol.name())
    );
    assert!(
        rec.frames.iter().all(|f| f.accepted),
        "a clean line has no rejected bytes"
    );
    // Start-up set up and read back the unit: no status says its configuration is unverified.
    assert!(!rec.statuses.is_empty());
    assert!(
        rec.statuses
            .iter()
            .all(|(_, s)| s.configuration_unverified == 0)
    );

    // ... and reached the subscriber, every one, in order.
    assert_eq!(got.len(), truth_data.len(), "{log}");
    assert!(got.iter().enumerate().all(|(i, s)| s.seq == i as u64));

    // Corrected with the truth model itself, the stream equals the true input within the noise:
    // white density x sqrt(100 Hz) per sample, plus the 16-bit quantization.
    let lsb_accel = 7000.0 / 32_768_000.0 * 9.80665;
    let lsb_gyro = 10000.0 / 32_768_000.0;
    let sigma_accel = 0.0005 * 10.0;
    let sigma_gyro = 0.0002 * 10.0;
    let mut sum_err = [0.0f64; 6];
    for (s, t) in got.iter().zip(&truth_data) {
        for i in 0..3 {
            let ea = s.accel_m_s2[i] - t.specific_force_m_s2[i];
            let eg = s.gyro_rad_s[i] - t.angular_rate_rad_s[i];
            assert!(
                ea.abs() < 6.0 * sigma_accel + lsb_accel,
                "accel {i} error {ea} at seq {}",
                s.seq
            );
            assert!(
                eg.abs() < 6.0 * sigma_gyro + lsb_gyro,
                "gyro {i} error {eg} at seq {}",
                s.seq
            );
            sum_err[i] += ea;
            sum_err[3 + i] += eg;
        }
        assert_ne!(s.calibration_id, 0);
    }
    // The daemon's own file, read by independent peers: Python mcap + mcap-ros2-support decode
    // /imu/data as sensor_msgs/msg/Imu with the values the subscriber got; rosbags opens it as
    // a ROS 2 bag.
    if let Some(py) = python_peer("recording_read.py", &files[0]) {
        assert_eq!(py["profile"], "ros2");
        assert_eq!(py["schemas"]["/imu/data"][0], "sensor_msgs/msg/Imu");
        let imu = py["messages"]["/imu/data"].as_array().unwrap();
        assert_eq!(imu.len(), got.len());
        for (m, s) in imu.iter().zip(&got) {
            // Exact in CDR; the JSON hop costs at most an ulp or two.
            let same = |a: f64, b: f64| (a - b).abs() <= 1e-15 * b.abs() + 1e-300;
            for i in 0..3 {
                assert!(same(
                    m["linear_acceleration"][i].as_f64().unwrap(),
                    s.accel_m_s2[i]
                ));
                assert!(same(
                    m["angular_velocity"][i].as_f64().unwrap(),
                    s.gyro_rad_s[i]
                ));
            }
            // Orientation is not provided: element 0 of its covariance is -1 (REP 145).
            assert_eq!(m["orientation_covariance"][0].as_f64().unwrap(), -1.0);
        }
    }
    if let Some(bag) = python_peer("recording_rosbags.py", &files[0]) {
        assert_eq!(bag["connections"]["/imu/data"], "sensor_msgs/msg/Imu");
        assert_eq!(bag["imu"].as_array().unwrap().len(), got.len());
    }

    // No residual bias: the mean error is at the noise-averaging level, not the 0.1 m/s^2 bias.
    let n = got.len() as f64;
    for (k, e) in sum_err.iter().enumerate() {
        let sigma = if k < 3 { sigma_accel } else { sigma_gyro };
        assert!(
            (e / n).abs() < 5.0 * sigma / n.sqrt() + 0.5 * lsb_accel,
            "mean error {k}: {}",
            e / n
        );
    }
}

#[test]
fn a_passive_gx1_powered_up_streaming_is_recorded_sample_for_sample() {
    a_passive_unit_is_recorded_sample_for_sample(DeviceProtocol::Gx1);
}

#[test]
fn a_passive_mip_unit_powered_up_streaming_is_recorded_sample_for_sample() {
    a_passive_unit_is_recorded_sample_for_sample(DeviceProtocol::Mip);
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
    let sim = imu_sim::spawn(opts).unwrap();
    let mut got = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(60);
    drain(&mut sub, &mut got, deadline, |_| sim.is_finished());
    let report = sim.join().unwrap();
    drain(
        &mut sub,
        &mut got,
        Instant::now() + Duration::from_secs(1),
        |_| false,
    );
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

#[test]
fn hot_reload_garbage_unplug_and_kill_9() {
    hot_reload_garbage_unplug_and_kill(DeviceProtocol::Gx1);
}

#[test]
fn mip_hot_reload_garbage_unplug_and_kill_9() {
    hot_reload_garbage_unplug_and_kill(DeviceProtocol::Mip);
}

fn hot_reload_garbage_unplug_and_kill(protocol: DeviceProtocol) {
    let dir = tempfile::tempdir().unwrap();
    let cal_path = dir.path().join("calibration.toml");
    std::fs::write(&cal_path, TRUTH).unwrap();
    let name = unique(&format!("faults-{protocol}"));
    let imud = Imud::start(dir.path(), &name, &dir.path().join("imu0"), &cal_path);
    let mut sub = Subscription::<CorrectedSample>::open(&name, Duration::from_secs(10))
        .unwrap_or_else(|e| panic!("{e}: {}", imud.stderr()));
    let sim = imu_sim::spawn(sim_options(dir.path(), true, protocol)).unwrap();
    let mut got = Vec::new();
    // Wait until the scenario reached its final, endless still segment (6.5 s in).
    drain(
        &mut sub,
        &mut got,
        Instant::now() + Duration::from_secs(30),
        |g| g.len() >= 800,
    );
    assert!(got.len() >= 800, "{}", imud.stderr());

    // Hot reload: a calibration whose accel bias is 0.5 m/s^2 smaller on x moves corrected x by
    // +0.5 m/s^2 (bias is subtracted after the gain stages, scaled by 1/(1+s) and the inverse
    // misalignment), starting at one sample.
    let reloaded = TRUTH.replace("value = [0.15, -0.2, 0.1]", "value = [-0.35, -0.2, 0.1]");
    std::fs::write(&cal_path, &reloaded).unwrap();
    imud.signal("-HUP");
    let new_id = u64::from_str_radix(
        &Calibration::from_toml_str(&reloaded, "b")
            .unwrap()
            .content_id(),
        16,
    )
    .unwrap();
    drain(
        &mut sub,
        &mut got,
        Instant::now() + Duration::from_secs(20),
        |g| g.iter().filter(|s| s.calibration_id == new_id).count() >= 100,
    );
    let switch = got
        .iter()
        .position(|s| s.calibration_id == new_id)
        .expect("reload took effect");
    assert!(
        got[switch..].iter().all(|s| s.calibration_id == new_id),
        "one switch, never back"
    );
    let mean_x =
        |s: &[CorrectedSample]| s.iter().map(|v| v.accel_m_s2[0]).sum::<f64>() / s.len() as f64;
    // Both windows lie in the final still segment, so only the calibration differs.
    let before = &got[..switch];
    let after = &got[switch..];
    let last_before = &before[before.len().saturating_sub(50)..];
    let first_after = &after[..50.min(after.len())];
    let shift = mean_x(first_after) - mean_x(last_before);
    assert!(
        (shift - 0.5 / 1.002).abs() < 0.05,
        "reload shifted x by {shift}"
    );

    // Garbage on the line is skipped and counted; no frame is lost around it.
    let garbage: Vec<u8> = (0..64u8).map(|i| i.wrapping_mul(37) | 0x80).collect();
    sim.inject(&garbage);
    let n_before = got.len();
    drain(
        &mut sub,
        &mut got,
        Instant::now() + Duration::from_secs(20),
        |g| g.len() >= n_before + 100,
    );
    assert!(
        got.windows(2).all(|w| w[1].seq == w[0].seq + 1),
        "no sample lost around the garbage"
    );

    // Unplug for a second: the daemon reconnects by itself and samples resume.
    sim.unplug(Duration::from_secs(1));
    let n_before = got.len();
    drain(
        &mut sub,
        &mut got,
        Instant::now() + Duration::from_secs(30),
        |g| g.len() >= n_before + 300,
    );
    assert!(
        got.len() >= n_before + 300,
        "streaming did not resume after replug: {}",
        imud.stderr()
    );

    // kill -9: the file is readable up to at most about a second before the kill.
    std::thread::sleep(Duration::from_millis(1500));
    let killed_at_ns = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_nanos() as u64;
    imud.signal("-KILL");
    let log = imud.stderr();
    drop(imud);
    drop(sim);
    let files = recordings(dir.path());
    let rec = read_recording(files.last().unwrap()).unwrap();
    assert!(
        rec.stopped_early.is_some(),
        "a killed daemon leaves no summary"
    );
    let last = rec
        .raw
        .last()
        .expect("samples before the kill are readable");
    let lag_s = (killed_at_ns - last.t_host_wall_ns) as f64 * 1e-9;
    assert!(lag_s < 1.5, "file ends {lag_s:.2} s before the kill");

    // The log shows the garbage counted, the reconnect, and the new calibration.
    let (_, last_status) = rec.statuses.last().expect("status records");
    assert!(
        last_status.garbage_bytes + last_status.checksum_failures > 0,
        "{last_status:?}"
    );
    assert_eq!(last_status.reconnects, 1, "{last_status:?}: {log}");
    // Every injected byte is in the log, flagged as rejected, in order (nothing lost, nothing
    // passed off as a frame).
    let rejected: Vec<u8> = rec
        .frames
        .iter()
        .filter(|f| !f.accepted)
        .flat_map(|f| f.bytes.iter().copied())
        .collect();
    assert!(
        rejected
            .windows(garbage.len())
            .any(|w| w == garbage.as_slice()),
        "the injected bytes must appear, flagged, in /imu/raw_frame"
    );
    assert!(
        rec.calibrations
            .iter()
            .any(|c| c.id == format!("{new_id:016x}"))
    );
    // Across the unplug the sequence numbering continues without reuse.
    assert!(rec.raw.windows(2).all(|w| w[1].seq == w[0].seq + 1));
}

#[test]
fn bad_config_and_calibration_files_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("imud.toml");
    std::fs::write(
        &cfg,
        "name = \"x\"\n[device]\nbaud = 38400\nparity = \"none\"\n",
    )
    .unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_imud"))
        .arg("--config")
        .arg(&cfg)
        .arg("--print-config")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("imud.toml:4:") && err.contains("parity"),
        "{err}"
    );

    let cal = dir.path().join("cal.toml");
    std::fs::write(
        &cal,
        "format = \"imud-calibration/1\"\n[accel.bias]\nvalue = [1.0, 2.0]\n",
    )
    .unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_imud"))
        .args(["--device", "/nonexistent", "--name"])
        .arg(unique("badcal"))
        .arg("--calibration")
        .arg(&cal)
        .arg("--log-dir")
        .arg(dir.path().join("logs"))
        .output()
        .unwrap();
    assert!(
        !out.status.success(),
        "an invalid calibration at start-up is fatal"
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("cal.toml:3") && err.contains("accel.bias"),
        "{err}"
    );

    // --print-config shows the effective configuration with flags applied.
    let out = Command::new(env!("CARGO_BIN_EXE_imud"))
        .args(["--print-config", "--baud", "115200", "--name", "printed"])
        .env_remove("IMUD_CONFIG")
        .output()
        .unwrap();
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("baud = 115200") && text.contains("name = \"printed\""),
        "{text}"
    );
}

#[test]
fn polled_mode_logs_temperature_and_reloads_on_file_change() {
    let dir = tempfile::tempdir().unwrap();
    let cal_path = dir.path().join("calibration.toml");
    std::fs::write(&cal_path, TRUTH).unwrap();
    let cfg = dir.path().join("imud.toml");
    std::fs::write(
        &cfg,
        "[device]\nmode = \"polled\"\npoll-rate-hz = 50.0\ntemperature-rate-hz = 2.0\n[calibration]\nwatch = true\n",
    )
    .unwrap();
    let name = unique("polled");
    let mut opts = sim_options(dir.path(), true, DeviceProtocol::Gx1);
    opts.scenario.temperature = imu_sim::scenario::TemperatureProfile::Warmup {
        ambient_c: 22.0,
        operating_c: 38.0,
        tau_s: 20.0,
    };
    let sim = imu_sim::spawn(opts).unwrap();
    let child = Command::new(env!("CARGO_BIN_EXE_imud"))
        .args(["--name", &name, "--baud", "115200", "--config"])
        .arg(&cfg)
        .arg("--device")
        .arg(dir.path().join("imu0"))
        .arg("--calibration")
        .arg(&cal_path)
        .arg("--log-dir")
        .arg(dir.path().join("logs"))
        .env("IMUD_LOG", "info")
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(dir.path().join("imud.stderr")).unwrap())
        .spawn()
        .unwrap();
    let imud = Imud {
        child,
        log_path: dir.path().join("imud.stderr"),
    };
    let mut sub = Subscription::<CorrectedSample>::open(&name, Duration::from_secs(10)).unwrap();
    let mut got = Vec::new();
    drain(
        &mut sub,
        &mut got,
        Instant::now() + Duration::from_secs(30),
        |g| g.len() >= 150,
    );

    // An invalid file is rejected and the previous calibration stays in force.
    let old_id = got.last().unwrap().calibration_id;
    std::fs::write(
        &cal_path,
        "format = \"imud-calibration/1\"\n[gyro.scale]\nvalue = [0.1, 0.2]\n",
    )
    .unwrap();
    imud.signal("-HUP");
    drain(
        &mut sub,
        &mut got,
        Instant::now() + Duration::from_secs(5),
        |g| g.len() >= 250,
    );
    assert!(
        got.iter().all(|s| s.calibration_id == old_id),
        "an invalid file must not replace the calibration"
    );
    let log = imud.stderr();
    assert!(
        log.contains("calibration.toml:3") && log.contains("gyro.scale"),
        "{log}"
    );

    // A valid edit is picked up by the file watch alone (no signal).
    std::thread::sleep(Duration::from_millis(1100)); // a new modification time
    let edited = TRUTH.replace(
        "value = [0.01, -0.005, 0.008]",
        "value = [0.02, -0.005, 0.008]",
    );
    std::fs::write(&cal_path, &edited).unwrap();
    let new_id = u64::from_str_radix(
        &Calibration::from_toml_str(&edited, "e")
            .unwrap()
            .content_id(),
        16,
    )
    .unwrap();
    drain(
        &mut sub,
        &mut got,
        Instant::now() + Duration::from_secs(10),
        |g| g.last().is_some_and(|s| s.calibration_id == new_id),
    );
    assert_eq!(
        got.last().unwrap().calibration_id,
        new_id,
        "{}",
        imud.stderr()
    );
    let log = imud.terminate();
    drop(sim);

    // Every poll answered is logged: samples and temperatures (at 2 Hz) match the truth.
    let truth = read_truth(&dir.path().join("truth.mcap")).unwrap();
    let rec = read_recording(&recordings(dir.path())[0]).unwrap();
    let truth_samples = truth
        .samples
        .iter()
        .filter(|s| is_data_command(s.command))
        .count();
    let truth_temps: Vec<f64> = truth
        .samples
        .iter()
        .filter(|s| s.command == 0x07)
        .map(|s| s.temp_c)
        .collect();
    // The simulator may have answered a last poll the daemon never read before it stopped.
    assert!(
        truth_samples - rec.raw.len() <= 1,
        "{truth_samples} vs {}: {log}",
        rec.raw.len()
    );
    assert!(truth_temps.len() - rec.temperatures.len() <= 1);
    let span_s = (rec.raw.last().unwrap().t_host_wall_ns - rec.raw[0].t_host_wall_ns) as f64 * 1e-9;
    assert!(
        rec.temperatures.len() as f64 >= 2.0 * span_s - 2.0,
        "{} temperatures in {span_s:.1} s",
        rec.temperatures.len()
    );
    for ((_, logged), truth_c) in rec.temperatures.iter().zip(&truth_temps) {
        assert!((logged - truth_c).abs() < 0.01, "{logged} vs {truth_c}");
    }
    // The warm-up is visible in the log: temperature rises.
    assert!(rec.temperatures.last().unwrap().1 > rec.temperatures[0].1 + 1.0);
}

#[test]
fn offline_recording_equals_the_truth_sample_for_sample() {
    offline_recording_equals_the_truth(DeviceProtocol::Gx1);
}

#[test]
fn offline_mip_recording_equals_the_truth_sample_for_sample() {
    offline_recording_equals_the_truth(DeviceProtocol::Mip);
}

fn offline_recording_equals_the_truth(protocol: DeviceProtocol) {
    let dir = tempfile::tempdir().unwrap();
    let scenario_path = dir.path().join("scenario.toml");
    // The scenario names its truth model (a top-level key, so before any table).
    std::fs::write(
        &scenario_path,
        format!(
            "truth = \"truth-model.toml\"\n{}",
            scenario(false, protocol)
        ),
    )
    .unwrap();
    std::fs::write(dir.path().join("truth-model.toml"), TRUTH).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_imud"))
        .args(["--offline", "--seed", "9", "--name", "off", "--log-dir"])
        .arg(dir.path().join("logs"))
        .arg("--sim")
        .arg(&scenario_path)
        .env_remove("IMUD_CONFIG")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let printed = String::from_utf8_lossy(&out.stdout);
    let files: Vec<&str> = printed.lines().collect();
    assert_eq!(files.len(), 2, "recording and truth paths: {printed}");
    let rec = read_recording(Path::new(files[0])).unwrap();
    let truth = read_truth(Path::new(files[1])).unwrap();
    assert_eq!(truth.run.get("seed").map(String::as_str), Some("9"));
    let data: Vec<_> = truth
        .samples
        .iter()
        .filter(|s| is_data_command(s.command))
        .collect();
    assert_eq!(rec.raw.len(), data.len());
    assert_eq!(rec.raw.len(), 750, "7.5 s at 100 Hz");
    // Temperature at the default 1 Hz, as a thermal analysis needs (polled from a GX1, the
    // MIP packets' field recorded once a second).
    assert_eq!(rec.temperatures.len(), 8);
    for (i, (r, t)) in rec.raw.iter().zip(&data).enumerate() {
        assert_same_device_time(protocol, r, t, i);
        match protocol {
            DeviceProtocol::Gx1 => {
                // Raw counts decode to the truth's pre-quantization measurement within half
                // an LSB, and the device reading is that decoding.
                let a =
                    imu_proto::scale::raw_bits_to_units(r.accel_counts[2] as u16, 7000) * 9.80665;
                assert!(
                    (a - t.measured_accel_m_s2[2]).abs()
                        <= 0.5 * 7000.0 / 32_768_000.0 * 9.80665 + 1e-12
                );
                assert_eq!(r.accel_device_m_s2[2], a);
            }
            DeviceProtocol::Mip => {
                // No counts; the device reading is the measurement in f32.
                assert_eq!(r.flags & imu_bus::sample::raw_flags::NO_COUNTS, 16);
                for k in 0..3 {
                    let (got, want) = (r.gyro_device_rad_s[k], t.measured_gyro_rad_s[k]);
                    assert!(
                        (got - want).abs() <= 1e-7 * want.abs() + 1e-30,
                        "{got} {want}"
                    );
                    let (got, want) = (r.accel_device_m_s2[k], t.measured_accel_m_s2[k]);
                    assert!(
                        (got - want).abs() <= 1e-6 * want.abs() + 1e-12,
                        "{got} {want}"
                    );
                }
            }
        }
    }
}
