//! The `imu-sim` binary speaking MIP on a real pseudo-terminal (`--protocol mip`), driven
//! through a real serial handle with the host side of the shared MIP codec, checked against the
//! truth file: the start-up a host does, then a 1 kHz real-time stream with no packet lost.

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Child, Command as Process, Stdio};
use std::time::Duration;

use imu_proto::mip::data::{INTERNAL_TICK_HZ, field};
use imu_proto::mip::{
    AckCode, DescriptorRate, ImuData, MessageFormat, MipCommand, MipDecoder, MipEvent, MipReply,
    Packet, Response, Setting,
};
use imu_rec::truth::read_truth;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio_serial::{SerialPortBuilderExt, SerialStream};

const G0: f64 = 9.80665;
const RATE_HZ: f64 = 1000.0;
const DRIFT_PPM: f64 = 80.0;

/// Still, a rotation about z and still again, at 1 kHz; the protocol comes from the command
/// line, as it would for any existing scenario.
const SCENARIO: &str = r#"
name = "mip-test"
rate-hz = 1000.0
latitude-deg = 40.0
power-on-before-s = 12.0
[device]
serial-number = 4242
firmware = 1141
clock-drift-ppm = 80.0
[temperature]
kind = "warmup"
ambient-c = 22.0
operating-c = 38.0
tau-s = 30.0
[[segment]]
kind = "static"
orientation = { x = "north", z = "up" }
duration-s = 1.0
[[segment]]
kind = "rotate"
axis = "z"
angle-deg = 90.0
duration-s = 1.0
[[segment]]
kind = "static"
duration-s = 1.0
"#;

/// A visible effect on every triad and white noise.
const TRUTH: &str = r#"
format = "imud-calibration/1"
[accel.bias]
value = [0.15, -0.2, 0.1]
[accel.noise]
white-density = [0.002, 0.002, 0.002]
[gyro.bias]
value = [0.01, -0.005, 0.008]
[gyro.noise]
white-density = [0.001, 0.001, 0.001]
"#;

struct Sim {
    child: Child,
    device: PathBuf,
    truth_out: PathBuf,
    _dir: tempfile::TempDir,
}

impl Drop for Sim {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn start_sim() -> Sim {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("scenario.toml");
    let truth = dir.path().join("truth-model.toml");
    let truth_out = dir.path().join("truth.mcap");
    std::fs::write(&scenario, SCENARIO).unwrap();
    std::fs::write(&truth, TRUTH).unwrap();
    let mut child = Process::new(env!("CARGO_BIN_EXE_imu-sim"))
        .arg("--scenario")
        .arg(&scenario)
        .arg("--truth")
        .arg(&truth)
        .arg("--truth-out")
        .arg(&truth_out)
        .args(["--protocol", "mip", "--seed", "5", "--linger-s", "2"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.as_mut().unwrap())
        .read_line(&mut line)
        .unwrap();
    let device = PathBuf::from(line.trim());
    assert!(
        device.exists(),
        "first stdout line is the device path: {line:?}"
    );
    Sim {
        child,
        device,
        truth_out,
        _dir: dir,
    }
}

/// The host's side of the link: the port, the decoder and the data packets seen so far.
struct Host {
    port: SerialStream,
    decoder: MipDecoder,
    data: Vec<ImuData>,
}

impl Host {
    /// Reads once and sorts what arrived: data packets are kept, replies returned. `None`
    /// once the device has gone (the simulator exits when its scenario is over).
    async fn read_some(&mut self) -> Option<Vec<MipReply>> {
        let mut buf = [0u8; 8192];
        let n = self.port.read(&mut buf).await.unwrap_or(0);
        if n == 0 {
            return None;
        }
        self.decoder.push(&buf[..n]);
        let mut replies = Vec::new();
        while let Some(ev) = self.decoder.next_event() {
            match ev {
                MipEvent::Packet { packet, .. } => self.sort(&packet, &mut replies),
                MipEvent::Rejected { bytes, reason, .. } => {
                    panic!("clean link produced rejected bytes {bytes:02X?} ({reason:?})")
                }
            }
        }
        Some(replies)
    }

    fn sort(&mut self, packet: &Packet, replies: &mut Vec<MipReply>) {
        match ImuData::decode_packet(packet) {
            Ok(d) => self.data.push(d),
            Err(_) => replies.extend(MipReply::decode_packet(packet).unwrap()),
        }
    }

    /// Sends `cmd` and waits for its ack (data packets meanwhile are kept).
    async fn ask(&mut self, cmd: &MipCommand) -> MipReply {
        self.port
            .write_all(cmd.to_packet().as_bytes())
            .await
            .unwrap();
        let (set, descriptor) = cmd.descriptor();
        tokio::time::timeout(Duration::from_secs(10), async {
            loop {
                for r in self.read_some().await.expect("device closed early") {
                    if (r.descriptor_set, r.command) == (set, descriptor) {
                        return r;
                    }
                }
            }
        })
        .await
        .unwrap_or_else(|_| panic!("no reply to {cmd:?}"))
    }
}

/// What imud's start-up does: idle, identify, read the base rate, set and read back the
/// message format, enable the stream, resume.
async fn start_up(host: &mut Host, format: &MessageFormat) {
    assert_eq!(host.ask(&MipCommand::SetToIdle).await.code, AckCode::Ok);
    let info = host.ask(&MipCommand::GetDeviceInfo).await;
    let Some(Response::DeviceInfo(info)) = info.response else {
        panic!("device info missing: {info:?}")
    };
    assert_eq!(
        (info.serial_number.as_str(), info.firmware_version),
        ("4242", 1141)
    );
    let base = host.ask(&MipCommand::GetImuBaseRate).await.response;
    assert_eq!(base, Some(Response::ImuBaseRate { rate_hz: 1000 }));
    let write = MipCommand::ImuMessageFormat(Setting::Write(format.clone()));
    assert_eq!(host.ask(&write).await.code, AckCode::Ok);
    let read = host.ask(&MipCommand::ImuMessageFormat(Setting::Read)).await;
    assert_eq!(
        read.response,
        Some(Response::ImuMessageFormat(format.clone()))
    );
    let enable = MipCommand::DataStream {
        descriptor_set: 0x80,
        setting: Setting::Write(true),
    };
    assert_eq!(host.ask(&enable).await.code, AckCode::Ok);
    assert!(host.data.is_empty(), "idle until resumed");
    assert_eq!(host.ask(&MipCommand::Resume).await.code, AckCode::Ok);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn mip_start_up_then_1khz_real_time_stream_matches_the_truth() {
    let mut sim = start_sim();
    let port = tokio_serial::new(sim.device.to_string_lossy(), 921_600)
        .open_native_async()
        .expect("the simulator's device opens like a serial port");
    let mut host = Host {
        port,
        decoder: MipDecoder::new(),
        data: Vec::new(),
    };
    let format = MessageFormat {
        fields: [
            field::SCALED_ACCEL,
            field::SCALED_GYRO,
            field::SCALED_MAG,
            field::DELTA_THETA,
            field::INTERNAL_TIMESTAMP,
            field::REFERENCE_TIME,
        ]
        .map(|descriptor| DescriptorRate {
            descriptor,
            decimation: 1,
        })
        .to_vec(),
    };
    start_up(&mut host, &format).await;
    // The scenario lasts 3 s: read until the device goes away (or is quiet for 5 s).
    while let Ok(Some(replies)) =
        tokio::time::timeout(Duration::from_secs(5), host.read_some()).await
    {
        assert!(replies.is_empty(), "unasked replies {replies:?}");
    }
    let status = sim.child.wait().unwrap();
    assert!(status.success(), "imu-sim failed");
    let s = host.decoder.stats();
    assert_eq!((s.rejected_bytes, s.resyncs), (0, 0));
    check_against_truth(&host.data, &sim);
}

/// Every data packet is one truth record, in order, with the measured values to f32 rounding;
/// the device clock advances one sample period per packet, so none was lost.
fn check_against_truth(data: &[ImuData], sim: &Sim) {
    let truth = read_truth(&sim.truth_out).unwrap();
    assert_eq!(truth.run.get("protocol").map(String::as_str), Some("mip"));
    let samples: Vec<_> = truth.samples.iter().filter(|t| t.command == 0x80).collect();
    assert_eq!(samples.len(), truth.samples.len(), "data records only");
    assert_eq!(data.len(), samples.len(), "one truth record per packet");
    // 3 s at 1 kHz, the first sample one period after the resume.
    assert!(
        (2990..=3000).contains(&data.len()),
        "{} packets",
        data.len()
    );
    let close = |got: [f32; 3], want: [f64; 3], scale: f64| {
        got.iter().zip(want).all(|(g, w)| {
            let w = w * scale;
            (f64::from(*g) - w).abs() <= 1.2e-7 * w.abs().max(1e-3)
        })
    };
    let period_s = 1.0 / (RATE_HZ * (1.0 + DRIFT_PPM * 1e-6));
    let mut last_ns = None;
    for (k, (d, t)) in data.iter().zip(&samples).enumerate() {
        assert_eq!(t.seq, k as u64);
        assert!(
            close(d.accel_g.unwrap(), t.measured_accel_m_s2, 1.0 / G0),
            "accel {k}"
        );
        assert!(
            close(d.gyro_rad_s.unwrap(), t.measured_gyro_rad_s, 1.0),
            "gyro {k}"
        );
        assert!(
            close(d.mag_gauss.unwrap(), t.measured_mag_gauss, 1.0),
            "mag {k}"
        );
        assert!(
            close(d.delta_theta_rad.unwrap(), t.measured_gyro_rad_s, period_s),
            "dtheta {k}"
        );
        assert_eq!(u64::from(d.internal_ticks.unwrap()), t.ticks_unwrapped);
        // The device clock: time since power-on on the drifting oscillator.
        let ns = d.reference_time_ns.unwrap();
        let device_s = (t.t_s + 12.0) * (1.0 + DRIFT_PPM * 1e-6);
        assert!(
            (ns as f64 * 1e-9 - device_s).abs() < 1e-8,
            "reference time {k}"
        );
        assert!(
            (t.ticks_unwrapped as f64 / INTERNAL_TICK_HZ - device_s).abs()
                <= 1.0 / INTERNAL_TICK_HZ
        );
        // No packet lost: consecutive device times are one nominal period apart.
        if let Some(last) = last_ns {
            let step_s = (ns - last) as f64 * 1e-9;
            assert!(
                (step_s - 1.0 / RATE_HZ).abs() < 1e-6,
                "gap at {k}: {step_s} s"
            );
        }
        last_ns = Some(ns);
    }
    // The rotation segment turns 90 degrees about z: the delta thetas add up to it (plus the
    // gyro bias and Earth's rate over one second, and white noise).
    let turned: f64 = data
        .iter()
        .zip(&samples)
        .filter(|(_, t)| t.segment == 1)
        .map(|(d, _)| f64::from(d.delta_theta_rad.unwrap()[2]))
        .sum();
    assert!(
        (turned.abs() - 90f64.to_radians()).abs() < 0.02,
        "turned {turned} rad"
    );
}

/// Line noise over MIP: garbage injected between packets (some of it looking like a packet
/// start) is rejected byte for byte, and no data packet is lost.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn injected_garbage_is_rejected_and_no_packet_is_lost() {
    let dir = tempfile::tempdir().unwrap();
    let scenario_path = dir.path().join("scenario.toml");
    std::fs::write(
        &scenario_path,
        SCENARIO.replace("rate-hz = 1000.0", "rate-hz = 500.0"),
    )
    .unwrap();
    let mut opts = imu_sim::SimOptions::from_files(&scenario_path, None).unwrap();
    opts.scenario
        .set_protocol(imu_proto::DeviceProtocol::Mip, "scenario.toml")
        .unwrap();
    opts.truth_out = Some(dir.path().join("truth.mcap"));
    // Real time: with fast pacing the device can run a pty buffer's worth (hundreds of
    // packets) ahead of this reader and finish before most of the noise is asked for, which
    // left too little noise on the line in a loaded run.
    opts.pacing = imu_sim::Pacing::RealTime;
    opts.linger = Duration::from_secs(2);
    let sim = imu_sim::spawn(opts).unwrap();
    let port = tokio_serial::new(sim.device_path().to_string_lossy(), 921_600)
        .open_native_async()
        .unwrap();
    let mut host = Host {
        port,
        decoder: MipDecoder::new(),
        data: Vec::new(),
    };
    assert_eq!(host.ask(&MipCommand::Resume).await.code, AckCode::Ok);
    let noise: [&[u8]; 3] = [
        &[0x00, 0x75, 0x65, 0x80, 0x10, 0xAA, 0x75],
        &[0x75, 0x65, 0x01, 0x02, 0x02, 0x01, 0x00, 0x00],
        &[0xFF; 40],
    ];
    let mut injected = 0;
    let mut next = 0;
    let mut rejected = 0;
    while let Ok(Some(_)) = tokio::time::timeout(Duration::from_secs(5), async {
        let mut buf = [0u8; 4096];
        let n = host.port.read(&mut buf).await.unwrap_or(0);
        host.decoder.push(&buf[..n]);
        (n > 0).then_some(n)
    })
    .await
    {
        while let Some(ev) = host.decoder.next_event() {
            match ev {
                MipEvent::Packet { packet, .. } => {
                    host.data.push(ImuData::decode_packet(&packet).unwrap());
                }
                MipEvent::Rejected { bytes, .. } => rejected += bytes.len(),
            }
        }
        // Every 100 packets, more noise.
        if host.data.len() >= 100 * (next + 1) && next < 30 {
            let bytes = noise[next % noise.len()];
            sim.inject(bytes);
            injected += bytes.len();
            next += 1;
        }
    }
    host.decoder.flush();
    while let Some(ev) = host.decoder.next_event() {
        assert!(matches!(ev, MipEvent::Rejected { .. }), "{ev:?}");
        rejected += ev.bytes().len();
    }
    // Noise asked for after the last sample is never sent: compare with what was.
    let report = sim.join().unwrap();
    assert!(report.completed);
    assert!(next >= 10, "noise asked for {next} times");
    assert!(report.bytes_injected as usize >= injected / 2, "{report:?}");
    assert_eq!(
        rejected as u64, report.bytes_injected,
        "exactly the injected bytes are rejected"
    );
    let truth = read_truth(&dir.path().join("truth.mcap")).unwrap();
    assert_eq!(host.data.len(), truth.samples.len(), "no packet lost");
    assert_eq!(host.data.len(), 1500, "3 s at 500 Hz");
    let s = host.decoder.stats();
    assert_eq!(s.bytes_in, s.frame_bytes + s.rejected_bytes);
    // Noise asked for between two of the device's writes goes out as one run.
    assert!((1..=next as u64).contains(&s.resyncs), "{s:?}");
    let times: Vec<u64> = host
        .data
        .iter()
        .map(|d| d.reference_time_ns.unwrap())
        .collect();
    assert!(
        times
            .windows(2)
            .all(|w| (w[1] - w[0]).abs_diff(2_000_000) < 1_000)
    );
}
