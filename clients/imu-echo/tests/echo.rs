//! End-to-end tests of the `imu-echo` binary against [`Publishers`] in this process: `--count`,
//! the jsonl/csv output, a closed pipe, and the error for an instance that does not run.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

use imu_bus::CorrectedSample;
use imu_bus::shm::{Publishers, ShmEvent, ShmOptions, Stream};

/// Upper bound for a child process; only reached when something hangs.
const PATIENCE: Duration = Duration::from_secs(60);

fn unique_instance(tag: &str) -> String {
    static COUNTER: AtomicU32 = AtomicU32::new(0);
    format!(
        "echo-{}-{tag}-{}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    )
}

fn imu_echo() -> Command {
    Command::new(env!("CARGO_BIN_EXE_imu-echo"))
}

fn corrected(seq: u64) -> CorrectedSample {
    CorrectedSample {
        seq,
        t_sample_ns: 10_000_000 * seq,
        accel_m_s2: [0.1 * seq as f64, -9.80665, 0.0],
        gyro_rad_s: [0.0, 0.001, -0.5],
        temp_c: 24.5,
        ..Default::default()
    }
}

/// Publishes corrected samples (seq 0, 1, ...) every 10 ms until `child` exits.
fn publish_until_exit(publishers: &mut Publishers, child: &mut Child) -> std::process::ExitStatus {
    let deadline = Instant::now() + PATIENCE;
    let mut seq = 0;
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            return status;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("imu-echo did not exit within {PATIENCE:?}");
        }
        publishers.publish_corrected(&corrected(seq)).unwrap();
        publishers.notify(ShmEvent::Samples).unwrap();
        seq += 1;
        std::thread::sleep(Duration::from_millis(10));
    }
}

#[test]
fn count_exits_zero_after_n_jsonl_samples() {
    let instance = unique_instance("count");
    let mut publishers = Publishers::open(&instance, &ShmOptions::default()).unwrap();
    let mut child = imu_echo()
        .args(["--name", &instance, "--format", "jsonl", "--count", "5"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let status = publish_until_exit(&mut publishers, &mut child);
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(status.success(), "{status}: {stderr}");
    let stdout = String::from_utf8(out.stdout).unwrap();
    let seqs: Vec<u64> = stdout
        .lines()
        .map(|l| {
            let v: serde_json::Value = serde_json::from_str(l).expect(l);
            assert_eq!(v["accel_m_s2"][1], -9.80665, "{l}");
            assert_eq!(v["temp_c"], 24.5, "{l}");
            v["seq"].as_u64().unwrap()
        })
        .collect();
    assert_eq!(seqs.len(), 5, "{stdout}");
    assert!(seqs.windows(2).all(|w| w[1] == w[0] + 1), "{seqs:?}");
    assert!(
        stderr.contains(&format!("imud/{instance}/corrected")),
        "a final statistics line names the service: {stderr}"
    );
}

#[test]
fn a_closed_pipe_exits_zero() {
    let instance = unique_instance("pipe");
    let mut publishers = Publishers::open(&instance, &ShmOptions::default()).unwrap();
    let mut child = imu_echo()
        .args(["--name", &instance, "--format", "csv", "--quiet"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Read the header and one row, then close the pipe like `| head -2` does.
    let mut stdout = BufReader::new(child.stdout.take().unwrap());
    let mut header = String::new();
    stdout.read_line(&mut header).unwrap();
    assert!(
        header.starts_with("seq,t_sample_ns,accel_x_m_s2"),
        "{header}"
    );
    let deadline = Instant::now() + PATIENCE;
    while publishers.subscribers(Stream::Corrected) == 0 {
        assert!(Instant::now() < deadline, "imu-echo never subscribed");
        std::thread::sleep(Duration::from_millis(10));
    }
    publishers.publish_corrected(&corrected(0)).unwrap();
    publishers.notify(ShmEvent::Samples).unwrap();
    let mut row = String::new();
    stdout.read_line(&mut row).unwrap();
    assert!(row.starts_with("0,0,0,-9.80665,"), "{row}");
    drop(stdout);

    let status = publish_until_exit(&mut publishers, &mut child);
    let stderr = String::from_utf8_lossy(&child.wait_with_output().unwrap().stderr).into_owned();
    assert!(status.success(), "{status}: {stderr}");
    assert!(stderr.is_empty(), "{stderr}");
}

#[test]
fn an_instance_that_does_not_run_is_an_error_naming_it() {
    let instance = unique_instance("absent");
    let out = imu_echo()
        .args(["--name", &instance, "--timeout-s", "0.2", "--status"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains(&format!("no imud instance named \"{instance}\" is running")),
        "{stderr}"
    );
    assert!(
        stderr.starts_with("imu-echo: error: subscribing to the status stream"),
        "{stderr}"
    );
}

#[test]
fn health_reports_print_their_states_by_name() {
    use imu_bus::CalibrationHealth;
    use imu_bus::sample::health_state;
    let instance = unique_instance("health");
    let mut publishers = Publishers::open(&instance, &ShmOptions::default()).unwrap();
    let mut child = imu_echo()
        .args([
            "--name", &instance, "--health", "--format", "csv", "--count", "2",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + PATIENCE;
    let report = |k: u64| CalibrationHealth {
        t_sample_ns: 20_000_000_000 + k,
        window_start_ns: 2_000_000_000 + k,
        accel_state: health_state::DEGRADED,
        gyro_state: health_state::OK,
        accel_residual_m_s2: 0.05,
        accel_offset_m_s2: [0.0, 0.0, 0.05],
        ..Default::default()
    };
    let mut k = 0;
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        assert!(Instant::now() < deadline, "imu-echo did not exit");
        publishers.publish_health(&report(k)).unwrap();
        publishers.notify(ShmEvent::Health).unwrap();
        k += 1;
        std::thread::sleep(Duration::from_millis(10));
    };
    let out = child.wait_with_output().unwrap();
    assert!(status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8(out.stdout).unwrap();
    let mut lines = stdout.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 2, "{stdout}");
    let at = |name: &str| header.iter().position(|h| *h == name).unwrap();
    assert_eq!(rows[0][at("accel_state")], "degraded");
    assert_eq!(rows[0][at("gyro_state")], "ok");
    assert_eq!(rows[0][at("accel_offset_z_m_s2")], "0.05");
    assert_eq!(rows[0][at("window_s")].parse::<f64>().unwrap(), 18.0);
}
