//! Golden regressions (gpsd's `regress-driver`): short committed byte captures per protocol
//! (`tests/golden/*.hex`, made by the simulator, faults included, and a real filter packet from
//! the vendor's SDK) are replayed through the drivers and the pipeline (`Daemon::replay`, the
//! recording written and read back), and every decoded sample and the final counters must
//! equal the committed expectation (`tests/golden/*.expected`), line for line.
//!
//! When a change is meant to alter the output: `IMUD_GOLDEN_REGENERATE=expected cargo test -p
//! imud --test golden` rewrites the expectations, to be reviewed with `git diff`;
//! `IMUD_GOLDEN_REGENERATE=captures` also makes the captures again from the simulator.

use std::path::{Path, PathBuf};

use imu_bus::recording::{Recorder, RecordingConfig, list_recordings, read_recording};
use imu_proto::DeviceProtocol;
use imu_proto::command::Command;
use imu_proto::mip::data::field;
use imu_proto::mip::{DescriptorRate, MessageFormat, MipCommand, PacketBuilder, Setting};
use imu_proto::xsens::data::id;
use imu_proto::xsens::{DataId, Format, OutputConfiguration, OutputSetting, XsensCommand};
use imu_sim::mip_device::MipDevice;
use imu_sim::vectornav_device::VnDevice;
use imu_sim::xsens_device::XsensDevice;
use imu_sim::{DeviceCore, Scenario};
use imud::config::Config;
use imud::drivers::{Device, Driver};
use imud::pipeline::{Pipeline, Sinks};
use imud::replay::{Capture, Speed};
use imud::session::{CalibrationSource, Daemon};

const SCENARIO: &str = include_str!("../../config/scenarios/demo.toml");
const TRUTH: &str = include_str!("../../config/models/example-3dm-gx1.toml");

/// mip_sdk (MIT) `test/cpp/mip_parser_performance.cpp`, `DATA_PACKET`: a 199-byte estimation
/// filter (0x82) packet of a real unit, as `imu-proto`'s decoder tests hold it.
const FILTER_PACKET_HEX: &str = "756582c10ed3408c84ef9db22d0f000000000ad5000000d47c364c4010057ffffff87fc000007ffffff8000110067fc000007fc000007fc0000000011007000000000000000000000000000108100002000000001c01000000000000000000000000000000000000000000000000000010027fc000007fc000007fc0000000001c427ff80000000000007ff80000000000007ff8000000000000000009464464268700040110080000000000000000000000000000100900000000000000000000000000008756";

/// One capture: its name (the protocol first) and how the simulator makes it.
struct Case {
    name: &'static str,
    protocol: DeviceProtocol,
    make: fn() -> Vec<u8>,
}

const CASES: [Case; 9] = [
    Case {
        name: "gx1-raw-faults",
        protocol: DeviceProtocol::Gx1,
        make: gx1_raw_faults,
    },
    Case {
        name: "gx1-vectors",
        protocol: DeviceProtocol::Gx1,
        make: gx1_vectors,
    },
    Case {
        name: "mip-reference-faults",
        protocol: DeviceProtocol::Mip,
        make: mip_reference_faults,
    },
    Case {
        name: "mip-internal-timestamp",
        protocol: DeviceProtocol::Mip,
        make: mip_internal,
    },
    Case {
        name: "mip-7series-interleaved",
        protocol: DeviceProtocol::Mip,
        make: mip_seven_series,
    },
    Case {
        name: "xsens-hr-faults",
        protocol: DeviceProtocol::Xsens,
        make: xsens_hr_faults,
    },
    Case {
        name: "xsens-fp1632",
        protocol: DeviceProtocol::Xsens,
        make: xsens_fp1632,
    },
    Case {
        name: "xsens-power-up-default",
        protocol: DeviceProtocol::Xsens,
        make: xsens_power_up_default,
    },
    Case {
        name: "vectornav-gnss-faults",
        protocol: DeviceProtocol::Vectornav,
        make: vectornav_gnss_faults,
    },
];

fn core(protocol: DeviceProtocol) -> DeviceCore {
    let mut scenario = Scenario::from_toml_str(SCENARIO, "demo").unwrap();
    scenario.set_protocol(protocol, "golden").unwrap();
    let truth = imu_model::Calibration::from_toml_str(TRUTH, "truth").unwrap();
    DeviceCore::new(scenario, truth, 11)
}

/// A GX1 streaming raw bits at 100 Hz for 3 s, a temperature reply each second, and faults:
/// three samples lost, a corrupted byte, garbage, a truncated frame.
fn gx1_raw_faults() -> Vec<u8> {
    let mut d = core(DeviceProtocol::Gx1);
    let mut out = Vec::new();
    for k in 0..300u64 {
        let t_s = k as f64 * 0.01;
        if k % 100 == 0 {
            d.data_reply(Command::Temperature, t_s).0.encode(&mut out);
        }
        let mut frame = Vec::new();
        d.data_reply(Command::RawSensorBits, t_s)
            .0
            .encode(&mut frame);
        match k {
            60..=62 => continue,
            120 => frame[7] ^= 0x10,
            180 => out.extend_from_slice(&[0x00, 0xAA, 0x13, 0x37, 0xFE]),
            240 => frame.truncate(10),
            _ => {}
        }
        out.extend_from_slice(&frame);
    }
    out
}

/// A GX1 streaming gyro-stabilized vectors (scaled counts) at 100 Hz for 1.5 s.
fn gx1_vectors() -> Vec<u8> {
    let mut d = core(DeviceProtocol::Gx1);
    let mut out = Vec::new();
    for k in 0..150u64 {
        d.data_reply(Command::StabilizedVectors, k as f64 * 0.01)
            .0
            .encode(&mut out);
    }
    out
}

/// A simulated MIP unit set to `fields` (at its own decimation) and resumed.
fn mip_unit(fields: &[u8]) -> MipDevice {
    let mut d = MipDevice::new(core(DeviceProtocol::Mip));
    let decimation = d.decimation();
    let format = MessageFormat {
        fields: fields
            .iter()
            .map(|&descriptor| DescriptorRate {
                descriptor,
                decimation,
            })
            .collect(),
    };
    for cmd in [
        MipCommand::ImuMessageFormat(Setting::Write(format)),
        MipCommand::Resume,
    ] {
        d.push(cmd.to_packet().as_bytes());
        while let Some(Ok(r)) = d.next_request() {
            let _ = d.handle(r);
        }
    }
    d
}

/// A MIP unit on its reference time (accel, gyro, mag, temperature) at 100 Hz for 2 s, with
/// faults: two packets lost, a corrupted byte, garbage.
fn mip_reference_faults() -> Vec<u8> {
    let mut d = mip_unit(&[
        field::SCALED_ACCEL,
        field::SCALED_GYRO,
        field::SCALED_MAG,
        field::TEMPERATURE_ABS,
        field::REFERENCE_TIME,
    ]);
    let mut out = Vec::new();
    for k in 0..200u64 {
        let mut packet = d.data_packet(k as f64 * 0.01).0.as_bytes().to_vec();
        match k {
            50 | 51 => continue,
            100 => packet[20] ^= 0x01,
            150 => out.extend_from_slice(&[0x75, 0x00, 0x65, 0x42]),
            _ => {}
        }
        out.extend_from_slice(&packet);
    }
    out
}

/// An older unit (3DM-GX3-like): accel, gyro and the 62.5 kHz internal timestamp, 1.5 s.
fn mip_internal() -> Vec<u8> {
    let mut d = mip_unit(&[
        field::SCALED_ACCEL,
        field::SCALED_GYRO,
        field::INTERNAL_TIMESTAMP,
    ]);
    (0..150u64)
        .flat_map(|k| d.data_packet(k as f64 * 0.01).0.as_bytes().to_vec())
        .collect()
}

/// A 7-series stream: IMU packets on the reference time, the vendor SDK's real filter packet
/// every tenth and a system (0xA0) packet with the shared reference time every fiftieth.
fn mip_seven_series() -> Vec<u8> {
    let mut d = mip_unit(&[
        field::SCALED_ACCEL,
        field::SCALED_GYRO,
        field::REFERENCE_TIME,
    ]);
    let filter: Vec<u8> = (0..FILTER_PACKET_HEX.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&FILTER_PACKET_HEX[i..i + 2], 16).unwrap())
        .collect();
    let mut out = Vec::new();
    for k in 0..150u64 {
        let (packet, truth) = d.data_packet(k as f64 * 0.01);
        out.extend_from_slice(packet.as_bytes());
        if k % 10 == 5 {
            out.extend_from_slice(&filter);
        }
        if k % 50 == 25 {
            let mut system = PacketBuilder::new(0xA0);
            let ns = (truth.t_s * 1e9) as u64;
            system
                .field(field::REFERENCE_TIME, &ns.to_be_bytes())
                .unwrap();
            out.extend_from_slice(system.build().as_bytes());
        }
    }
    out
}

/// A simulated MTi set to `outputs` (if any) and in measurement mode.
fn xsens_unit(outputs: Option<OutputConfiguration>) -> XsensDevice {
    let mut d = XsensDevice::new(core(DeviceProtocol::Xsens));
    if let Some(outputs) = outputs {
        for cmd in [
            XsensCommand::GoToConfig,
            XsensCommand::SetOutputConfiguration(outputs),
            XsensCommand::GoToMeasurement,
        ] {
            d.push(cmd.to_message().as_bytes());
            while let Some(Ok(r)) = d.next_request() {
                let _ = d.handle(r);
            }
        }
    }
    d
}

/// An MTi set up as imud's start-up sets it (HR and compensated outputs, magnetic field,
/// temperature, UTC time; float32) at 100 Hz for 1.5 s, with faults: two messages lost, a
/// corrupted byte, garbage with a false preamble.
fn xsens_hr_faults() -> Vec<u8> {
    let mut d = xsens_unit(Some(imud::drivers::xsens::preferred_outputs(100)));
    let mut out = Vec::new();
    for k in 0..150u64 {
        let mut msg = d.data_message(k as f64 * 0.01).0.as_bytes().to_vec();
        match k {
            40 | 41 => continue,
            80 => msg[30] ^= 0x01,
            120 => out.extend_from_slice(&[0xFA, 0x00, 0xFA, 0xFF, 0x36]),
            _ => {}
        }
        out.extend_from_slice(&msg);
    }
    out
}

/// A VN-200 streaming the binary output imud configures (startup time, GPS time and status,
/// uncompensated and compensated readings, temperature) at 100 Hz for 1.5 s with its power-up
/// `$VNYPR` output still on at 40 Hz between the messages, and faults: two messages lost, a
/// corrupted byte, garbage, a truncated message.
fn vectornav_gnss_faults() -> Vec<u8> {
    use imu_proto::vectornav::{BinaryOutputConfig, Check, Register, VnCommand};
    let mut scenario = Scenario::from_toml_str(SCENARIO, "demo").unwrap();
    scenario
        .set_protocol(DeviceProtocol::Vectornav, "golden")
        .unwrap();
    scenario.device.model = "VN-200T-CR".into();
    let truth = imu_model::Calibration::from_toml_str(TRUTH, "truth").unwrap();
    let mut d = VnDevice::new(DeviceCore::new(scenario, truth, 11));
    let output = Register::BinaryOutput {
        index: 1,
        config: BinaryOutputConfig {
            async_mode: 3,
            rate_divisor: 8,
            fields: imud::drivers::vectornav::startup::preferred_fields(true),
        },
    };
    d.push(
        VnCommand::Write(output)
            .to_sentence(Check::Checksum8)
            .as_bytes(),
    );
    while let Some(Ok(r)) = d.next_request() {
        let _ = d.handle(r);
    }
    let mut out = Vec::new();
    for k in 0..150u64 {
        let mut frame = Vec::new();
        d.stream_sample(k as f64 * 0.01, &mut frame);
        match k {
            30 | 31 => continue,
            60 => {
                let last = frame.len() - 5;
                frame[last] ^= 0x01;
            }
            90 => out.extend_from_slice(&[0xFA, 0x00, 0x24, 0x56, 0x13]),
            120 => {
                let n = frame.len() - 40;
                frame.truncate(n);
            }
            _ => {}
        }
        out.extend_from_slice(&frame);
    }
    out
}

/// The HR outputs in fixed point 16.32 with `SampleTimeFine`, 1 s.
fn xsens_fp1632() -> Vec<u8> {
    let outputs = [
        (id::SAMPLE_TIME_FINE, 0xFFFF),
        (
            DataId::with_format(id::ACCELERATION_HR, Format::Fp1632).0,
            100,
        ),
        (
            DataId::with_format(id::RATE_OF_TURN_HR, Format::Fp1632).0,
            100,
        ),
    ]
    .map(|(data_id, rate_hz)| OutputSetting { data_id, rate_hz })
    .to_vec();
    let mut d = xsens_unit(Some(OutputConfiguration(outputs)));
    (0..100u64)
        .flat_map(|k| d.data_message(k as f64 * 0.01).0.as_bytes().to_vec())
        .collect()
}

/// A unit as it powers up: its default outputs (compensated acceleration, rate of turn and
/// magnetic field, no HR outputs), 1 s.
fn xsens_power_up_default() -> Vec<u8> {
    let mut d = xsens_unit(None);
    (0..100u64)
        .flat_map(|k| d.data_message(k as f64 * 0.01).0.as_bytes().to_vec())
        .collect()
}

fn golden_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden")
}

/// The capture as a hex dump, 32 bytes a line with their offset.
fn hex_dump(name: &str, bytes: &[u8]) -> String {
    let mut text = format!(
        "# {name}: made by daemon/tests/golden.rs from the simulator ({} bytes)\n",
        bytes.len()
    );
    for (i, line) in bytes.chunks(32).enumerate() {
        text.push_str(&format!("{:06x}:", i * 32));
        for b in line {
            text.push_str(&format!(" {b:02x}"));
        }
        text.push('\n');
    }
    text
}

/// Replays the capture through a passive device of `protocol` and the pipeline, recording;
/// the samples and final counters as text.
fn decode(path: &Path, protocol: DeviceProtocol) -> String {
    let dir = tempfile::tempdir().unwrap();
    let mut config = Config::default();
    config.device.protocol = Some(protocol);
    config.device.configure = false;
    config.device.path = path.to_path_buf();
    let recorder = Recorder::start(
        RecordingConfig {
            dir: dir.path().to_path_buf(),
            prefix: "golden".into(),
            ..RecordingConfig::default()
        },
        Vec::new(),
    )
    .unwrap();
    let device = Device::new(&config);
    let mut pipeline = Pipeline::new(device.initial_session(), None);
    pipeline.set_health(Some(config.health.clone()));
    let mut daemon = Daemon {
        calibration: CalibrationSource::new(None, false),
        config,
        sinks: Sinks {
            recorder: Some(recorder),
            ..Sinks::default()
        },
        pipeline,
        device,
        reconnects: 0,
        notified_ready: false,
        on_identity: Box::new(|_, _| {}),
        calibration_noise_pending: false,
        input_link: None,
    };
    // Fixed host times: the capture paced at 115200 bit/s from a fixed origin.
    let capture = Capture::read(
        path,
        115_200,
        (1_000_000_000_000, 1_767_225_600_000_000_000),
    )
    .unwrap();
    daemon.replay(&capture, Speed::Max).unwrap();
    let recorder = daemon.sinks.recorder.take().unwrap();
    recorder.finish().unwrap();
    let files = list_recordings(dir.path(), "golden").unwrap();
    let rec = read_recording(&files[0]).unwrap();
    let (_, s) = rec.statuses.last().expect("a final status");
    let mut text = format!(
        "# decoded by imud's {protocol} driver and pipeline; regenerate with \
         IMUD_GOLDEN_REGENERATE=expected\n\
         frames {} samples {} lost {} checksum-failures {} garbage-bytes {} truncated {} \
         unusable {} fields-skipped {} temperatures {}\n\
         # seq ticks t_sample_ns t_device_ns flags counts(accel gyro mag) \
         device(accel_m_s2 gyro_rad_s mag_gauss) temp_c | imu(stamp accel gyro)\n",
        s.frames,
        s.samples,
        s.samples_lost,
        s.checksum_failures,
        s.garbage_bytes,
        s.truncated_frames,
        s.packets_unusable,
        s.fields_skipped,
        rec.temperatures.len(),
    );
    for (r, imu) in rec.raw.iter().zip(&rec.imu) {
        text.push_str(&format!(
            "{} {} {} {} {:#06x} {:?} {:?} {:?} {:?} {:?} {:?} {:?} | {} {:?} {:?}\n",
            r.seq,
            r.ticks_unwrapped,
            r.t_sample_ns,
            r.t_device_ns,
            r.flags,
            r.accel_counts,
            r.gyro_counts,
            r.mag_counts,
            r.accel_device_m_s2,
            r.gyro_device_rad_s,
            r.mag_device_gauss,
            r.temp_c,
            imu.header.stamp.to_ns(),
            imu.linear_acceleration,
            imu.angular_velocity,
        ));
    }
    text
}

#[test]
fn golden_captures_decode_to_their_expected_samples() {
    let regenerate = std::env::var("IMUD_GOLDEN_REGENERATE").ok();
    let dir = golden_dir();
    let mut failures = Vec::new();
    for case in CASES {
        let capture = dir.join(format!("{}.hex", case.name));
        if regenerate.as_deref() == Some("captures") {
            std::fs::write(&capture, hex_dump(case.name, &(case.make)())).unwrap();
        }
        let got = decode(&capture, case.protocol);
        let expected_path = dir.join(format!("{}.expected", case.name));
        if regenerate.is_some() {
            std::fs::write(&expected_path, &got).unwrap();
            eprintln!(
                "{}: regenerated; review it with git diff",
                expected_path.display()
            );
            continue;
        }
        let expected = std::fs::read_to_string(&expected_path).unwrap_or_else(|e| {
            panic!(
                "{}: {e} (IMUD_GOLDEN_REGENERATE=expected makes it)",
                expected_path.display()
            )
        });
        if got != expected {
            let (line, (e, g)) = expected
                .lines()
                .chain(std::iter::repeat("<end>"))
                .zip(got.lines().chain(std::iter::repeat("<end>")))
                .enumerate()
                .find(|(_, (e, g))| e != g)
                .expect("texts differ");
            failures.push(format!(
                "{}:{}:\n  expected {e}\n  got      {g}",
                expected_path.display(),
                line + 1
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "decoding changed (if that is intended: IMUD_GOLDEN_REGENERATE=expected cargo test -p \
         imud --test golden, then review the diff):\n{}",
        failures.join("\n")
    );
}

/// The captures are what the generators make: a change to the simulator or the codec that
/// alters them is seen here, not only as changed decoding.
#[test]
fn the_captures_are_what_the_simulator_makes() {
    if std::env::var("IMUD_GOLDEN_REGENERATE").as_deref() == Ok("captures") {
        return;
    }
    for case in CASES {
        let path = golden_dir().join(format!("{}.hex", case.name));
        let committed = std::fs::read_to_string(&path).unwrap();
        assert!(
            committed == hex_dump(case.name, &(case.make)()),
            "{}: the simulator makes another capture now (IMUD_GOLDEN_REGENERATE=captures)",
            path.display()
        );
    }
}
