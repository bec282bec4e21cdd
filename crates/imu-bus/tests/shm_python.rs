//! Cross-language test: `examples/python/imu_subscriber.py` (the `iceoryx2` package from PyPI)
//! subscribes to services published by [`Publishers`] in this process and must print exactly
//! the values published, proving the ctypes mirrors and type names match the Rust layouts.
//!
//! Skipped with a message when python3 or its `iceoryx2` package is missing, unless
//! `IMUD_REQUIRE_PEERS` is set, in which case that is a failure.

use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

use imu_bus::shm::{Publishers, ShmEvent, ShmOptions};
use imu_bus::{CorrectedSample, RawSample};
use serde_json::Value;

/// Upper bound for the Python process; only reached when something hangs.
const PATIENCE: Duration = Duration::from_secs(60);

fn unique_instance(tag: &str) -> String {
    static COUNTER: AtomicU32 = AtomicU32::new(0);
    format!(
        "pytest-{}-{tag}-{}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    )
}

fn example_script() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../examples/python/imu_subscriber.py")
}

/// True when python3 can import iceoryx2; otherwise skips (or fails under IMUD_REQUIRE_PEERS).
fn python_peer_available() -> bool {
    let probe = Command::new("python3")
        .args(["-c", "import iceoryx2"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status();
    if probe.is_ok_and(|s| s.success()) {
        return true;
    }
    let why = "python3 with the `iceoryx2` package is not available \
               (pip install -r requirements-dev.txt)";
    if std::env::var_os("IMUD_REQUIRE_PEERS").is_some() {
        panic!("{why}, and IMUD_REQUIRE_PEERS is set");
    }
    eprintln!("SKIPPED: {why}");
    false
}

fn raw_sample(seq: u64) -> RawSample {
    RawSample {
        seq,
        t_device_ns: 10_000_000 * seq + 3,
        t_host_monotonic_ns: u64::MAX - seq,
        t_host_wall_ns: 1_700_000_000_000_000_000 + seq,
        t_sample_ns: 5_000_000 * seq,
        ticks_unwrapped: 65_536 + seq,
        accel_counts: [i32::MIN, -(seq as i32), i32::MAX],
        gyro_counts: [1, -2, 3],
        mag_counts: [32_767, -32_768, seq as i32],
        temp_c: 21.5 + seq as f64 / 3.0,
        ticks: (seq % 65_536) as u16,
        command: 0x0c,
        reserved: 0,
        flags: (seq % 16) as u32,
        accel_device_m_s2: [seq as f64 * 0.5, -9.80665, f64::INFINITY],
        gyro_device_rad_s: [1e-3, -2e-3, seq as f64],
        mag_device_gauss: [0.25, -0.5, 0.125],
    }
}

fn corrected_sample(seq: u64) -> CorrectedSample {
    let x = seq as f64;
    CorrectedSample {
        seq,
        t_sample_ns: 5_000_000 * seq,
        t_wall_ns: 1_700_000_000_000_000_000 + seq,
        t_device_ns: 10_000_000 * seq + 3,
        // Values with long decimal expansions, a subnormal, -0.0 and extremes: the JSON printed
        // by Python must parse back to the same bits.
        accel_m_s2: [0.1 * x + 0.2, -9.80665 / (x + 1.0), f64::MIN_POSITIVE / 8.0],
        gyro_rad_s: [-0.0, 1e-300 * x, f64::MAX],
        mag_gauss: [std::f64::consts::PI * x, -std::f64::consts::E, 1.0 / 3.0],
        temp_c: if seq.is_multiple_of(2) {
            f64::NAN
        } else {
            25.0 + x / 7.0
        },
        calibration_id: 0xdead_beef_0000_0000 + seq,
        flags: (seq % 8) as u32,
        reserved: 0,
    }
}

/// JSON of a float the way the example prints it: non-finite values as null.
fn float(x: f64) -> Value {
    if x.is_finite() {
        Value::from(x)
    } else {
        Value::Null
    }
}

fn floats(xs: &[f64]) -> Value {
    Value::Array(xs.iter().copied().map(float).collect())
}

fn expected_raw(s: &RawSample) -> Value {
    serde_json::json!({
        "stream": "raw",
        "seq": s.seq,
        "t_device_ns": s.t_device_ns,
        "t_host_monotonic_ns": s.t_host_monotonic_ns,
        "t_host_wall_ns": s.t_host_wall_ns,
        "t_sample_ns": s.t_sample_ns,
        "ticks_unwrapped": s.ticks_unwrapped,
        "accel_counts": s.accel_counts,
        "gyro_counts": s.gyro_counts,
        "mag_counts": s.mag_counts,
        "temp_c": float(s.temp_c),
        "ticks": s.ticks,
        "command": s.command,
        "reserved": s.reserved,
        "flags": s.flags,
        "accel_device_m_s2": floats(&s.accel_device_m_s2),
        "gyro_device_rad_s": floats(&s.gyro_device_rad_s),
        "mag_device_gauss": floats(&s.mag_device_gauss),
    })
}

fn expected_corrected(s: &CorrectedSample) -> Value {
    serde_json::json!({
        "stream": "corrected",
        "seq": s.seq,
        "t_sample_ns": s.t_sample_ns,
        "t_wall_ns": s.t_wall_ns,
        "t_device_ns": s.t_device_ns,
        "accel_m_s2": floats(&s.accel_m_s2),
        "gyro_rad_s": floats(&s.gyro_rad_s),
        "mag_gauss": floats(&s.mag_gauss),
        "temp_c": float(s.temp_c),
        "calibration_id": s.calibration_id,
        "flags": s.flags,
        "reserved": s.reserved,
    })
}

/// Compares floats by bits (serde_json's `==` on numbers would let -0.0 equal 0.0).
fn assert_same(got: &Value, want: &Value, line: &str) {
    match (got, want) {
        (Value::Object(g), Value::Object(w)) => {
            assert_eq!(
                g.keys().collect::<Vec<_>>(),
                w.keys().collect::<Vec<_>>(),
                "fields of {line}"
            );
            for (k, wv) in w {
                assert_same(&g[k], wv, line);
            }
        }
        (Value::Array(g), Value::Array(w)) => {
            assert_eq!(g.len(), w.len(), "{line}");
            for (gv, wv) in g.iter().zip(w) {
                assert_same(gv, wv, line);
            }
        }
        (Value::Number(g), Value::Number(w)) if w.is_f64() => {
            let (g, w) = (g.as_f64().unwrap(), w.as_f64().unwrap());
            assert_eq!(g.to_bits(), w.to_bits(), "{g} != {w} in {line}");
        }
        (g, w) => assert_eq!(g, w, "in {line}"),
    }
}

#[test]
fn the_python_example_receives_exactly_what_was_published() {
    if !python_peer_available() {
        return;
    }
    const COUNT: usize = 40;
    let instance = unique_instance("interop");
    let mut publishers = Publishers::open(&instance, &ShmOptions::default()).expect("publishers");
    let mut child = Command::new("python3")
        .arg(example_script())
        .args([
            "--name",
            &instance,
            "--raw",
            "--format",
            "jsonl",
            "--timeout",
            "30",
        ])
        .args(["--count", &COUNT.to_string()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start python3");

    // Publish raw + corrected pairs until the subscriber has printed COUNT samples and exited.
    // Python may connect at any point; it must then see a gap-free run of what was published.
    let deadline = Instant::now() + PATIENCE;
    let mut published = 0u64;
    let status = loop {
        if let Some(status) = child.try_wait().expect("poll python") {
            break status;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("the Python subscriber did not finish within {PATIENCE:?}");
        }
        publishers.publish_raw(&raw_sample(published)).unwrap();
        publishers
            .publish_corrected(&corrected_sample(published))
            .unwrap();
        publishers.notify(ShmEvent::Samples).unwrap();
        published += 1;
        std::thread::sleep(Duration::from_millis(10)); // the device's 100 Hz
    };
    let out = child.wait_with_output().expect("python output");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(status.success(), "python exited with {status}: {stderr}");

    let stdout = String::from_utf8(out.stdout).expect("utf-8");
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(lines.len(), COUNT, "{stdout}\n{stderr}");
    let mut last_seq: [Option<u64>; 2] = [None, None];
    for line in &lines {
        let got: Value = serde_json::from_str(line).expect("a JSON line");
        let seq = got["seq"].as_u64().expect("seq");
        assert!(seq < published, "{line}");
        let (want, slot) = match got["stream"].as_str() {
            Some("raw") => (expected_raw(&raw_sample(seq)), 0),
            Some("corrected") => (expected_corrected(&corrected_sample(seq)), 1),
            other => panic!("unexpected stream {other:?} in {line}"),
        };
        assert_same(&got, &want, line);
        if let Some(prev) = last_seq[slot] {
            assert_eq!(seq, prev + 1, "gap or reordering before {line}");
        }
        last_seq[slot] = Some(seq);
    }
    assert!(last_seq.iter().all(Option::is_some), "both streams arrived");
}

#[test]
fn the_python_example_reports_a_missing_instance() {
    if !python_peer_available() {
        return;
    }
    let instance = unique_instance("absent");
    let out = Command::new("python3")
        .arg(example_script())
        .args(["--name", &instance, "--timeout", "0.2", "--count", "1"])
        .output()
        .expect("run python3");
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains(&format!("no imud instance named '{instance}' is running")),
        "{stderr}"
    );
}

#[test]
fn the_python_example_refuses_services_an_untrusted_user_created() {
    if !python_peer_available() {
        return;
    }
    let instance = unique_instance("untrusted");
    let _publishers = Publishers::open(&instance, &ShmOptions::default()).expect("publishers");
    let me = imu_bus::shm::UserId::current().0;
    let stranger = me.wrapping_add(4242).to_string();
    // Trusting another uid only: refused before any sample, naming the creator (this user).
    let out = Command::new("python3")
        .arg(example_script())
        .args(["--name", &instance, "--timeout", "5", "--count", "1"])
        .args(["--publisher-user", &stranger])
        .output()
        .expect("run python3");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(out.stdout.is_empty());
    assert!(stderr.contains("not a trusted imud publisher"), "{stderr}");
    assert!(stderr.contains(&format!("(uid {me})")), "{stderr}");
    // (With the default trust, this user's own, the other tests of this file receive.)
}

/// A listening readers' socket of this process in a fresh directory.
fn readers_listener(dir: &std::path::Path) -> (socket2::Socket, PathBuf) {
    let path = dir.join("readers.sock");
    let s = socket2::Socket::new(socket2::Domain::UNIX, socket2::Type::SEQPACKET, None).unwrap();
    s.bind(&socket2::SockAddr::unix(&path).unwrap()).unwrap();
    s.listen(4).unwrap();
    (s, path)
}

#[test]
fn the_python_example_reads_the_readers_socket_exactly() {
    use imu_bus::readers::encode_packet;
    use std::io::Write;
    // The socket mode needs python3 only, not its iceoryx2 package.
    if Command::new("python3").arg("--version").output().is_err() {
        assert!(
            std::env::var_os("IMUD_REQUIRE_PEERS").is_none(),
            "python3 is missing"
        );
        eprintln!("SKIPPED: python3 is missing");
        return;
    }
    const PAIRS: u64 = 12;
    let dir = tempfile::tempdir().unwrap();
    let (listener, path) = readers_listener(dir.path());
    let child = Command::new("python3")
        .arg(example_script())
        .arg("--socket")
        .arg(&path)
        .args(["--raw", "--format", "jsonl", "--timeout", "30"])
        .args(["--count", &(2 * PAIRS).to_string()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start python3");
    let (mut conn, _) = listener.accept().unwrap();
    let mut packet = Vec::new();
    for seq in 0..PAIRS {
        encode_packet(&raw_sample(seq), &mut packet);
        conn.write_all(&packet).unwrap();
        // A status between the samples: skipped by the example, never misread.
        encode_packet(&imu_bus::DaemonStatus::default(), &mut packet);
        conn.write_all(&packet).unwrap();
        encode_packet(&corrected_sample(seq), &mut packet);
        conn.write_all(&packet).unwrap();
    }
    let out = child.wait_with_output().expect("python output");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "python: {stderr}");
    let stdout = String::from_utf8(out.stdout).unwrap();
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(lines.len() as u64, 2 * PAIRS, "{stdout}\n{stderr}");
    for (i, line) in lines.iter().enumerate() {
        let seq = i as u64 / 2;
        let want = if i % 2 == 0 {
            expected_raw(&raw_sample(seq))
        } else {
            expected_corrected(&corrected_sample(seq))
        };
        assert_same(&serde_json::from_str(line).unwrap(), &want, line);
    }
}

#[test]
fn the_python_example_refuses_a_socket_served_by_an_untrusted_user() {
    if Command::new("python3").arg("--version").output().is_err() {
        assert!(
            std::env::var_os("IMUD_REQUIRE_PEERS").is_none(),
            "python3 is missing"
        );
        eprintln!("SKIPPED: python3 is missing");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (_listener, path) = readers_listener(dir.path());
    let other = imu_bus::shm::UserId::current().0.wrapping_add(1);
    let out = Command::new("python3")
        .arg(example_script())
        .arg("--socket")
        .arg(&path)
        .args(["--publisher-user", &other.to_string(), "--count", "1"])
        .output()
        .expect("run python3");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(out.stdout.is_empty(), "{stderr}");
    assert!(
        stderr.contains("which is not a trusted imud publisher"),
        "{stderr}"
    );
    assert!(
        stderr.contains(&format!("pid {}", std::process::id())),
        "{stderr}"
    );
}
