//! Live calibration health end to end: imu-sim on a real pty -> the imud binary -> a real
//! iceoryx2 subscriber of `imud/<name>/health` and the MCAP's `/imud/health`. A still unit
//! whose accelerometer z bias is knocked by 0.05 m/s^2 half way: the health is `ok` before, goes
//! `degraded` after, says so in one log line, sizes the shift, and every report published is
//! recorded.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use imu_bus::CalibrationHealth;
use imu_bus::recording::read_recording;
use imu_bus::sample::health_state;
use imu_bus::shm::Subscription;
use imu_model::Calibration;
use imu_sim::{Pacing, Scenario, SimOptions};

const TRUTH: &str = r#"
format = "imud-calibration/1"
[accel.bias]
value = [0.15, -0.2, 0.1]
[accel.noise]
white-density = [0.0005, 0.0005, 0.0005]
[gyro.bias]
value = [0.01, -0.005, 0.008]
[gyro.noise]
white-density = [0.0002, 0.0002, 0.0002]
"#;

const SCENARIO: &str = r#"
name = "health-e2e"
rate-hz = 100.0
latitude-deg = 40.0
[device]
baud = 115200
[[disturbance]]
triad = "accel"
amplitude = [0.0, 0.0, 0.05]
step-at-s = 14.0
[[segment]]
kind = "static"
orientation = { x = "north", z = "up" }
duration-s = 30.0
"#;

fn config(dir: &Path, name: &str) -> PathBuf {
    let path = dir.join("imud.toml");
    std::fs::write(
        &path,
        format!(
            r#"name = "{name}"
[device]
path = "{dev}"
baud = 115200
[calibration]
path = "{cal}"
[log]
dir = "{logs}"
[health]
latitude-deg = 40.0
gravity-m-s2 = 9.80665
max-window-s = 4.0
"#,
            dev = dir.join("imu0").display(),
            cal = dir.join("calibration.toml").display(),
            logs = dir.join("logs").display(),
        ),
    )
    .unwrap();
    path
}

/// The daemon, killed if the test fails before it is stopped.
struct Imud(Child);

impl Drop for Imud {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
fn a_knock_on_a_still_unit_turns_the_live_health_degraded() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("calibration.toml"), TRUTH).unwrap();
    let name = format!("e2e-health-{}", std::process::id());
    let log = dir.path().join("imud.stderr");
    let mut imud = Imud(
        Command::new(env!("CARGO_BIN_EXE_imud"))
            .arg("--config")
            .arg(config(dir.path(), &name))
            .env("IMUD_LOG", "info")
            .env_remove("IMUD_CONFIG")
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&log).unwrap())
            .spawn()
            .unwrap(),
    );
    let stderr = || std::fs::read_to_string(&log).unwrap_or_default();
    let mut sub = Subscription::<CalibrationHealth>::open(&name, Duration::from_secs(10))
        .unwrap_or_else(|e| panic!("{e}: {}", stderr()));
    let sim = imu_sim::spawn(SimOptions {
        scenario: Scenario::from_toml_str(SCENARIO, "health scenario").unwrap(),
        scenario_text: SCENARIO.into(),
        truth: Calibration::from_toml_str(TRUTH, "truth").unwrap(),
        seed: 9,
        truth_out: None,
        link: Some(dir.path().join("imu0")),
        pacing: Pacing::RealTime,
        linger: Duration::from_secs(2),
    })
    .unwrap();
    let mut got: Vec<CalibrationHealth> = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(90);
    while Instant::now() < deadline && !sim.is_finished() {
        got.extend(sub.wait(Duration::from_millis(200)).unwrap());
    }
    sim.join().unwrap();
    got.extend(sub.wait(Duration::from_millis(500)).unwrap());
    let ok = Command::new("kill")
        .args(["-TERM", &imud.0.id().to_string()])
        .status()
        .unwrap()
        .success();
    assert!(ok);
    assert!(imud.0.wait().unwrap().success(), "{}", stderr());
    let log_text = stderr();

    // The device clock starts at the first sample; the knock is 14 s into the scenario.
    let t0 = got.first().expect("no health report").window_start_ns;
    let at_s = |r: &CalibrationHealth| (r.window_start_ns - t0) as f64 * 1e-9;
    let tested: Vec<_> = got.iter().filter(|r| r.accel_p.is_finite()).collect();
    let before: Vec<_> = tested.iter().filter(|r| at_s(r) + 4.5 < 13.0).collect();
    let after: Vec<_> = tested.iter().filter(|r| at_s(r) > 14.5).collect();
    assert!(
        !before.is_empty() && after.len() >= 2,
        "{got:#?}\n{log_text}"
    );
    assert!(
        before.iter().all(|r| r.accel_state == health_state::OK),
        "alarm before the knock: {before:#?}"
    );
    assert!(
        after.iter().all(|r| r.accel_state != health_state::OK),
        "knock not flagged: {after:#?}"
    );
    let last = after.last().unwrap();
    // Gravity along -z (z up: the specific force is +z; the bias adds to it).
    assert!(
        (last.accel_offset_m_s2[2] - 0.05).abs() < 0.015,
        "{:?}",
        last.accel_offset_m_s2
    );
    assert!(
        (last.accel_residual_m_s2 - 0.05).abs() < 0.015,
        "{}",
        last.accel_residual_m_s2
    );
    assert!(
        log_text.contains("health: accel ok -> degraded"),
        "{log_text}"
    );
    assert!(log_text.contains("along +z"), "{log_text}");
    assert!(after.iter().all(|r| r.gyro_state == health_state::OK));

    // Every report published is in the recording.
    let files: Vec<PathBuf> = std::fs::read_dir(dir.path().join("logs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "mcap"))
        .collect();
    let recordings: Vec<_> = files.iter().map(|f| read_recording(f).unwrap()).collect();
    let recorded: Vec<CalibrationHealth> =
        recordings.iter().flat_map(|r| r.health.clone()).collect();
    // The status carries the states too: the last one (at shutdown) says accel is not ok.
    let (_, status) = recordings
        .iter()
        .flat_map(|r| r.statuses.clone())
        .last()
        .expect("a status");
    assert!(
        matches!(
            status.health_accel,
            health_state::DEGRADED | health_state::STALE
        ),
        "{status:?}"
    );
    assert_eq!(status.health_gyro, health_state::OK);
    assert_eq!(
        recorded.len(),
        got.len(),
        "published {} recorded {}",
        got.len(),
        recorded.len()
    );
    for (a, b) in recorded.iter().zip(&got) {
        assert_eq!(a.window_start_ns, b.window_start_ns);
        assert_eq!(a.accel_state, b.accel_state);
    }
}
