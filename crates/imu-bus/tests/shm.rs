//! Tests of the shared-memory contract against real iceoryx2 services: bit-identical round
//! trips, a stalled subscriber never blocks the publisher, event wake-up, start order, and
//! recovery after a publisher process is killed with SIGKILL.
//!
//! Every test uses its own instance name (pid + counter) so tests run in parallel without
//! sharing services. Time limits only turn a hang into a failure; nothing asserts speed.

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use iceoryx2::node::NodeView;
use iceoryx2::prelude::*;
use imu_bus::shm::{
    ProcessIdentity, Publishers, ShmError, ShmEvent, ShmOptions, Stream, Subscriber, Subscription,
    TrustedPublishers, UserId, validate_instance_name,
};
use imu_bus::{CorrectedSample, DaemonStatus, RawSample};

/// Upper bound for anything that should happen "soon"; only reached when something hangs.
const PATIENCE: Duration = Duration::from_secs(30);

/// Env var that turns [`helper_child_publisher_process`] into a publishing child process.
const CHILD_ENV: &str = "IMUD_SHM_TEST_CHILD_INSTANCE";

fn unique_instance(tag: &str) -> String {
    static COUNTER: AtomicU32 = AtomicU32::new(0);
    format!(
        "test-{}-{tag}-{}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    )
}

fn raw_sample(seq: u64) -> RawSample {
    RawSample {
        seq,
        t_device_ns: u64::MAX - 1,
        t_host_monotonic_ns: 123_456_789_012,
        t_host_wall_ns: 1_700_000_000_123_456_789,
        t_sample_ns: 123_456_700_000 + seq,
        ticks_unwrapped: 0x1234_5678_9abc,
        accel_counts: [i32::MIN, -1, i32::MAX],
        gyro_counts: [32767, -32768, 0],
        mag_counts: [1, 2, 65535],
        temp_c: f64::from_bits(0x7ff8_0000_dead_beef), // a NaN with a payload
        ticks: 0xfffe,
        command: 0x31,
        reserved: 0,
        flags: 0b1011,
        accel_device_m_s2: [1.5, -9.81, 0.0],
        gyro_device_rad_s: [f64::MIN_POSITIVE, -1.0, 1e300],
        mag_device_gauss: [0.3, 0.2, -0.1],
    }
}

fn corrected_sample(seq: u64) -> CorrectedSample {
    CorrectedSample {
        seq,
        t_sample_ns: 42 + seq,
        t_wall_ns: 1_700_000_000_000_000_001,
        t_device_ns: 7,
        accel_m_s2: [0.1 + 0.2, -9.80665, f64::MIN_POSITIVE / 4.0], // includes a subnormal
        gyro_rad_s: [-0.0, 1e-300, f64::MAX],
        mag_gauss: [0.25, -0.5, std::f64::consts::PI],
        temp_c: 25.125,
        calibration_id: 0xdead_beef_cafe_f00d,
        flags: 0b0101,
        reserved: 0,
    }
}

fn daemon_status(n: u64) -> DaemonStatus {
    DaemonStatus {
        t_host_monotonic_ns: 1 + n,
        frames: 2,
        samples: 3,
        checksum_failures: 4,
        resyncs: 5,
        garbage_bytes: 6,
        truncated_frames: 7,
        samples_lost: 8,
        log_drops: 9,
        publish_drops: 10,
        reconnects: 11,
        calibration_id: u64::MAX,
        tick_period_est_s: 0.006_553_6,
        clock_drift_ppm: -12.5,
        temp_c: f64::NAN,
        device_connected: 1,
        logging: 0,
        gains_fallback: 7,
        health_accel: 1,
        health_gyro: 3,
        protocol: 1,
        configuration_unverified: 1,
        reserved: 0,
        clock_offset_s: -0.0,
        clock_residual_s: f64::NAN,
        gain_scale_accel: 7000,
        gain_scale_gyro: 10_000,
        gain_scale_mag: 2000,
        reserved_end: [0; 2],
        packets_unusable: u64::MAX,
        fields_skipped: 13,
        time_source: 2,
        time_sync: 4,
        reserved_sync: [0; 6],
        gnss_minus_wall_s: -0.25,
        gnss_drift_ppm: f64::NAN,
        gnss_valid_transitions: 3,
        gnss_lost_transitions: u64::MAX - 1,
    }
}

/// Every field as raw bits, so floats compare bit for bit (NaN payloads and -0.0 included).
fn raw_bits(s: &RawSample) -> Vec<u64> {
    let mut v = vec![
        s.seq,
        s.t_device_ns,
        s.t_host_monotonic_ns,
        s.t_host_wall_ns,
        s.t_sample_ns,
        s.ticks_unwrapped,
    ];
    v.extend(
        s.accel_counts
            .iter()
            .chain(&s.gyro_counts)
            .chain(&s.mag_counts)
            .map(|&c| c as u32 as u64),
    );
    v.extend([
        s.temp_c.to_bits(),
        s.ticks.into(),
        s.command.into(),
        s.reserved.into(),
        s.flags.into(),
    ]);
    v
}

fn corrected_bits(s: &CorrectedSample) -> Vec<u64> {
    let mut v = vec![s.seq, s.t_sample_ns, s.t_wall_ns, s.t_device_ns];
    v.extend(
        s.accel_m_s2
            .iter()
            .chain(&s.gyro_rad_s)
            .chain(&s.mag_gauss)
            .map(|x| x.to_bits()),
    );
    v.extend([
        s.temp_c.to_bits(),
        s.calibration_id,
        s.flags.into(),
        s.reserved.into(),
    ]);
    v
}

fn status_bits(s: &DaemonStatus) -> Vec<u64> {
    let mut v = vec![
        s.t_host_monotonic_ns,
        s.frames,
        s.samples,
        s.checksum_failures,
        s.resyncs,
        s.garbage_bytes,
        s.truncated_frames,
        s.samples_lost,
        s.log_drops,
        s.publish_drops,
        s.reconnects,
        s.calibration_id,
        s.tick_period_est_s.to_bits(),
        s.clock_drift_ppm.to_bits(),
        s.temp_c.to_bits(),
        s.device_connected.into(),
        s.logging.into(),
        s.gains_fallback.into(),
        s.health_accel.into(),
        s.health_gyro.into(),
        s.clock_offset_s.to_bits(),
        s.clock_residual_s.to_bits(),
        s.gain_scale_accel.into(),
        s.gain_scale_gyro.into(),
        s.gain_scale_mag.into(),
        s.protocol.into(),
        s.configuration_unverified.into(),
        s.reserved.into(),
        s.packets_unusable,
        s.fields_skipped,
        s.time_source.into(),
        s.time_sync.into(),
        s.gnss_minus_wall_s.to_bits(),
        s.gnss_drift_ppm.to_bits(),
        s.gnss_valid_transitions,
        s.gnss_lost_transitions,
    ];
    v.extend(s.reserved_end.iter().map(|&b| u64::from(b)));
    v.extend(s.reserved_sync.iter().map(|&b| u64::from(b)));
    v
}

/// Waits until at least one sample arrives (or [`PATIENCE`] runs out).
fn wait_for_one<T: imu_bus::shm::ShmPayload>(sub: &mut Subscription<T>) -> Vec<T> {
    let deadline = Instant::now() + PATIENCE;
    let mut got = Vec::new();
    while got.is_empty() && Instant::now() < deadline {
        got = sub.wait(Duration::from_millis(500)).expect("wait");
    }
    got
}

#[test]
fn every_payload_type_round_trips_bit_identical() {
    let instance = unique_instance("roundtrip");
    let mut publishers = Publishers::open(&instance, &ShmOptions::default()).expect("publishers");
    let mut raw = Subscription::<RawSample>::open(&instance, PATIENCE).expect("raw sub");
    let mut corrected =
        Subscription::<CorrectedSample>::open(&instance, PATIENCE).expect("corrected sub");
    let mut status = Subscription::<DaemonStatus>::open(&instance, PATIENCE).expect("status sub");
    assert_eq!(publishers.subscribers(Stream::Raw), 1);
    assert_eq!(publishers.subscribers(Stream::Corrected), 1);
    assert_eq!(publishers.subscribers(Stream::Status), 1);

    let (r, c, s) = (raw_sample(5), corrected_sample(5), daemon_status(5));
    assert_eq!(publishers.publish_raw(&r).expect("raw"), 1);
    assert_eq!(publishers.publish_corrected(&c).expect("corrected"), 1);
    publishers.notify(ShmEvent::Samples).expect("notify");
    assert_eq!(publishers.publish_status(&s).expect("status"), 1);
    publishers.notify(ShmEvent::Status).expect("notify");

    let got_raw = wait_for_one(&mut raw);
    let got_corrected = wait_for_one(&mut corrected);
    let got_status = wait_for_one(&mut status);
    assert_eq!(got_raw.len(), 1);
    assert_eq!(got_corrected.len(), 1);
    assert_eq!(got_status.len(), 1);
    assert_eq!(raw_bits(&got_raw[0]), raw_bits(&r));
    assert_eq!(corrected_bits(&got_corrected[0]), corrected_bits(&c));
    assert_eq!(status_bits(&got_status[0]), status_bits(&s));
    assert_eq!(publishers.drops(), 0);
    assert_eq!(raw.received(), 1);
    assert_eq!(raw.missed(), 0);
    assert_eq!(raw.publishers(), 1);
    assert!(corrected.try_recv().expect("try_recv").is_none());
}

#[test]
fn a_subscriber_that_never_reads_does_not_block_the_publisher() {
    const BUFFER: usize = 4;
    const FLOOD: u64 = 100 * BUFFER as u64;
    let instance = unique_instance("stall");
    let (to_main, from_publisher) = mpsc::channel::<&'static str>();
    let (to_publisher, from_main) = mpsc::channel::<()>();
    let inst = instance.clone();
    // iceoryx2 ports are not Send, so the publisher lives entirely in its own thread; if it
    // blocked, the channel below would time out instead of hanging the test.
    let publisher = std::thread::spawn(move || -> u64 {
        let options = ShmOptions {
            subscriber_buffer_size: BUFFER,
            history_size: 0,
            max_subscribers: 2,
        };
        let mut publishers = Publishers::open(&inst, &options).expect("publishers");
        to_main.send("open").unwrap();
        from_main.recv().unwrap(); // subscribed
        publishers.publish_corrected(&corrected_sample(0)).unwrap();
        publishers.notify(ShmEvent::Samples).unwrap();
        from_main.recv().unwrap(); // the subscriber has seen seq 0 and stops reading
        for seq in 1..=FLOOD {
            publishers
                .publish_corrected(&corrected_sample(seq))
                .unwrap();
            publishers.notify(ShmEvent::Samples).unwrap();
        }
        to_main.send("flooded").unwrap();
        from_main.recv().unwrap(); // keep the publisher alive until the subscriber drained
        publishers.drops()
    });

    assert_eq!(from_publisher.recv_timeout(PATIENCE), Ok("open"));
    let mut sub = Subscription::<CorrectedSample>::open(&instance, PATIENCE).expect("sub");
    to_publisher.send(()).unwrap();
    let first = wait_for_one(&mut sub);
    assert_eq!(first.iter().map(|s| s.seq).collect::<Vec<_>>(), [0]);
    to_publisher.send(()).unwrap();

    assert_eq!(
        from_publisher.recv_timeout(PATIENCE),
        Ok("flooded"),
        "the publisher did not finish publishing {FLOOD} samples to a subscriber that does not read"
    );
    let mut newest = Vec::new();
    sub.drain_into(&mut newest).expect("drain");
    to_publisher.send(()).unwrap();
    let drops = publisher.join().expect("publisher thread");

    let seqs: Vec<u64> = newest.iter().map(|s| s.seq).collect();
    let expected: Vec<u64> = (FLOOD - BUFFER as u64 + 1..=FLOOD).collect();
    assert_eq!(seqs, expected, "the subscriber keeps the newest samples");
    assert_eq!(
        sub.missed(),
        FLOOD - BUFFER as u64,
        "overwritten samples show as seq gaps"
    );
    assert_eq!(
        drops, 0,
        "overwriting a slow subscriber is not a publish failure"
    );
}

#[test]
fn a_subscriber_blocked_in_wait_is_woken_by_notify() {
    let instance = unique_instance("wake");
    let mut publishers = Publishers::open(&instance, &ShmOptions::default()).expect("publishers");
    let (to_main, from_waiter) = mpsc::channel();
    let inst = instance.clone();
    let wait_timeout = 2 * PATIENCE;
    let waiter = std::thread::spawn(move || {
        let mut sub = Subscription::<CorrectedSample>::open(&inst, PATIENCE).expect("sub");
        to_main.send(None).unwrap();
        let started = Instant::now();
        let got = sub.wait(wait_timeout).expect("wait");
        to_main.send(Some((got, started.elapsed()))).unwrap();
    });
    assert_eq!(from_waiter.recv_timeout(PATIENCE).unwrap(), None);
    // Give the waiter time to go to sleep in the listener; correctness does not depend on it.
    std::thread::sleep(Duration::from_millis(200));
    publishers.publish_corrected(&corrected_sample(77)).unwrap();
    publishers.notify(ShmEvent::Samples).unwrap();

    let (got, waited) = from_waiter
        .recv_timeout(wait_timeout + PATIENCE)
        .expect("waiter finished")
        .expect("result");
    waiter.join().unwrap();
    assert_eq!(got.len(), 1);
    assert_eq!(
        corrected_bits(&got[0]),
        corrected_bits(&corrected_sample(77))
    );
    assert!(
        waited < wait_timeout,
        "wait() returned only at its timeout: the notification did not wake it"
    );
}

#[test]
fn a_subscriber_may_start_before_the_daemon() {
    let instance = unique_instance("early");
    let (to_main, from_sub) = mpsc::channel();
    let inst = instance.clone();
    let subscriber = std::thread::spawn(move || {
        let mut sub = Subscriber::open(&inst, Stream::Status, PATIENCE).expect("sub");
        assert_eq!(sub.stream(), Stream::Status);
        let Subscriber::Status(sub) = &mut sub else {
            unreachable!()
        };
        to_main.send(wait_for_one(sub)).unwrap();
    });
    std::thread::sleep(Duration::from_millis(300));
    let mut publishers = Publishers::open(&instance, &ShmOptions::default()).expect("publishers");
    // Publish until the late subscriber has connected and received (bounded by PATIENCE).
    let deadline = Instant::now() + PATIENCE;
    let got = loop {
        publishers.publish_status(&daemon_status(1)).unwrap();
        publishers.notify(ShmEvent::Status).unwrap();
        if let Ok(got) = from_sub.recv_timeout(Duration::from_millis(50)) {
            break got;
        }
        assert!(
            Instant::now() < deadline,
            "the early subscriber never received"
        );
    };
    subscriber.join().unwrap();
    assert!(!got.is_empty());
    assert_eq!(status_bits(&got[0]), status_bits(&daemon_status(1)));
}

#[test]
fn opening_an_instance_that_does_not_run_names_it() {
    let instance = unique_instance("absent");
    let err = Subscription::<CorrectedSample>::open(&instance, Duration::from_millis(200))
        .expect_err("nothing runs under this name");
    assert!(matches!(err, ShmError::NotRunning { .. }), "{err:?}");
    let msg = err.to_string();
    assert!(
        msg.contains(&format!("no imud instance named \"{instance}\" is running")),
        "{msg}"
    );
    assert!(msg.contains(&format!("imud/{instance}/corrected")), "{msg}");
}

#[test]
fn instance_names_are_validated() {
    assert!(validate_instance_name("default").is_ok());
    assert!(validate_instance_name("lab-2.imu_A").is_ok());
    for bad in ["", "a/b", "with space", "ü", &"x".repeat(65)] {
        let err = Publishers::open(bad, &ShmOptions::default()).expect_err(bad);
        assert!(
            matches!(err, ShmError::InvalidInstanceName { .. }),
            "{bad}: {err:?}"
        );
    }
}

#[test]
fn a_second_publisher_on_the_same_instance_is_refused() {
    let instance = unique_instance("twice");
    let _first = Publishers::open(&instance, &ShmOptions::default()).expect("first");
    let err = Publishers::open(&instance, &ShmOptions::default()).expect_err("second");
    assert!(matches!(err, ShmError::AlreadyPublishing { .. }), "{err:?}");
    assert!(err.to_string().contains("already publishing"), "{err}");
    // The error names the process that holds the service: this one, as this user.
    let ShmError::AlreadyPublishing { holder, .. } = err else {
        unreachable!()
    };
    assert_eq!(
        holder,
        Some(ProcessIdentity {
            pid: std::process::id() as i32,
            user: Some(UserId::current()),
        })
    );
}

#[test]
fn a_subscriber_trusts_a_publisher_by_its_user_only() {
    let instance = unique_instance("trust");
    let _publishers = Publishers::open(&instance, &ShmOptions::default()).expect("publishers");
    let sub = Subscription::<CorrectedSample>::open(&instance, Duration::from_secs(5)).unwrap();
    let me = UserId::current();
    let publisher = sub
        .verify_publisher(&TrustedPublishers::users(vec![me]))
        .expect("this user's own publisher is trusted");
    assert_eq!(publisher.map(|p| p.pid), Some(std::process::id() as i32));
    assert!(TrustedPublishers::default_for_this_process().contains(me));
    // Any other user is not: the service was created by this one.
    let other = UserId(me.0.wrapping_add(4242));
    let err = sub
        .verify_publisher(&TrustedPublishers::users(vec![other]))
        .expect_err("another user's publisher is refused");
    assert!(
        matches!(err, ShmError::UntrustedPublisher { .. }),
        "{err:?}"
    );
    assert!(err.to_string().contains("created by"), "{err}");
}

/// Not a test on its own: with [`CHILD_ENV`] set it is the body of the child process that
/// [`a_publisher_killed_with_sigkill_is_cleaned_up_and_replaced`] starts and kills.
#[test]
fn helper_child_publisher_process() {
    let Ok(instance) = std::env::var(CHILD_ENV) else {
        return;
    };
    let mut publishers = Publishers::open(&instance, &ShmOptions::default()).expect("child");
    println!("READY");
    // Bounded so an orphaned child cannot outlive the test run by much.
    let deadline = Instant::now() + 2 * PATIENCE;
    let mut seq = 0;
    while Instant::now() < deadline {
        publishers
            .publish_corrected(&corrected_sample(seq))
            .unwrap();
        publishers.notify(ShmEvent::Samples).unwrap();
        seq += 1;
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Kills the child process if the test fails before it does.
struct KillOnDrop(std::process::Child);

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn dead_nodes_named(name: &str) -> usize {
    let mut n = 0;
    Node::<ipc::Service>::list(Config::global_config(), |state| {
        if let NodeState::Dead(view) = &state
            && view
                .details()
                .as_ref()
                .is_some_and(|d| d.name().as_str() == name)
        {
            n += 1;
        }
        CallbackProgression::Continue
    })
    .expect("list nodes");
    n
}

#[test]
fn a_publisher_killed_with_sigkill_is_cleaned_up_and_replaced() {
    let instance = unique_instance("sigkill");
    let mut child = Command::new(std::env::current_exe().unwrap())
        .args([
            "--exact",
            "helper_child_publisher_process",
            "--nocapture",
            "--test-threads=1",
        ])
        .env(CHILD_ENV, &instance)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn child");
    let stdout = child.stdout.take().unwrap();
    let mut child = KillOnDrop(child);
    // libtest prints "test helper_child_publisher_process ... " before the test's own output.
    let mut lines = BufReader::new(stdout).lines();
    assert!(
        lines.any(|l| l.is_ok_and(|l| l.trim_end().ends_with("READY"))),
        "the child never became ready"
    );

    // A subscriber that lives across the crash, and proof the child really published.
    let mut survivor = Subscription::<CorrectedSample>::open(&instance, PATIENCE).expect("sub");
    assert!(
        !wait_for_one(&mut survivor).is_empty(),
        "nothing from the child"
    );
    assert_eq!(survivor.publishers(), 1);

    child.0.kill().expect("SIGKILL"); // std's kill() is SIGKILL on Unix
    child.0.wait().expect("reap");

    // Each service admits one publisher, so this only succeeds if the dead child's publisher
    // was removed by the stale-resource cleanup.
    let mut publishers = Publishers::open(&instance, &ShmOptions::default())
        .expect("a new daemon opens the same instance after a SIGKILL");
    assert_eq!(
        dead_nodes_named(&format!("imud-{instance}")),
        0,
        "the dead node's resources are gone"
    );
    let mut fresh = Subscription::<CorrectedSample>::open(&instance, PATIENCE).expect("fresh");
    let marker = corrected_sample(1_000_000);
    publishers.publish_corrected(&marker).unwrap();
    publishers.notify(ShmEvent::Samples).unwrap();

    let got = wait_for_one(&mut fresh);
    assert_eq!(
        got.last().map(corrected_bits),
        Some(corrected_bits(&marker))
    );
    let deadline = Instant::now() + PATIENCE;
    let mut last = None;
    while last.map(|s: CorrectedSample| s.seq) != Some(marker.seq) && Instant::now() < deadline {
        last = survivor
            .wait(Duration::from_millis(500))
            .unwrap()
            .last()
            .copied()
            .or(last);
    }
    assert_eq!(
        last.map(|s| s.seq),
        Some(marker.seq),
        "a subscriber from before the crash receives from the new daemon"
    );
    assert_eq!(survivor.publishers(), 1);
}
