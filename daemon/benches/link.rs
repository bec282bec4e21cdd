//! Whole-system benchmarks through a real pseudo-terminal: imu-sim -> the imud binary -> an
//! iceoryx2 subscriber and the MCAP file.
//!
//! 1. Sustained throughput: the simulator streams as fast as the link allows; reports frames/s
//!    and checks that every frame sent is in the MCAP file (and how many the subscriber saw).
//! 2. Latency from the daemon reading a frame's last byte to a subscriber's receipt (p50, p99,
//!    p99.9), both on CLOCK_MONOTONIC, with event wake-ups.
//! 3. CPU use of the imud process at 100 Hz and at 1 kHz.
//! 4. The same unit speaking MIP at 1 kHz (its base rate): every frame logged, and CPU.
//! 5. The same unit as an Xsens MTi at 2 kHz (an MTi-600's highest HR rate): every frame sent
//!    after imud's start-up logged; CPU at 1 kHz.
//! 6. The same unit speaking VectorNav at 800 Hz (its IMU rate, the highest it outputs):
//!    every frame logged, and CPU.
//!
//! Run: `cargo bench -p imud --bench link` (`-- mip`, `-- xsens` or `-- vectornav` for that part
//! alone). Numbers go to BENCHMARKS.md.

#[path = "common/cpu_time.rs"]
mod cpu_time;

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use imu_bus::RawSample;
use imu_bus::recording::read_recording;
use imu_bus::shm::Subscription;
use imu_model::Calibration;
use imu_proto::DeviceProtocol;
use imu_sim::{Pacing, Scenario, SimOptions};

fn scenario(rate_hz: f64, duration_s: f64, baud: u32, protocol: DeviceProtocol) -> String {
    format!(
        "name = \"bench\"\nrate-hz = {rate_hz}\n[device]\nbaud = {baud}\nprotocol = \"{protocol}\"\n[[segment]]\nkind = \"static\"\nduration-s = {duration_s}\n"
    )
}

fn sim(dir: &Path, text: &str, pacing: Pacing) -> imu_sim::SimHandle {
    let model = Calibration::load(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../config/models/example-3dm-gx1.toml"
    )))
    .expect("example model");
    imu_sim::spawn(SimOptions {
        scenario: Scenario::from_toml_str(text, "bench").expect("scenario"),
        scenario_text: text.to_string(),
        truth: model,
        seed: 1,
        truth_out: None,
        link: Some(dir.join("imu0")),
        pacing,
        linger: Duration::from_secs(3),
    })
    .expect("simulator")
}

/// imud on the simulated device, told its protocol (the probe is not what is measured).
fn imud(dir: &Path, name: &str, baud: u32, protocol: DeviceProtocol) -> Child {
    Command::new(env!("CARGO_BIN_EXE_imud"))
        .args(["--name", name, "--baud", &baud.to_string()])
        .args(["--protocol", protocol.name()])
        .arg("--device")
        .arg(dir.join("imu0"))
        .arg("--log-dir")
        .arg(dir.join("logs"))
        .env("IMUD_LOG", "warn")
        .env_remove("IMUD_CONFIG")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("imud")
}

fn stop(mut child: Child) {
    let _ = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status();
    let _ = child.wait();
}

fn recorded_raw(dir: &Path) -> usize {
    let mut n = 0;
    for e in std::fs::read_dir(dir.join("logs")).expect("logs") {
        let p = e.expect("entry").path();
        if p.extension().is_some_and(|x| x == "mcap") {
            n += read_recording(&p).expect("recording").raw.len();
        }
    }
    n
}

/// Streams `n_frames` through the pty, either as fast as the link allows (`rate_hz` = None) or
/// paced at `rate_hz` in real time (the simulated baud rate is set high enough not to limit it).
fn throughput(n_frames: u64, rate_hz: Option<f64>, protocol: DeviceProtocol) {
    let dir = tempfile::tempdir().expect("tmp");
    let name = format!(
        "bench-tp-{}-{protocol}-{}",
        rate_hz.unwrap_or(0.0) as u64,
        std::process::id()
    );
    let rate = rate_hz.unwrap_or(1000.0);
    let text = scenario(rate, n_frames as f64 / rate, 100_000_000, protocol);
    let daemon = imud(dir.path(), &name, 4_000_000, protocol);
    let mut sub =
        Subscription::<RawSample>::open(&name, Duration::from_secs(10)).expect("subscriber");
    let pacing = if rate_hz.is_some() {
        Pacing::RealTime
    } else {
        Pacing::Fast
    };
    let sim = sim(dir.path(), &text, pacing);
    let mut received = 0usize;
    let mut first: Option<Instant> = None;
    let mut last = Instant::now();
    let mut buf = Vec::new();
    while !sim.is_finished() {
        buf.clear();
        if sub
            .wait_into(Duration::from_millis(50), &mut buf)
            .unwrap_or(0)
            > 0
        {
            first.get_or_insert_with(Instant::now);
            last = Instant::now();
            received += buf.len();
        }
    }
    let report = sim.join().expect("sim");
    let t0 = first.unwrap_or(last);
    std::thread::sleep(Duration::from_millis(500));
    stop(daemon);
    let logged = recorded_raw(dir.path());
    let secs = (last - t0).as_secs_f64();
    // A MIP unit sends nothing before it is configured; the GX1 answers one start-up poll; an
    // MTi streams from power-up until imud's GoToConfig, and those samples are not imud's.
    let sent = match protocol {
        DeviceProtocol::Gx1 => report.data_replies - 1,
        DeviceProtocol::Mip | DeviceProtocol::Vectornav => report.data_replies,
        DeviceProtocol::Xsens => {
            report.data_replies - report.data_replies_before_first_command.unwrap_or(0)
        }
    };
    println!(
        "throughput, {protocol} ({}): {} frames sent in {:.2} s = {:.0} frames/s; logged {} ({}), subscriber saw {} (buffer 256; a slower subscriber loses the oldest)",
        rate_hz.map_or("as fast as the pty allows".to_string(), |r| format!(
            "paced at {r} Hz"
        )),
        sent,
        secs,
        sent as f64 / secs,
        logged,
        if logged as u64 == sent {
            "zero loss"
        } else {
            "LOSS"
        },
        received
    );
}

fn latency() {
    let dir = tempfile::tempdir().expect("tmp");
    let name = format!("bench-lat-{}", std::process::id());
    let text = scenario(500.0, 40.0, 115_200, DeviceProtocol::Gx1);
    let daemon = imud(dir.path(), &name, 115_200, DeviceProtocol::Gx1);
    let mut sub =
        Subscription::<RawSample>::open(&name, Duration::from_secs(10)).expect("subscriber");
    let sim = sim(dir.path(), &text, Pacing::RealTime);
    let mut lat_us = Vec::new();
    let mut buf = Vec::new();
    while !sim.is_finished() {
        buf.clear();
        if sub
            .wait_into(Duration::from_millis(50), &mut buf)
            .unwrap_or(0)
            > 0
        {
            let now = nix::time::clock_gettime(nix::time::ClockId::CLOCK_MONOTONIC).expect("clock");
            let now_ns = now.tv_sec() as u64 * 1_000_000_000 + now.tv_nsec() as u64;
            for s in &buf {
                lat_us.push(now_ns.saturating_sub(s.t_host_monotonic_ns) as f64 * 1e-3);
            }
        }
    }
    drop(sim);
    stop(daemon);
    lat_us.sort_by(f64::total_cmp);
    let q = |p: f64| lat_us[((lat_us.len() - 1) as f64 * p) as usize];
    println!(
        "latency (last byte read by imud -> subscriber receipt, {} samples at 500 Hz): p50 {:.0} us, p99 {:.0} us, p99.9 {:.0} us, max {:.0} us",
        lat_us.len(),
        q(0.5),
        q(0.99),
        q(0.999),
        lat_us.last().copied().unwrap_or(f64::NAN)
    );
}

fn cpu(rate_hz: f64, protocol: DeviceProtocol) {
    let dir = tempfile::tempdir().expect("tmp");
    let name = format!(
        "bench-cpu-{}-{protocol}-{}",
        rate_hz as u64,
        std::process::id()
    );
    let baud = if rate_hz > 300.0 { 460_800 } else { 115_200 };
    let text = scenario(rate_hz, 25.0, baud, protocol);
    let daemon = imud(dir.path(), &name, baud, protocol);
    let sim = sim(dir.path(), &text, Pacing::RealTime);
    std::thread::sleep(Duration::from_secs(3));
    let (t0, c0) = (Instant::now(), cpu_time::cpu_ns(daemon.id()));
    std::thread::sleep(Duration::from_secs(15));
    let (t1, c1) = (Instant::now(), cpu_time::cpu_ns(daemon.id()));
    let cpu_pct = (c1 - c0) as f64 * 1e-9 / (t1 - t0).as_secs_f64() * 100.0;
    drop(sim);
    stop(daemon);
    println!(
        "cpu: imud ({protocol}) at {rate_hz} Hz uses {cpu_pct:.1} % of one core (on-CPU time from schedstat, 15 s window, logging and publishing on)"
    );
}

fn main() {
    let mip = DeviceProtocol::Mip;
    let xsens = DeviceProtocol::Xsens;
    let vectornav = DeviceProtocol::Vectornav;
    if std::env::args().skip(1).any(|a| a == "mip") {
        throughput(60_000, Some(1000.0), mip);
        cpu(1000.0, mip);
        return;
    }
    if std::env::args().skip(1).any(|a| a == "xsens") {
        throughput(120_000, Some(2000.0), xsens);
        cpu(1000.0, xsens);
        return;
    }
    if std::env::args().skip(1).any(|a| a == "vectornav") {
        throughput(48_000, Some(800.0), vectornav);
        cpu(800.0, vectornav);
        return;
    }
    let gx1 = DeviceProtocol::Gx1;
    throughput(600_000, Some(60_000.0), gx1);
    throughput(300_000, None, gx1);
    latency();
    cpu(100.0, gx1);
    cpu(1000.0, gx1);
    throughput(60_000, Some(1000.0), mip);
    cpu(1000.0, mip);
    throughput(120_000, Some(2000.0), xsens);
    cpu(1000.0, xsens);
    throughput(48_000, Some(800.0), vectornav);
    cpu(800.0, vectornav);
}
