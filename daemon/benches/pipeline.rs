//! Per-frame cost of imud's data path: decode + calibrate + publish (iceoryx2) + log enqueue
//! (MCAP writer thread), on pre-encoded 3DM-GX1 raw-bits frames. Prints the median and tail of
//! the per-frame time over batches, for each stage combination. Run: `cargo bench -p imud`.

use std::collections::BTreeMap;
use std::time::Instant;

use imu_bus::recording::{Recorder, RecordingConfig};
use imu_bus::shm::{Publishers, ShmOptions};
use imu_model::Calibration;
use imu_proto::decoder::ReplyDecoder;
use imu_proto::reply::Reply;
use imud::pipeline::{ActiveCalibration, GainFallback, Gains, Pipeline, Sinks};

const BATCH: usize = 1000;
const BATCHES: usize = 1000;

fn frames() -> Vec<u8> {
    let mut bytes = Vec::with_capacity(BATCH * 23);
    for i in 0..BATCH {
        let w = |k: usize| 32_768u16.wrapping_add(((i * 7 + k * 13) % 200) as u16);
        Reply::RawSensorBits {
            mag: [w(0), w(1), w(2)],
            accel: [w(3), w(4), 32_768 + 4_681],
            rate: [w(6), w(7), w(8)],
            ticks: (i * 2) as u16,
        }
        .encode(&mut bytes);
    }
    bytes
}

fn run(label: &str, sinks: &mut Sinks, calibrated: bool, health: bool) {
    let model = Calibration::load(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../config/models/example-3dm-gx1.toml"
    )))
    .expect("example model");
    let cal = calibrated.then(|| std::sync::Arc::new(ActiveCalibration::new(model)));
    let gains = Gains {
        accel: 7000,
        gyro: 10000,
        mag: 2000,
        fallback: GainFallback::NONE,
    };
    let mut pipeline = Pipeline::new(gains, 6.5536e-3, cal);
    // The daemon watches its calibration's health by default (imud::health).
    pipeline.set_health(health.then(imud::config::HealthConfig::default));
    let mut decoder = ReplyDecoder::new();
    let stream = frames();
    let mut per_frame_ns = Vec::with_capacity(BATCHES);
    for b in 0..BATCHES {
        let start = Instant::now();
        for (k, frame) in stream.chunks_exact(23).enumerate() {
            decoder.push(frame);
            let t = (b * BATCH + k) as u64 * 10_000_000;
            while let Some(ev) = decoder.next_event() {
                pipeline.on_event(ev, t, t, sinks);
            }
        }
        per_frame_ns.push(start.elapsed().as_nanos() as f64 / BATCH as f64);
        // Let the writer thread drain between batches (untimed): the daemon runs at hundreds of
        // Hz, so the enqueue cost that matters is the one with a queue that keeps up, and a full
        // queue would only measure the (cheaper) drop path.
        if let Some(r) = &sinks.recorder {
            let expected = 3 * ((b + 1) * BATCH) as u64;
            let waited = Instant::now();
            while waited.elapsed().as_secs() < 5 {
                let s = r.stats();
                if s.written + s.dropped_queue_full + s.dropped_not_logging >= expected {
                    break;
                }
                std::thread::sleep(std::time::Duration::from_micros(200));
            }
        }
    }
    per_frame_ns.sort_by(f64::total_cmp);
    let q = |p: f64| per_frame_ns[((per_frame_ns.len() - 1) as f64 * p) as usize];
    let drops = sinks.recorder.as_ref().map_or(0, |r| {
        let s = r.stats();
        s.dropped_queue_full + s.dropped_not_logging
    });
    println!(
        "{label:<48} median {:>7.0} ns/frame   p90 {:>7.0}   p99 {:>7.0}   ({} frames, {} log drops)",
        q(0.5),
        q(0.9),
        q(0.99),
        BATCH * BATCHES,
        drops
    );
    assert_eq!(pipeline.counters().samples as usize, BATCH * BATCHES);
}

fn main() {
    let dir = tempfile::tempdir().expect("temp dir");
    let name = format!("bench-{}", std::process::id());
    println!("imud per-frame path, {BATCH}-frame batches x {BATCHES} (raw-bits frames, 23 bytes)");
    run(
        "decode only (uncalibrated, no sinks)",
        &mut Sinks::default(),
        false,
        false,
    );
    run(
        "decode + calibrate (no sinks)",
        &mut Sinks::default(),
        true,
        false,
    );
    run(
        "decode + calibrate + health (no sinks)",
        &mut Sinks::default(),
        true,
        true,
    );
    let publishers = Publishers::open(&name, &ShmOptions::default()).expect("shared memory");
    let mut with_pub = Sinks {
        publishers: Some(publishers),
        recorder: None,
        ros2: None,
    };
    run(
        "decode + calibrate + health + publish",
        &mut with_pub,
        true,
        true,
    );
    let recorder = Recorder::start(
        RecordingConfig {
            dir: dir.path().to_path_buf(),
            prefix: "bench".into(),
            queue_capacity: 1 << 20,
            ..RecordingConfig::default()
        },
        vec![("bench".into(), BTreeMap::new())],
    )
    .expect("recorder");
    let mut all = Sinks {
        publishers: with_pub.publishers,
        recorder: Some(recorder),
        ros2: None,
    };
    run(
        "decode + calibrate + health + publish + log enqueue",
        &mut all,
        true,
        true,
    );
    if let Some(r) = all.recorder {
        let _ = r.finish();
    }
}
