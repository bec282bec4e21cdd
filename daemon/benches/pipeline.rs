//! Per-frame cost of imud's data path: decode + calibrate + publish (iceoryx2) + log enqueue
//! (MCAP writer thread), on pre-encoded 3DM-GX1 raw-bits frames, on MIP IMU packets (the
//! fields imud configures: scaled accel, gyro, mag, temperature, reference time), on Xsens
//! MTData2 messages (the outputs imud configures: counter, SampleTimeFine, UTC time,
//! temperature, HR and compensated acceleration and rate of turn, magnetic field) and on
//! VectorNav binary messages (startup time, uncompensated and compensated accel, gyro, mag,
//! temperature). Prints the
//! median and tail of the per-frame time over batches, for each stage combination and protocol.
//! Run: `cargo bench -p imud --bench pipeline`.

use std::collections::BTreeMap;
use std::time::Instant;

use imu_bus::recording::{Recorder, RecordingConfig};
use imu_bus::shm::{Publishers, ShmOptions};
use imu_model::Calibration;
use imu_proto::DeviceProtocol;
use imu_proto::mip::{ImuData, TemperatureStats};
use imu_proto::reply::Reply;
use imu_proto::xsens::{Format, MtData2, UtcTime};
use imud::config::DeviceConfig;
use imud::drivers::gx1::{self, Gx1Driver};
use imud::drivers::mip::{self, MipDriver, MipTimebase};
use imud::drivers::vectornav::{self, VnDriver};
use imud::drivers::xsens::{self, XsensDriver};
use imud::drivers::{Driver, DriverEvent, FrameSlot};
use imud::pipeline::{
    Acquisition, ActiveCalibration, GainFallback, Gains, Pipeline, SessionSpec, Sinks, log_rejected,
};

const BATCH: usize = 1000;
const BATCHES: usize = 1000;

/// One batch of encoded frames of `protocol` (each frame its own slice) and the host spacing.
fn frames(protocol: DeviceProtocol) -> (Vec<Vec<u8>>, u64) {
    let w = |i: usize, k: usize| ((i * 7 + k * 13) % 200) as u16;
    match protocol {
        DeviceProtocol::Gx1 => {
            let frames = (0..BATCH)
                .map(|i| {
                    let c = |k| 32_768u16.wrapping_add(w(i, k));
                    let mut bytes = Vec::with_capacity(23);
                    Reply::RawSensorBits {
                        mag: [c(0), c(1), c(2)],
                        accel: [c(3), c(4), 32_768 + 4_681],
                        rate: [c(6), c(7), c(8)],
                        ticks: (i * 2) as u16,
                    }
                    .encode(&mut bytes);
                    bytes
                })
                .collect();
            (frames, 10_000_000)
        }
        DeviceProtocol::Mip => {
            let frames = (0..BATCH)
                .map(|i| {
                    let f = |k| f32::from(w(i, k)) * 1e-4;
                    ImuData {
                        accel_g: Some([f(0), f(1), -1.0 + f(2)]),
                        gyro_rad_s: Some([f(3), f(4), f(5)]),
                        mag_gauss: Some([0.2 + f(6), f(7), 0.4]),
                        temperature: Some(TemperatureStats {
                            min_c: 24.0,
                            max_c: 25.0,
                            mean_c: 24.5,
                        }),
                        reference_time_ns: Some(1_000_000 * i as u64),
                        ..ImuData::default()
                    }
                    .to_packet()
                    .as_bytes()
                    .to_vec()
                })
                .collect();
            (frames, 1_000_000)
        }
        DeviceProtocol::Xsens => {
            let frames = (0..BATCH)
                .map(|i| {
                    let f = |k| f64::from(w(i, k)) * 1e-3;
                    let accel = [f(0), f(1), -9.8 + f(2)];
                    let gyro = [f(3), f(4), f(5)];
                    MtData2 {
                        packet_counter: Some(i as u16),
                        // 10 kHz: 10 counts a frame at 1 kHz.
                        sample_time_fine: Some(10 * i as u32),
                        utc: Some(UtcTime {
                            ns: 1_000_000 * i as u32,
                            year: 2026,
                            month: 1,
                            day: 1,
                            flags: imu_proto::xsens::data::UTC_VALID,
                            ..UtcTime::default()
                        }),
                        temperature_c: Some(24.5),
                        acceleration_hr_m_s2: Some(accel),
                        rate_of_turn_hr_rad_s: Some(gyro),
                        acceleration_m_s2: Some(accel),
                        rate_of_turn_rad_s: Some(gyro),
                        magnetic_field_normalised: Some([0.2 + f(6), f(7), 0.4]),
                        ..MtData2::default()
                    }
                    .to_message(Format::Float32)
                    .as_bytes()
                    .to_vec()
                })
                .collect();
            (frames, 1_000_000)
        }
        DeviceProtocol::Vectornav => {
            let frames = (0..BATCH)
                .map(|i| vectornav_message(i as u64 * 1_250_000, |k| f32::from(w(i, k)) * 1e-4))
                .collect();
            (frames, 1_250_000)
        }
    }
}

/// The binary message imud configures, at startup time `t_ns`, values from `f`.
fn vectornav_message(t_ns: u64, f: impl Fn(usize) -> f32) -> Vec<u8> {
    use imu_proto::vectornav::{BinaryData, BinaryMessage};
    let data = BinaryData {
        startup_ns: Some(t_ns),
        uncomp_accel_m_s2: Some([f(0), f(1), -9.8 + f(2)]),
        uncomp_gyro_rad_s: Some([f(3), f(4), f(5)]),
        uncomp_mag_gauss: Some([0.2 + f(6), f(7), 0.4]),
        temp_c: Some(24.5),
        accel_m_s2: Some([f(1), f(0), -9.8]),
        angular_rate_rad_s: Some([f(4), f(3), f(5)]),
        mag_gauss: Some([0.2, f(6), 0.4]),
        ..BinaryData::default()
    };
    BinaryMessage::encode(vectornav::startup::preferred_fields(false), &data)
        .expect("the preferred fields are filled")
        .as_bytes()
        .to_vec()
}

fn run(protocol: DeviceProtocol, label: &str, sinks: &mut Sinks, calibrated: bool, health: bool) {
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
    // The daemon's own drivers, as the session feeds them.
    let cfg = DeviceConfig::default();
    let (mut driver, session): (Box<dyn Driver>, SessionSpec) = match protocol {
        // The GX1 batches repeat their ticks, so they run without loss accounting (as polls),
        // as in every earlier run of this benchmark.
        DeviceProtocol::Gx1 => (
            Box::new(Gx1Driver::with_session(&cfg, gains)),
            SessionSpec {
                acquisition: Acquisition::Polled { rate_hz: 100.0 },
                ..gx1::session(&cfg, gains)
            },
        ),
        // Loss accounting on, as when streaming.
        DeviceProtocol::Mip => (
            Box::new(MipDriver::with_session(&cfg, MipTimebase::ReferenceTime)),
            mip::session(MipTimebase::ReferenceTime),
        ),
        DeviceProtocol::Xsens => (Box::new(XsensDriver::with_session(&cfg)), xsens::session()),
        DeviceProtocol::Vectornav => (Box::new(VnDriver::with_session(&cfg)), vectornav::session()),
    };
    let mut pipeline = Pipeline::new(session, cal);
    // The daemon watches its calibration's health by default (imud::health).
    pipeline.set_health(health.then(imud::config::HealthConfig::default));
    let (stream, spacing_ns) = frames(protocol);
    let mut per_frame_ns = Vec::with_capacity(BATCHES);
    let now = Instant::now();
    // The caller's frame slot, as the session keeps one for its reads.
    let mut slot = FrameSlot::default();
    for b in 0..BATCHES {
        // MIP stamps run on: the batch's packets shifted by the batch's time.
        let batch = match protocol {
            DeviceProtocol::Gx1 => stream.clone(),
            DeviceProtocol::Mip => shifted_mip(&stream, (b * BATCH) as u64 * spacing_ns),
            DeviceProtocol::Xsens => shifted_xsens(&stream, (b * BATCH) as u64 * spacing_ns),
            DeviceProtocol::Vectornav => {
                shifted_vectornav(&stream, (b * BATCH) as u64 * spacing_ns)
            }
        };
        let start = Instant::now();
        for (k, frame) in batch.iter().enumerate() {
            let t = (b * BATCH + k) as u64 * spacing_ns;
            driver.handle_input(frame, now);
            while let Some(ev) = driver.poll_event(&mut slot) {
                match ev {
                    DriverEvent::Frame => pipeline.on_frame(&mut slot, t, t, sinks),
                    DriverEvent::Rejected {
                        bytes,
                        offset,
                        reason,
                    } => log_rejected(bytes, offset, reason, t, t, sinks),
                    _ => {}
                }
            }
        }
        per_frame_ns.push(start.elapsed().as_nanos() as f64 / BATCH as f64);
        // Let the writer thread drain between batches (untimed): the daemon runs at hundreds of
        // Hz, so the enqueue cost that matters is the one with a queue that keeps up, and a full
        // queue would only measure the (cheaper) drop path.
        if let Some(r) = &sinks.recorder {
            // One record per frame: the sample with its frame (and a MIP temperature a second,
            // with its frame on its own).
            let expected = ((b + 1) * BATCH) as u64;
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

/// The MIP packets with their reference time moved on by `offset_ns` (re-encoded, untimed).
fn shifted_mip(stream: &[Vec<u8>], offset_ns: u64) -> Vec<Vec<u8>> {
    stream
        .iter()
        .map(|bytes| {
            let packet = imu_proto::mip::Packet::parse(bytes).expect("packet");
            let mut data = ImuData::decode_packet(&packet).expect("data");
            data.reference_time_ns = data.reference_time_ns.map(|t| t + offset_ns);
            data.to_packet().as_bytes().to_vec()
        })
        .collect()
}

/// The Xsens messages with their SampleTimeFine moved on by `offset_ns` (re-encoded,
/// untimed; the u32 wraps as the unit's does).
fn shifted_xsens(stream: &[Vec<u8>], offset_ns: u64) -> Vec<Vec<u8>> {
    let offset_ticks = (offset_ns / 100_000) as u32;
    stream
        .iter()
        .map(|bytes| {
            let msg = imu_proto::xsens::Message::parse(bytes).expect("message");
            let mut data = MtData2::decode(&msg).expect("data");
            data.sample_time_fine = data.sample_time_fine.map(|t| t.wrapping_add(offset_ticks));
            data.to_message(Format::Float32).as_bytes().to_vec()
        })
        .collect()
}

/// The VectorNav messages with their startup time moved on by `offset_ns` (re-encoded,
/// untimed).
fn shifted_vectornav(stream: &[Vec<u8>], offset_ns: u64) -> Vec<Vec<u8>> {
    stream
        .iter()
        .map(|bytes| {
            let m = imu_proto::vectornav::BinaryMessage::parse(bytes).expect("message");
            let mut data = m.data().clone();
            data.startup_ns = data.startup_ns.map(|t| t + offset_ns);
            imu_proto::vectornav::BinaryMessage::encode(m.fields(), &data)
                .expect("same fields")
                .as_bytes()
                .to_vec()
        })
        .collect()
}

fn main() {
    let protocol = match std::env::args()
        .skip(1)
        .find(|a| a == "mip" || a == "3dm-gx1" || a == "xsens" || a == "vectornav")
    {
        Some(p) => p.parse().expect("protocol"),
        None => {
            for p in DeviceProtocol::ALL {
                bench(p);
            }
            return;
        }
    };
    bench(protocol);
}

fn bench(protocol: DeviceProtocol) {
    let dir = tempfile::tempdir().expect("temp dir");
    let name = format!("bench-{}-{protocol}", std::process::id());
    let (stream, spacing_ns) = frames(protocol);
    println!(
        "imud per-frame path, {protocol}: {BATCH}-frame batches x {BATCHES} ({} bytes a frame, \
         {:.0} Hz)",
        stream[0].len(),
        1e9 / spacing_ns as f64
    );
    let run = |label, sinks: &mut Sinks, calibrated, health| {
        run(protocol, label, sinks, calibrated, health)
    };
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
        readers: None,
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
            ..RecordingConfig::default()
        },
        vec![("bench".into(), BTreeMap::new())],
    )
    .expect("recorder");
    let mut all = Sinks {
        publishers: with_pub.publishers,
        readers: None,
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
