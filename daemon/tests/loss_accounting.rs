//! The per-frame path at CPU speed with synthesized links: loss accounting on a clean link with
//! host jitter and on a corrupting one, and time stamps through host stalls. Frames go through
//! the real codec (the GX1 driver, its session set as a streaming unit's) and `Pipeline`;
//! arrival times are made up, so minutes of link take a moment.

use imu_proto::reply::Reply;
use imud::config::DeviceConfig;
use imud::drivers::gx1::{self, Gx1Driver};
use imud::drivers::{Driver, DriverEvent, FrameSlot};
use imud::pipeline::{GainFallback, Gains, Pipeline, Sinks, log_rejected};

const TICK_S: f64 = 6.5536e-3;

/// A small deterministic generator (fixed seeds: the outcomes are exact, not statistical).
struct Lcg(u64);

impl Lcg {
    fn unit(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A continuous raw-bits stream (100 Hz unless said) from a device whose clock runs
/// `drift_ppm` fast.
struct Link {
    drift_ppm: f64,
    rng: Lcg,
    period_s: f64,
}

impl Link {
    /// True host time of sample `k`, s, and its frame.
    fn sample(&self, k: u64) -> (f64, Vec<u8>) {
        let device_s = 3.0 + k as f64 * self.period_s;
        let host_s = 50.0 + k as f64 * self.period_s / (1.0 + self.drift_ppm * 1e-6);
        let ticks = ((device_s / TICK_S).floor() as u64 % 65_536) as u16;
        let w = |i: u64| 32_768 + ((k * 7 + i * 13) % 50) as u16;
        let mut bytes = Vec::with_capacity(23);
        Reply::RawSensorBits {
            mag: [w(0), w(1), w(2)],
            accel: [w(3), w(4), 32_768 + 4681],
            rate: [w(6), w(7), w(8)],
            ticks,
        }
        .encode(&mut bytes);
        (host_s, bytes)
    }
}

const GAINS: Gains = Gains {
    accel: 8500,
    gyro: 10_000,
    mag: 2000,
    fallback: GainFallback::NONE,
};

/// A continuous stream's device: the default configuration, on `TICK_S` ticks.
fn device() -> DeviceConfig {
    DeviceConfig {
        tick_period_s: TICK_S,
        ..DeviceConfig::default()
    }
}

fn pipeline() -> Pipeline {
    Pipeline::new(gx1::session(&device(), GAINS), None)
}

fn driver() -> Gx1Driver {
    Gx1Driver::with_session(&device(), GAINS)
}

/// Pushes `bytes` that arrived at `host_s` and returns the stamps of the samples they completed.
fn deliver(
    p: &mut Pipeline,
    decoder: &mut Gx1Driver,
    bytes: &[u8],
    host_s: f64,
    stamps: &mut Vec<u64>,
) {
    decoder.handle_input(bytes, std::time::Instant::now());
    let t_ns = (host_s * 1e9) as u64;
    let wall_ns = t_ns + 1_700_000_000_000_000_000;
    let before = p.counters().samples;
    let mut sinks = Sinks::default();
    let mut slot = FrameSlot::default();
    while let Some(ev) = decoder.poll_event(&mut slot) {
        match ev {
            DriverEvent::Frame => p.on_frame(&mut slot, t_ns, wall_ns, &mut sinks),
            DriverEvent::Rejected {
                bytes,
                offset,
                reason,
            } => log_rejected(bytes, offset, reason, t_ns, wall_ns, &sinks),
            other => panic!("a session-set driver made {other:?}"),
        }
    }
    if p.counters().samples > before {
        // The stamp of the last sample is what the clock gave it.
        stamps.push(p.last_stamp_ns().expect("a sample was stamped"));
    }
}

/// `n` samples of an uncorrupted link, each arriving `late_s` plus up to `jitter_s` after it was
/// sent (bytes still in order): the pipeline after them and the samples' stamps.
fn clean_run(link: &mut Link, n: u64, late_s: f64, jitter_s: f64) -> (Pipeline, Vec<u64>) {
    let mut p = pipeline();
    let mut decoder = driver();
    let mut stamps = Vec::new();
    let mut arrival_s = 0.0f64;
    for k in 0..n {
        let (t_s, bytes) = link.sample(k);
        arrival_s = arrival_s.max(t_s + late_s + jitter_s * link.rng.unit());
        deliver(&mut p, &mut decoder, &bytes, arrival_s, &mut stamps);
    }
    (p, stamps)
}

#[test]
fn ten_clean_minutes_with_20_ms_of_host_jitter_lose_nothing() {
    let mut link = Link {
        drift_ppm: 80.0,
        rng: Lcg(1),
        period_s: 0.01,
    };
    let n = 60_000;
    // Late by 1 ms plus up to 20 ms.
    let (p, stamps) = clean_run(&mut link, n, 0.001, 0.02);
    assert_eq!(p.counters().samples, n);
    assert_eq!(p.counters().samples_lost, 0);
    assert!(stamps.windows(2).all(|w| w[1] > w[0]), "stamps repeat");
    let drift = p.clock().drift_ppm().unwrap();
    assert!((drift - 80.0).abs() < 20.0, "drift {drift} ppm");
    // Spacing is the device's 10 ms (at the fitted rate), not the host's jitter.
    let spacing_s: Vec<f64> = stamps[10_000..]
        .windows(2)
        .map(|w| (w[1] - w[0]) as f64 * 1e-9)
        .collect();
    let worst = spacing_s
        .iter()
        .map(|d| (d - 0.01).abs())
        .fold(0.0, f64::max);
    assert!(
        worst < 0.01 * imud::clock::MAX_SLEW * 1.1,
        "spacing off by {worst}"
    );
}

/// Several samples a tick (200 Hz to 1 kHz on 6.5536 ms ticks): a clean link with host jitter
/// loses nothing (the tracker counted 6 to 516 phantom losses in 30 000 samples there before),
/// and the stamps keep the device's spacing.
#[test]
fn clean_links_above_one_sample_a_tick_lose_nothing() {
    for (rate_hz, seed) in [(200.0, 4), (333.0, 5), (500.0, 6), (1000.0, 7)] {
        let period_s = 1.0 / rate_hz;
        let mut link = Link {
            drift_ppm: 60.0,
            rng: Lcg(seed),
            period_s,
        };
        let n = 30_000;
        let (p, stamps) = clean_run(&mut link, n, 0.0005, 0.003);
        assert_eq!(p.counters().samples, n, "{rate_hz} Hz");
        assert_eq!(p.counters().samples_lost, 0, "{rate_hz} Hz");
        assert!(stamps.windows(2).all(|w| w[1] > w[0]), "stamps repeat");
        let spacing_s =
            (stamps[n as usize - 1] - stamps[n as usize / 2]) as f64 * 1e-9 / (n / 2 - 1) as f64;
        assert!(
            (spacing_s / period_s - 1.0).abs() < 1e-3,
            "{rate_hz} Hz: mean spacing {spacing_s} s"
        );
    }
}

#[test]
fn three_percent_byte_corruption_and_bursts_count_the_lost_frames() {
    let mut link = Link {
        drift_ppm: -40.0,
        rng: Lcg(2),
        period_s: 0.01,
    };
    let mut p = pipeline();
    let mut decoder = driver();
    let mut stamps = Vec::new();
    let n = 20_000u64;
    let mut corrupted_frames = 0u64;
    for k in 0..n {
        let (t_s, mut bytes) = link.sample(k);
        // 3 % of the bytes, plus a burst that wipes 40 frames every 2000.
        let burst = k % 2000 >= 1000 && k % 2000 < 1040;
        let mut hit = false;
        for b in &mut bytes {
            if burst || link.rng.unit() < 0.03 {
                *b ^= 1 + (link.rng.unit() * 254.0) as u8;
                hit = true;
            }
        }
        corrupted_frames += u64::from(hit);
        deliver(&mut p, &mut decoder, &bytes, t_s + 0.002, &mut stamps);
    }
    let c = p.counters();
    // What was really lost: frames sent minus samples that came out (a corrupted frame is
    // never accepted: the checksum sees any single changed byte).
    let lost = n - c.samples;
    assert!(lost > n / 3, "the link should lose about half: {lost}");
    assert!(lost.abs_diff(corrupted_frames) <= corrupted_frames / 1000 + 2);
    let error = c.samples_lost.abs_diff(lost) as f64 / lost as f64;
    eprintln!(
        "lost {lost}, counted {}, corrupted frames {corrupted_frames}",
        c.samples_lost
    );
    assert!(
        error <= 0.01,
        "samples_lost {} vs {lost} lost ({:.2} %)",
        c.samples_lost,
        error * 100.0
    );
    assert!(stamps.windows(2).all(|w| w[1] > w[0]), "stamps repeat");
}

#[test]
fn stamps_and_drift_are_not_bent_by_one_second_stalls() {
    let link = Link {
        drift_ppm: 150.0,
        rng: Lcg(3),
        period_s: 0.01,
    };
    let mut p = pipeline();
    let mut decoder = driver();
    let mut stamps = Vec::new();
    let mut truth_s = Vec::new();
    let mut stall_until = 0.0f64;
    for k in 0..30_000u64 {
        let (t_s, bytes) = link.sample(k);
        // The host stalls for a second every 20 s, then reads the backlog at once.
        if k % 2000 == 1000 {
            stall_until = t_s + 1.0;
        }
        let before = stamps.len();
        deliver(
            &mut p,
            &mut decoder,
            &bytes,
            (t_s + 0.002).max(stall_until),
            &mut stamps,
        );
        if stamps.len() > before {
            truth_s.push(t_s);
        }
    }
    assert_eq!(p.counters().samples_lost, 0);
    assert!(stamps.windows(2).all(|w| w[1] > w[0]), "stamps repeat");
    let drift = p.clock().drift_ppm().unwrap();
    assert!((drift - 150.0).abs() < 100.0, "drift {drift} ppm");
    // After the first minute every stamp, including those read after a stall, is within 1 ms
    // of the true sample time plus the 2 ms least latency.
    for (s, t) in stamps.iter().zip(&truth_s).skip(6000) {
        let error_s = *s as f64 * 1e-9 - t - 0.002;
        assert!(error_s.abs() < 1e-3, "stamp off by {error_s} s");
    }
    assert!(p.clock().residual_s().unwrap() < 1e-3);
}
