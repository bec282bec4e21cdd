//! End-to-end protocol tests: the `imu-sim` binary on a real pseudo-terminal, driven through a
//! real serial handle (tokio-serial) with the shared codec, checked against the truth file.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command as Process, Stdio};
use std::time::Duration;

use imu_proto::command::Command;
use imu_proto::decoder::{DecodeEvent, ReplyDecoder};
use imu_proto::reply::Reply;
use imu_proto::scale;
use imu_rec::truth::{TruthSample, read_truth};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio_serial::{SerialPortBuilderExt, SerialStream};

const G0: f64 = 9.80665;

/// A short scenario with motion on every axis so that streamed values change.
const SCENARIO: &str = r#"
name = "protocol-test"
rate-hz = 200.0
latitude-deg = 40.0
[device]
serial-number = 4242
firmware = 3104
tick-period-s = 0.0065536
clock-drift-ppm = 120.0
initial-ticks = 65000
baud = 115200
gain-scale = { accel = 8500, gyro = 10000, mag = 2000 }
[temperature]
kind = "warmup"
ambient-c = 22.0
operating-c = 38.0
tau-s = 30.0
[[segment]]
kind = "static"
orientation = { x = "north", z = "up" }
duration-s = 2.0
[[segment]]
kind = "index-table"
axis = "y"
step-deg = 45.0
positions = 4
dwell-s = 1.0
move-s = 0.5
[[segment]]
kind = "rate-steps"
axis = "z"
rates-deg-s = [40, -40]
dwell-s = 1.0
accel-deg-s2 = 80.0
"#;

/// A truth model with a visible effect on every triad and white noise.
const TRUTH: &str = r#"
format = "imud-calibration/1"
[accel.bias]
value = [0.15, -0.2, 0.1]
[accel.scale]
value = [0.002, -0.001, 0.003]
[accel.noise]
white-density = [0.002, 0.002, 0.002]
[gyro.bias]
value = [0.01, -0.005, 0.008]
[gyro.g-sensitivity]
matrix = [[0.0, 0.0, 1e-4], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]
[gyro.noise]
white-density = [0.001, 0.001, 0.001]
"#;

struct Sim {
    child: Child,
    device: PathBuf,
    truth_out: PathBuf,
    _dir: tempfile::TempDir,
}

fn start_sim(extra: &[&str]) -> Sim {
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
        .args(["--seed", "11", "--linger-s", "2"])
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.as_mut().unwrap())
        .read_line(&mut line)
        .unwrap();
    let device = PathBuf::from(line.trim());
    if !device.exists() {
        let _ = child.wait();
        let mut err = String::new();
        std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
        panic!("first stdout line must be the device path, got {line:?}; stderr: {err}");
    }
    Sim {
        child,
        device,
        truth_out,
        _dir: dir,
    }
}

impl Sim {
    fn wait_ok(mut self) -> (String, Sim) {
        let status = self.child.wait().unwrap();
        let mut stderr = String::new();
        std::io::Read::read_to_string(&mut self.child.stderr.take().unwrap(), &mut stderr).unwrap();
        assert!(status.success(), "imu-sim failed: {stderr}");
        (stderr, self)
    }
}

impl Drop for Sim {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn open(path: &Path) -> SerialStream {
    tokio_serial::new(path.to_string_lossy(), 38_400)
        .open_native_async()
        .expect("the simulator's device opens like a serial port")
}

/// Sends `cmd` and waits for its reply, returning data frames that arrived before it.
async fn transact(port: &mut SerialStream, dec: &mut ReplyDecoder, cmd: Command) -> Reply {
    port.write_all(&cmd.to_bytes()).await.unwrap();
    let code = cmd.code();
    tokio::time::timeout(Duration::from_secs(10), async {
        let mut buf = [0u8; 1024];
        loop {
            while let Some(ev) = dec.next_event() {
                if let DecodeEvent::Frame { reply, .. } = ev
                    && reply.code() == code
                {
                    return reply;
                }
            }
            let n = port.read(&mut buf).await.unwrap();
            dec.push(&buf[..n]);
        }
    })
    .await
    .unwrap_or_else(|_| panic!("no reply to {cmd:?}"))
}

/// Reads frames until `done` says stop; returns them.
async fn read_frames(
    port: &mut SerialStream,
    dec: &mut ReplyDecoder,
    mut done: impl FnMut(&Reply) -> bool,
) -> Vec<Reply> {
    let mut frames = Vec::new();
    tokio::time::timeout(Duration::from_secs(60), async {
        let mut buf = [0u8; 4096];
        loop {
            while let Some(ev) = dec.next_event() {
                match ev {
                    DecodeEvent::Frame { reply, .. } => {
                        let stop = done(&reply);
                        frames.push(reply);
                        if stop {
                            return;
                        }
                    }
                    DecodeEvent::Rejected { bytes, reason, .. } => {
                        panic!("clean link produced rejected bytes {bytes:02X?} ({reason:?})")
                    }
                }
            }
            let n = port.read(&mut buf).await.unwrap();
            assert!(n > 0, "device closed early");
            dec.push(&buf[..n]);
        }
    })
    .await
    .expect("frames keep coming");
    frames
}

fn assert_raw_matches_truth(reply: &Reply, truth: &TruthSample, gains: (u16, u16, u16)) {
    let Reply::RawSensorBits {
        mag,
        accel,
        rate,
        ticks,
    } = reply
    else {
        panic!("expected raw sensor bits, got {reply:?}");
    };
    assert_eq!(*ticks, truth.ticks, "seq {}", truth.seq);
    assert_eq!(truth.command, 0x01);
    for i in 0..3 {
        let half_lsb = |gain: u16| 0.5 * gain as f64 / 32_768_000.0 + 1e-12;
        let a_g = scale::raw_bits_to_units(accel[i], gains.0);
        assert!(
            (a_g - truth.measured_accel_m_s2[i] / G0).abs() <= half_lsb(gains.0),
            "accel {i} seq {}",
            truth.seq
        );
        let w = scale::raw_bits_to_units(rate[i], gains.1);
        assert!(
            (w - truth.measured_gyro_rad_s[i]).abs() <= half_lsb(gains.1),
            "gyro {i} seq {}",
            truth.seq
        );
        let m = scale::raw_bits_to_units(mag[i], gains.2);
        assert!(
            (m - truth.measured_mag_gauss[i]).abs() <= half_lsb(gains.2),
            "mag {i} seq {}",
            truth.seq
        );
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn startup_sequence_streaming_and_truth_agree() {
    let sim = start_sim(&["--fast"]);
    let mut port = open(&sim.device);
    let mut dec = ReplyDecoder::new();

    // The robust start-up sequence of the protocol notes.
    let stop = transact(&mut port, &mut dec, Command::SetContinuous { command: 0 }).await;
    assert!(
        matches!(stop, Reply::Continuous { command: 0, .. }),
        "{stop:?}"
    );
    let fw = transact(&mut port, &mut dec, Command::FirmwareVersion).await;
    assert_eq!(fw, Reply::FirmwareVersion { version: 3104 });
    let sn = transact(&mut port, &mut dec, Command::SerialNumber).await;
    assert_eq!(sn, Reply::SerialNumber { serial: 4242 });
    let mut gains = [0u16; 3];
    for (i, address) in [230u16, 130, 232].into_iter().enumerate() {
        match transact(&mut port, &mut dec, Command::ReadEeprom { address }).await {
            Reply::EepromRead { value, .. } => gains[i] = value,
            other => panic!("{other:?}"),
        }
    }
    assert_eq!(gains, [8500, 10000, 2000]);
    let gains = (gains[0], gains[1], gains[2]);

    // A temperature poll starts the scenario clock at t = 0 (22 C at power-on).
    let Reply::Temperature { raw, .. } = transact(&mut port, &mut dec, Command::Temperature).await
    else {
        panic!("temperature reply expected");
    };
    assert!((scale::temp_raw_to_c(raw) - 22.0).abs() < 0.01);

    // Stream raw bits until the scenario ends (the device stops talking), then stop.
    port.write_all(&Command::SetContinuous { command: 0x01 }.to_bytes())
        .await
        .unwrap();
    let ack = read_frames(&mut port, &mut dec, |r| {
        matches!(r, Reply::Continuous { .. })
    })
    .await;
    assert!(matches!(
        ack.last(),
        Some(Reply::Continuous { command: 0x01, .. })
    ));
    let total_s = 2.0 + 4.0 * 1.0 + 3.0 * 0.5 + (0.5 + 1.0 + 1.0 + 1.0 + 0.5);
    let expected = (total_s * 200.0 * (1.0 + 120e-6)) as usize;
    // Read until the device falls silent: the scenario has ended and it lingers until we have
    // read every byte before it exits.
    let mut frames = Vec::new();
    let mut buf = vec![0u8; 1 << 16];
    while let Ok(Ok(n)) = tokio::time::timeout(Duration::from_secs(2), port.read(&mut buf)).await {
        if n == 0 {
            break;
        }
        dec.push(&buf[..n]);
        while let Some(ev) = dec.next_event() {
            match ev {
                DecodeEvent::Frame { reply, .. } => frames.push(reply),
                DecodeEvent::Rejected { bytes, .. } => panic!("rejected {bytes:02X?}"),
            }
        }
    }
    let (stderr, sim) = sim.wait_ok();
    assert_eq!(dec.stats().checksum_failures, 0);
    assert_eq!(dec.stats().garbage_bytes, 0);

    let truth = read_truth(&sim.truth_out).unwrap();
    assert!(
        truth.report.stopped_early.is_none(),
        "truth file must be finished cleanly"
    );
    assert_eq!(truth.run.get("seed").map(String::as_str), Some("11"));
    assert!(truth.truth_model_toml.contains("g-sensitivity"));
    // Truth holds the temperature poll and then exactly the streamed frames, in order, no gaps.
    assert_eq!(truth.samples[0].command, 0x07);
    let streamed = &truth.samples[1..];
    assert_eq!(
        streamed.len(),
        frames.len(),
        "every streamed frame has one truth record; stderr: {stderr}"
    );
    assert!(
        frames.len() >= expected - 2 && frames.len() <= expected + 2,
        "{} frames, expected about {expected}",
        frames.len()
    );
    for (k, (reply, t)) in frames.iter().zip(streamed).enumerate() {
        assert_eq!(t.seq, k as u64 + 1);
        assert_raw_matches_truth(reply, t, gains);
    }
    // The device clock runs 120 ppm fast: successive samples are 1/(200 Hz) apart in device time,
    // so the unwrapped ticks advance by rate-derived amounts and wrap past 65535.
    let first = streamed.first().unwrap();
    let last = streamed.last().unwrap();
    let device_s = (last.ticks_unwrapped - first.ticks_unwrapped) as f64 * 0.0065536;
    let true_s = last.t_s - first.t_s;
    assert!((device_s / true_s - (1.0 + 120e-6)).abs() < 0.0065536 / true_s * 1.01 + 1e-9);
    assert!(
        last.ticks_unwrapped > 65_536,
        "the test must cross a tick wrap"
    );
    // The truth reproduces the true input: the static first segment is level-ish with z up.
    let s0 = &streamed[10];
    assert!((s0.specific_force_m_s2[2] - G0).abs() < 1e-9);
    // Segments were written, the rate plateaus among them.
    assert!(truth.segments.iter().any(|s| {
        s.kind == "rate"
            && s.table_rate_rad_s
                .is_some_and(|r| (r - 40f64.to_radians()).abs() < 1e-12)
    }));
}

/// A unit set up and saved with the vendor's tool: it streams raw sensor bits from power-up,
/// with no command from the host (`--power-up-streaming`), every frame its truth record.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_unit_powered_up_streaming_sends_raw_bits_without_any_command() {
    let sim = start_sim(&["--fast", "--power-up-streaming"]);
    let mut port = open(&sim.device);
    let mut dec = ReplyDecoder::new();
    // Read until the device falls silent (the scenario ended); nothing is ever written.
    let mut frames = Vec::new();
    let mut buf = vec![0u8; 1 << 16];
    while let Ok(Ok(n)) = tokio::time::timeout(Duration::from_secs(2), port.read(&mut buf)).await {
        if n == 0 {
            break;
        }
        dec.push(&buf[..n]);
        while let Some(ev) = dec.next_event() {
            match ev {
                DecodeEvent::Frame { reply, .. } => frames.push(reply),
                DecodeEvent::Rejected { bytes, .. } => panic!("rejected {bytes:02X?}"),
            }
        }
    }
    let (stderr, sim) = sim.wait_ok();
    assert!(stderr.contains("0 bytes in"), "{stderr}");
    let truth = read_truth(&sim.truth_out).unwrap();
    assert_eq!(
        truth.run.get("power-up-streaming").map(String::as_str),
        Some("true")
    );
    // The whole scenario from power-up, one sample a period: the first at one period, and
    // samples until the scenario's end, on the device's 120 ppm fast clock.
    let total_s = 2.0 + 4.0 * 1.0 + 3.0 * 0.5 + (0.5 + 1.0 + 1.0 + 1.0 + 0.5);
    let expected = (total_s * 200.0 * (1.0 + 120e-6)) as usize;
    assert!(
        frames.len() >= expected - 1 && frames.len() <= expected + 1,
        "{} frames, expected about {expected}",
        frames.len()
    );
    assert_eq!(truth.samples.len(), frames.len(), "{stderr}");
    for (k, (reply, t)) in frames.iter().zip(&truth.samples).enumerate() {
        assert_eq!(t.seq, k as u64);
        assert_raw_matches_truth(reply, t, (8500, 10000, 2000));
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn polled_mode_interleaves_temperature_and_skips_garbage() {
    let sim = start_sim(&["--fast"]);
    let mut port = open(&sim.device);
    let mut dec = ReplyDecoder::new();
    let mut polls = Vec::new();
    for i in 0..50 {
        // Garbage and a truncated command between polls must be skipped by the device.
        if i % 10 == 3 {
            port.write_all(&[0x77, 0x29, 0x71, 0x00]).await.unwrap();
        }
        polls.push(transact(&mut port, &mut dec, Command::RawSensorBits).await);
        if i % 5 == 0 {
            polls.push(transact(&mut port, &mut dec, Command::Temperature).await);
        }
    }
    // Write to EEPROM and read it back.
    let w = transact(
        &mut port,
        &mut dec,
        Command::WriteEeprom {
            address: 300,
            value: 0xBEEF,
        },
    )
    .await;
    assert!(matches!(w, Reply::EepromWrite { value: 0xBEEF, .. }));
    let r = transact(&mut port, &mut dec, Command::ReadEeprom { address: 300 }).await;
    assert!(matches!(r, Reply::EepromRead { value: 0xBEEF, .. }));
    drop(port);
    // The truth writer flushes at least every 0.5 s; give it that, then kill -9.
    std::thread::sleep(Duration::from_millis(1500));
    let mut sim = sim;
    sim.child.kill().unwrap();
    sim.child.wait().unwrap();
    // Killed mid-run: the truth file is still readable up to its last flush.
    let truth = read_truth(&sim.truth_out).unwrap();
    assert!(
        truth.report.stopped_early.is_some(),
        "a killed run leaves no summary"
    );
    assert_eq!(
        truth.samples.len(),
        polls.len(),
        "every data poll is in the truth, in order"
    );
    for (reply, t) in polls.iter().zip(&truth.samples) {
        assert_eq!(reply.code(), t.command);
        assert_eq!(reply.ticks(), Some(t.ticks));
        if let Reply::Temperature { raw, .. } = reply {
            assert!((scale::temp_raw_to_c(*raw) - t.temp_c).abs() < 0.005);
        } else {
            assert_raw_matches_truth(reply, t, (8500, 10000, 2000));
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn real_time_stream_with_stable_link_and_stop_command() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("imu0");
    let sim = start_sim(&["--link", link.to_str().unwrap()]);
    assert_eq!(sim.device, link);
    assert!(
        std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    let mut port = open(&link);
    let mut dec = ReplyDecoder::new();
    port.write_all(&Command::SetContinuous { command: 0x02 }.to_bytes())
        .await
        .unwrap();
    let frames = read_frames(&mut port, &mut dec, {
        let mut n = 0;
        move |r| {
            if matches!(r, Reply::Vectors { .. }) {
                n += 1;
            }
            n >= 40
        }
    })
    .await;
    let vectors: Vec<_> = frames
        .iter()
        .filter(|r| matches!(r, Reply::Vectors { .. }))
        .collect();
    assert_eq!(vectors.len(), 40);
    // In real time at 200 Hz the ticks of consecutive samples advance by 5 ms / 6.5536 ms.
    let ticks: Vec<u16> = vectors.iter().map(|r| r.ticks().unwrap()).collect();
    let span = ticks.last().unwrap().wrapping_sub(ticks[0]) as f64;
    assert!(
        (span - 39.0 * 0.005 * (1.0 + 120e-6) / 0.0065536).abs() <= 1.0,
        "span {span}"
    );
    // Gravity is on +z in the first segment: the scaled accel z is about +1 g (8500 gain).
    if let Reply::Vectors { accel, .. } = vectors[5] {
        let z_g = scale::scaled_to_units(accel[2], 8500);
        assert!((z_g - (1.0 + 0.1 / G0) * 1.003).abs() < 0.01, "z = {z_g} g");
    }
    // Stop continuous mode: after the acknowledgement no further data arrives.
    let ack = transact(&mut port, &mut dec, Command::SetContinuous { command: 0 }).await;
    assert!(matches!(ack, Reply::Continuous { command: 0, .. }));
    let mut buf = [0u8; 256];
    let quiet = tokio::time::timeout(Duration::from_millis(300), port.read(&mut buf)).await;
    assert!(quiet.is_err(), "device kept streaming after stop");
}

#[test]
fn sigterm_finishes_the_truth_file_and_removes_the_link() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("imu1");
    let sim = start_sim(&["--link", link.to_str().unwrap()]);
    std::thread::sleep(Duration::from_millis(200));
    let status = Process::new("kill")
        .args(["-TERM", &sim.child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let (_stderr, sim) = sim.wait_ok();
    assert!(
        std::fs::symlink_metadata(&link).is_err(),
        "link must be removed on exit"
    );
    let truth = read_truth(&sim.truth_out).unwrap();
    assert!(
        truth.report.stopped_early.is_none(),
        "SIGTERM must finish the truth file"
    );
    assert!(!truth.segments.is_empty());
}

#[test]
fn bad_scenario_is_a_clear_error_with_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("bad.toml");
    std::fs::write(
        &scenario,
        "name = \"x\"\n[[segment]]\nkind = \"static\"\nduration = 5\n",
    )
    .unwrap();
    let out = Process::new(env!("CARGO_BIN_EXE_imu-sim"))
        .arg("--scenario")
        .arg(&scenario)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.toml:4:"), "{err}");
    assert!(err.contains("duration"), "{err}");
    assert!(
        out.stdout.is_empty(),
        "no device path may be printed on error"
    );
}
