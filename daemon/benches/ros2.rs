//! The DDS output's cost, measured against the Cyclone DDS peer inside a network namespace of
//! its own (see `daemon/tests/ros2_common`):
//!
//! 1. Latency from imud reading a frame's last byte (`RawSample::t_host_wall_ns`) to the Cyclone
//!    reader's listener receiving the `sensor_msgs/Imu` of that sample (wall clock, same host),
//!    at 500 Hz: p50, p99, p99.9 and the maximum.
//! 2. The CPU imud adds at 1 kHz: the process's on-CPU time (schedstat) over the same 15 s window with
//!    `--ros2` and a matched subscriber, and without `--ros2` (the simulator runs in imud's
//!    process in both, so the difference is the DDS output), and the DDS threads alone with a
//!    reader of `imu/data`, with no reader at all and with readers of every topic.
//! 3. The floor under that: the same thread hand-offs with no encoding and no DDS
//!    (`common/handoff_floor.rs`), two hops as imud's path has and one.
//!
//! Run: `cargo bench -p imud --bench ros2`. Numbers go to BENCHMARKS.md. `ROS2_BENCH_CONFIG`
//! adds `[ros2]` lines (`;`-separated, e.g. `depth = 5`); `ROS2_BENCH_LATENCY_ONLY=1` skips the
//! CPU part.

#[path = "common/cpu_time.rs"]
mod cpu_time;
#[path = "common/handoff_floor.rs"]
mod handoff_floor;
#[path = "../tests/ros2_common/mod.rs"]
mod ros2_common;

use std::time::{Duration, Instant};

use cpu_time::{cpu_ns, thread_cpu_ns};
use ros2_common::{End, Options, PeerTopics, Started, samples, stamp_ns};

/// A still device for `duration_s` at `rate_hz`; the truth is the identity.
fn scenario(rate_hz: f64, duration_s: f64, baud: u32) -> String {
    format!(
        "name = \"bench\"\nrate-hz = {rate_hz}\ntruth = \"truth.toml\"\n[device]\nbaud = {baud}\n\
         [[segment]]\nkind = \"static\"\nduration-s = {duration_s}\n"
    )
}

const MODEL: &str = "format = \"imud-calibration/1\"\n";

fn percentile(sorted: &[f64], p: f64) -> f64 {
    let i = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[i]
}

fn latency(rate_hz: f64, duration_s: f64) {
    let baud = 460_800;
    let run = Started::start(&Options {
        scenario: scenario(rate_hz, duration_s, baud),
        model: MODEL.into(),
        ros2_config: std::env::var("ROS2_BENCH_CONFIG")
            .unwrap_or_default()
            .replace(";", "\n"),
        ros2: true,
        peer: true,
        topics: PeerTopics::Only(&["imu"]),
        late_after_s: 1e9,
        end: End::PeerIdle,
        baud,
    })
    .finish()
    .expect("cyclonedds and unshare are needed");
    let got = samples(&run.peer["early"]["imu"], "imu");
    // The n-th /imu/data message is the n-th raw sample's (one each); find each received one by
    // its stamp.
    let index: std::collections::HashMap<u64, usize> = run
        .rec
        .imu
        .iter()
        .enumerate()
        .map(|(k, m)| (m.header.stamp.to_ns(), k))
        .collect();
    let mut lat_us: Vec<f64> = got
        .iter()
        .map(|s| {
            let k = index[&stamp_ns(s)];
            let read_ns = run.rec.raw[k].t_host_wall_ns;
            (s["rx_ns"].as_u64().unwrap() as f64 - read_ns as f64) * 1e-3
        })
        .collect();
    lat_us.sort_by(f64::total_cmp);
    report_drops(&run);
    println!(
        "latency at {rate_hz} Hz, frame read -> Cyclone receipt: {} of {} samples received; \
         p50 {:.0} us, p99 {:.0} us, p99.9 {:.0} us, max {:.0} us",
        got.len(),
        run.rec.imu.len(),
        percentile(&lat_us, 0.5),
        percentile(&lat_us, 0.99),
        percentile(&lat_us, 0.999),
        lat_us.last().unwrap(),
    );
}

/// imud's own count of what it could not publish (the DDS queue and writer, and shared memory,
/// which is off here), from the recording's last status.
fn report_drops(run: &ros2_common::Run) {
    let last = run.rec.statuses.last().map(|s| s.1);
    println!(
        "  (imud publish_drops at the end: {:?}, log_drops {:?}, samples_lost {:?})",
        last.map(|s| s.publish_drops),
        last.map(|s| s.log_drops),
        last.map(|s| s.samples_lost)
    );
}

/// imud's DDS threads (the `imud-ros2` thread and rustdds's own).
fn dds_thread_ns(pid: u32) -> u64 {
    thread_cpu_ns(pid, |comm| {
        comm.starts_with("imud-ros2") || comm.starts_with("RustDDS")
    })
}

/// Which readers the CPU measurement runs with.
#[derive(Clone, Copy, PartialEq)]
enum Readers {
    /// No `--ros2`, no peer.
    NoDds,
    /// `--ros2`, no reader of any topic (nothing is written).
    Nobody,
    /// `--ros2`, a reader of `imu/data` only (the other topics have none: not sent).
    ImuOnly,
    /// `--ros2`, the peer's readers of every topic.
    Every,
}

/// imud's CPU over 15 s of a 1 kHz stream (after 5 s of start-up), % of one core: the whole
/// process and its DDS threads.
fn cpu(rate_hz: f64, readers: Readers) -> (f64, f64) {
    let ros2 = readers != Readers::NoDds;
    let peer = matches!(readers, Readers::ImuOnly | Readers::Every);
    let baud = 460_800;
    let started = Started::start(&Options {
        scenario: scenario(rate_hz, 30.0, baud),
        model: MODEL.into(),
        ros2_config: std::env::var("ROS2_BENCH_CONFIG")
            .unwrap_or_default()
            .replace(";", "\n"),
        ros2,
        peer,
        topics: if readers == Readers::ImuOnly {
            PeerTopics::Only(&["imu"])
        } else {
            PeerTopics::Every
        },
        late_after_s: 1e9,
        end: End::AfterS(22.0),
        baud,
    });
    let pid = started
        .imud_pid(Duration::from_secs(30))
        .expect("imud started");
    std::thread::sleep(Duration::from_secs(5));
    let (t0, c0, d0) = (Instant::now(), cpu_ns(pid), dds_thread_ns(pid));
    std::thread::sleep(Duration::from_secs(15));
    let (t1, c1, d1) = (Instant::now(), cpu_ns(pid), dds_thread_ns(pid));
    let run = started.finish().expect("cyclonedds and unshare are needed");
    if peer {
        let got = samples(&run.peer["early"]["imu"], "imu").len();
        println!(
            "  (subscriber received {got} of {} samples)",
            run.rec.imu.len()
        );
        report_drops(&run);
    }
    let pct = |ns: u64| ns as f64 * 1e-9 / (t1 - t0).as_secs_f64() * 100.0;
    (pct(c1 - c0), pct(d1 - d0))
}

fn main() {
    if let Err(why) = ros2_common::confinement_available() {
        eprintln!("skipping: {why}");
        return;
    }
    latency(500.0, 20.0);
    if std::env::var_os("ROS2_BENCH_LATENCY_ONLY").is_some() {
        return;
    }
    let floor = |hops| handoff_floor::measure(hops, 1000.0, Duration::from_secs(10));
    let (two, one) = (
        floor(handoff_floor::Hops::Two),
        floor(handoff_floor::Hops::One),
    );
    println!(
        "hand-off floor at 1 kHz (no encoding, no DDS; one 400-byte datagram a sample), % of one \
         core: two hops (imud's shape) {two:.2}, one hop {one:.2}"
    );
    let (with, dds) = cpu(1000.0, Readers::ImuOnly);
    let (without, _) = cpu(1000.0, Readers::NoDds);
    println!(
        "cpu at 1 kHz, % of one core: imud --sim (simulator included) with --ros2 {with:.1}, \
         without {without:.1} (difference {:.1}); imud's DDS threads alone {dds:.1}",
        with - without
    );
    let (_, dds_nobody) = cpu(1000.0, Readers::Nobody);
    println!(
        "cpu at 1 kHz with --ros2 and no reader of any topic: imud's DDS threads {dds_nobody:.1}"
    );
    let (every, dds_every) = cpu(1000.0, Readers::Every);
    println!(
        "cpu at 1 kHz with readers of every topic (imu/data, data_raw, mag, temperature, \
         diagnostics): imud --sim {every:.1}, imud's DDS threads alone {dds_every:.1}"
    );
}
