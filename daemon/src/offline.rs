//! Offline recording: run a simulator scenario through the daemon's real decode, calibration and
//! logging path as fast as the CPU allows, without a pty, shared memory or wall-clock pacing.
//!
//! The bytes are the simulator's replies, encoded and decoded by the same codec as on a serial
//! line, and the recording is written by the same `Recorder`, so a file made here is exactly what
//! `imud` would have logged for the same scenario, seed and truth model (host timestamps are
//! synthetic: the scenario clock plus a fixed offset). This is how hours of data for the offline
//! tools' accuracy tests are produced in seconds: `imud --sim SCENARIO --offline`.
//!
//! A scenario whose device speaks MIP (`[device] protocol = "mip"`, or `--protocol mip`) runs
//! through the MIP codec the same way: the unit is configured by the live start-up's first
//! message format (accel, gyro, mag, temperature, reference time) and its data packets are
//! decoded by the MIP decoder.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::Context;
use imu_bus::recording::{Recorder, RecordingConfig};
use imu_bus::truth::TruthWriter;
use imu_proto::DeviceProtocol;
use imu_proto::command::Command;
use imu_proto::decoder::ReplyDecoder;
use imu_proto::mip::{MipCommand, MipDecoder, Setting};
use imu_proto::reply::Reply;
use imu_sim::mip_device::MipDevice;
use imu_sim::{DeviceCore, SimOptions};

use crate::config::Config;
use crate::pipeline::{
    ActiveCalibration, GainFallback, Gains, MipTimebase, Pipeline, SampleClock, Sinks, Timebase,
};

/// What an offline run produced.
#[derive(Debug, Clone)]
pub struct OfflineReport {
    /// Data samples recorded.
    pub samples: u64,
    /// Temperature readings recorded.
    pub temperatures: u64,
    /// The recording files written.
    pub files: Vec<PathBuf>,
    /// The truth file, if one was asked for.
    pub truth: Option<PathBuf>,
}

/// A simulated session on disk: one recording file and the simulator's truth of it.
#[derive(Debug, Clone)]
pub struct Session {
    /// The recording (imud's MCAP).
    pub recording: PathBuf,
    /// The truth file (`<dir>/<name>-truth.mcap`).
    pub truth: PathBuf,
}

/// Records the scenario file `scenario` under `truth_model` (default: the scenario's own) with
/// `seed` into `dir` (recording under `<dir>/<name>/`, truth `<dir>/<name>-truth.mcap`), imud
/// applying `calibration` if given, with every other setting at its default: the fixture the
/// accuracy tests, end-to-end tests and benchmarks start from.
pub fn record_session(
    dir: &Path,
    name: &str,
    scenario: &Path,
    truth_model: Option<&Path>,
    seed: u64,
    calibration: Option<&Path>,
) -> anyhow::Result<Session> {
    let mut sim = SimOptions::from_files(scenario, truth_model)?;
    sim.seed = seed;
    let truth = dir.join(format!("{name}-truth.mcap"));
    sim.truth_out = Some(truth.clone());
    let mut config = Config::default();
    config.log.dir = dir.join(name);
    config.name = name.into();
    config.calibration.path = calibration.map(Path::to_path_buf);
    let out = record(sim, &config)?;
    anyhow::ensure!(
        out.files.len() == 1,
        "expected one recording file, got {:?}",
        out.files
    );
    Ok(Session {
        recording: out.files[0].clone(),
        truth,
    })
}

/// [`record_session`] from texts: the scenario and (optionally) the truth model are written to
/// `<dir>/<name>-scenario.toml` and `<dir>/<name>-truth-model.toml` first.
pub fn record_session_text(
    dir: &Path,
    name: &str,
    scenario: &str,
    truth_model: Option<&str>,
    seed: u64,
    calibration: Option<&Path>,
) -> anyhow::Result<Session> {
    let scenario_path = dir.join(format!("{name}-scenario.toml"));
    std::fs::write(&scenario_path, scenario)
        .with_context(|| format!("writing {}", scenario_path.display()))?;
    let model_path = dir.join(format!("{name}-truth-model.toml"));
    if let Some(text) = truth_model {
        std::fs::write(&model_path, text)
            .with_context(|| format!("writing {}", model_path.display()))?;
    }
    record_session(
        dir,
        name,
        &scenario_path,
        truth_model.map(|_| model_path.as_path()),
        seed,
        calibration,
    )
}

/// Host wall-clock time the synthetic timestamps start at (2026-01-01T00:00:00Z), ns.
const WALL_ORIGIN_NS: u64 = 1_767_225_600_000_000_000;
/// Synthetic host monotonic time at scenario start, ns.
const MONO_ORIGIN_NS: u64 = 1_000_000_000_000;

/// Runs `sim` through the daemon's pipeline into `config.log.dir`. Temperature is polled at
/// `config.device.temperature-rate-hz` (as in polled mode) so thermal analyses have it.
pub fn record(sim: SimOptions, config: &Config) -> anyhow::Result<OfflineReport> {
    std::fs::create_dir_all(&config.log.dir)
        .with_context(|| format!("creating {}", config.log.dir.display()))?;
    let sinks = Sinks {
        publishers: None,
        recorder: Some(start_recorder(&sim, config)?),
        ros2: None,
    };
    let mut run = Run::start(sim, config, sinks)?;
    run.for_each_sample(|_| {})?;
    run.finish(config)
}

/// Runs `sim` through the daemon's pipeline with nothing recorded or published and returns
/// the live calibration health reports it made (one per still window): how the health
/// monitor's false-alarm rate is measured over many simulated days.
pub fn health_reports(
    sim: SimOptions,
    config: &Config,
) -> anyhow::Result<Vec<imu_bus::CalibrationHealth>> {
    let mut run = Run::start(sim, config, Sinks::default())?;
    let mut reports = Vec::new();
    run.for_each_sample(|pipeline| reports.extend(pipeline.take_health()))?;
    Ok(reports)
}

impl Run {
    /// A run of `sim` into `sinks`: the device started, its gains read, the pipeline made.
    fn start(sim: SimOptions, config: &Config, mut sinks: Sinks) -> anyhow::Result<Run> {
        let mut core = DeviceCore::new(sim.scenario.clone(), sim.truth.clone(), sim.seed);
        let truth = open_truth(&sim, &core)?;
        let period_s = core.sample_period_s();
        anyhow::ensure!(
            core.timeline().duration_s().is_finite(),
            "offline recording needs a scenario that ends (the last segment has no duration-s)"
        );
        let (device, gains, timebase) = match sim.scenario.device.protocol {
            DeviceProtocol::Gx1 => {
                let gains = read_gains(&mut core, config);
                let timebase = Timebase::gx1(config.device.tick_period_s);
                (
                    OfflineDevice::Gx1(core, ReplyDecoder::new()),
                    gains,
                    timebase,
                )
            }
            DeviceProtocol::Mip => {
                let device = configure_mip(core, period_s)?;
                let timebase = MipTimebase::ReferenceTime.timebase();
                (
                    OfflineDevice::Mip(Box::new(device), MipDecoder::new()),
                    Gains::NOT_APPLICABLE,
                    timebase,
                )
            }
        };
        let pipeline = start_pipeline(&sim, config, (gains, timebase), period_s, &mut sinks)?;
        Ok(Run {
            device,
            pipeline,
            sinks,
            truth,
            cmd: config.device.command.command(),
            temp_every: temperature_every(config, period_s),
            queue_capacity: config.log.queue_capacity,
            report: OfflineReport {
                samples: 0,
                temperatures: 0,
                files: Vec::new(),
                truth: sim.truth_out.clone(),
            },
        })
    }

    /// Every sample of the scenario through the pipeline, `after` called after each.
    fn for_each_sample(&mut self, mut after: impl FnMut(&mut Pipeline)) -> anyhow::Result<()> {
        let period_s = self.device.core().sample_period_s();
        let duration_s = self.device.core().timeline().duration_s();
        let mut bytes = Vec::with_capacity(64);
        let mut k: u64 = 0;
        loop {
            let t_s = k as f64 * period_s;
            if t_s >= duration_s {
                return Ok(());
            }
            self.step(k, t_s, &mut bytes)?;
            after(&mut self.pipeline);
            k += 1;
        }
    }
}

/// Opens the truth file `sim.truth_out` (if asked for) and writes the timeline's segments to it.
fn open_truth(sim: &SimOptions, device: &DeviceCore) -> anyhow::Result<Option<TruthWriter>> {
    let Some(path) = &sim.truth_out else {
        return Ok(None);
    };
    let run = BTreeMap::from([
        ("scenario-name".to_string(), sim.scenario.name.clone()),
        ("seed".to_string(), sim.seed.to_string()),
        ("rate-hz".to_string(), sim.scenario.rate_hz.to_string()),
        ("pacing".to_string(), "offline".to_string()),
    ]);
    let mut w = TruthWriter::create(path, &run, &sim.scenario_text, &sim.truth.to_toml_string())?;
    for s in device.timeline().segments() {
        w.write_segment(&imu_sim::segment_record(s))?;
    }
    Ok(Some(w))
}

/// Starts the MCAP recorder into `config.log.dir` with the config and the scenario as metadata.
fn start_recorder(sim: &SimOptions, config: &Config) -> anyhow::Result<Recorder> {
    Recorder::start(
        RecordingConfig {
            dir: config.log.dir.clone(),
            prefix: config.name.clone(),
            rotate_size_bytes: config.log.rotate_size_mib * 1024 * 1024,
            // Rotation by time follows the synthetic clock poorly; offline files rotate by size.
            rotate_interval_s: 0.0,
            queue_capacity: config.log.queue_capacity,
            frame_id: config.log.frame_id.clone(),
            ..RecordingConfig::default()
        },
        vec![
            (
                "imud.config".to_string(),
                BTreeMap::from([("toml".to_string(), config.to_toml())]),
            ),
            (
                "imud.offline".to_string(),
                BTreeMap::from([
                    ("scenario-name".to_string(), sim.scenario.name.clone()),
                    ("seed".to_string(), sim.seed.to_string()),
                ]),
            ),
        ],
    )
    .context("starting the MCAP recorder")
}

/// The start-up exchange, through the codec, as on a line: reads the three gain scales from the
/// EEPROM, falling back to `config.device.fallback-gains` where the device gives none.
fn read_gains(device: &mut DeviceCore, config: &Config) -> Gains {
    let fb = config.device.fallback_gains;
    let (accel, fa) = read_gain(device, imu_proto::device::ACCEL_GAIN_SCALE_ADDR, fb.accel);
    let (gyro, fg) = read_gain(device, imu_proto::device::GYRO_GAIN_SCALE_ADDR, fb.gyro);
    let (mag, fm) = read_gain(device, imu_proto::device::MAG_GAIN_SCALE_ADDR, fb.mag);
    Gains {
        accel,
        gyro,
        mag,
        fallback: GainFallback {
            accel: fa,
            gyro: fg,
            mag: fm,
        },
    }
}

/// One gain scale read from EEPROM `address` at t = 0, and whether `fallback` replaced it.
fn read_gain(device: &mut DeviceCore, address: u16, fallback: u16) -> (u16, bool) {
    let reply = device
        .handle(Command::ReadEeprom { address }, 0.0)
        .reply
        .and_then(|r| Reply::decode(&r.to_bytes()).ok());
    match reply {
        Some(Reply::EepromRead { value, .. }) if value != 0 => (value, false),
        _ => (fallback, true),
    }
}

/// The MIP unit configured as the live start-up configures it: its first message format at the
/// scenario's rate, then resumed; each command through the codec.
fn configure_mip(core: DeviceCore, period_s: f64) -> anyhow::Result<MipDevice> {
    let mut device = MipDevice::new(core);
    let decimation = device.decimation();
    let format = crate::startup::preferred_mip_format(decimation);
    for cmd in [
        MipCommand::ImuMessageFormat(Setting::Write(format)),
        MipCommand::Resume,
    ] {
        device.push(cmd.to_packet().as_bytes());
        while let Some(request) = device.next_request() {
            let request = request.map_err(|n| anyhow::anyhow!("the unit rejected {n} bytes"))?;
            let reply = device.handle(request);
            let replies = imu_proto::mip::MipReply::decode_packet(&reply)?;
            anyhow::ensure!(
                replies
                    .iter()
                    .all(|r| r.code == imu_proto::mip::AckCode::Ok),
                "the simulated unit refused {cmd:?} at {:.0} Hz: {replies:?}",
                1.0 / period_s
            );
        }
    }
    Ok(device)
}

/// The pipeline for a new session with `gains` on `timebase`, the configured calibration
/// applied and logged, and the device metadata written to the recorder.
fn start_pipeline(
    sim: &SimOptions,
    config: &Config,
    (gains, timebase): (Gains, Timebase),
    period_s: f64,
    sinks: &mut Sinks,
) -> anyhow::Result<Pipeline> {
    let calibration = match &config.calibration.path {
        Some(p) => Some(std::sync::Arc::new(ActiveCalibration::new(
            imu_model::Calibration::load(p)?,
        ))),
        None => None,
    };
    let mut pipeline = Pipeline::new(gains, config.device.tick_period_s, None);
    pipeline.new_session(gains, timebase);
    // The synthetic host time is the scenario's exact sample time: stamp with it (the clock fit
    // would place samples on whole 6.5536 ms ticks, coarser than a 100 Hz sample interval).
    pipeline.set_sample_clock(SampleClock::Host);
    pipeline.set_health(Some(config.health.clone()));
    if let Some(cal) = calibration {
        pipeline.set_calibration(Some(cal.clone()));
        sinks.log_calibration(WALL_ORIGIN_NS, &cal, Some(1.0 / period_s));
    }
    if let Some(r) = &sinks.recorder {
        let protocol = sim.scenario.device.protocol;
        let mut metadata = BTreeMap::from([
            ("path".to_string(), "offline simulation".to_string()),
            ("protocol".to_string(), protocol.name().to_string()),
            (
                "serial-number".to_string(),
                sim.scenario.device.serial_number.to_string(),
            ),
        ]);
        if protocol == DeviceProtocol::Gx1 {
            metadata.extend(gains.metadata());
        }
        r.update_metadata("imud.device", metadata);
    }
    Ok(pipeline)
}

/// Every how many samples a temperature is polled (`u64::MAX`: never).
fn temperature_every(config: &Config, period_s: f64) -> u64 {
    if config.device.temperature_rate_hz > 0.0 {
        ((1.0 / period_s) / config.device.temperature_rate_hz)
            .round()
            .max(1.0) as u64
    } else {
        u64::MAX
    }
}

/// The simulated device of an offline run and the host's decoder for it.
// One lives per offline run: the variants' sizes do not matter.
#[allow(clippy::large_enum_variant)]
enum OfflineDevice {
    /// A 3DM-GX1, polled.
    Gx1(DeviceCore, ReplyDecoder),
    /// A MIP unit, streaming.
    Mip(Box<MipDevice>, MipDecoder),
}

impl OfflineDevice {
    fn core(&self) -> &DeviceCore {
        match self {
            OfflineDevice::Gx1(core, _) => core,
            OfflineDevice::Mip(device, _) => device.core(),
        }
    }
}

/// The state of an offline run between samples.
struct Run {
    device: OfflineDevice,
    pipeline: Pipeline,
    sinks: Sinks,
    truth: Option<TruthWriter>,
    /// The data command polled every sample.
    cmd: Command,
    /// Every how many samples a temperature is polled.
    temp_every: u64,
    queue_capacity: usize,
    report: OfflineReport,
}

impl Run {
    /// Sample `k` at `t_s`: the device's replies encoded into `bytes`, decoded, run through the
    /// pipeline, and their truth written.
    fn step(&mut self, k: u64, t_s: f64, bytes: &mut Vec<u8>) -> anyhow::Result<()> {
        bytes.clear();
        let mut truths = Vec::with_capacity(2);
        let (mono, wall) = {
            let t_ns = (t_s * 1e9) as u64;
            (MONO_ORIGIN_NS + t_ns, WALL_ORIGIN_NS + t_ns)
        };
        match &mut self.device {
            OfflineDevice::Gx1(device, decoder) => {
                if k.is_multiple_of(self.temp_every) {
                    let (reply, t) = device.data_reply(Command::Temperature, t_s);
                    reply.encode(bytes);
                    truths.push(t);
                    self.report.temperatures += 1;
                }
                let (reply, t) = device.data_reply(self.cmd, t_s);
                reply.encode(bytes);
                truths.push(t);
                decoder.push(bytes);
                while let Some(ev) = decoder.next_event() {
                    self.pipeline.on_event(ev, mono, wall, &mut self.sinks);
                }
            }
            OfflineDevice::Mip(device, decoder) => {
                // The temperature comes with every packet (recorded once a second).
                let (packet, t) = device.data_packet(t_s);
                truths.push(t);
                decoder.push(packet.as_bytes());
                while let Some(ev) = decoder.next_event() {
                    self.pipeline.on_mip_event(ev, mono, wall, &mut self.sinks);
                }
                self.report.temperatures = self.pipeline.counters().temperatures;
            }
        }
        self.report.samples += 1;
        if let Some(w) = &mut self.truth {
            for t in &truths {
                w.write_sample(t)?;
            }
        }
        if k.is_multiple_of(1024) {
            self.wait_for_writer();
        }
        Ok(())
    }

    /// Offline there is no reason to drop: waits for the writer while its queue is over half full.
    fn wait_for_writer(&self) {
        let Some(r) = &self.sinks.recorder else {
            return;
        };
        // A sample is one record (with its frame), a temperature two (its frame and itself).
        let logged = self.report.samples + 2 * self.report.temperatures;
        while {
            let s = r.stats();
            logged.saturating_sub(s.written + s.dropped_queue_full + s.dropped_not_logging)
                > (self.queue_capacity as u64) / 2
        } {
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
    }

    /// Closes the truth file and the recording (failing if any record was dropped) and lists the
    /// files written.
    fn finish(mut self, config: &Config) -> anyhow::Result<OfflineReport> {
        if let Some(w) = self.truth {
            w.finish()?;
        }
        let recorder = self.sinks.recorder.take().expect("recorder");
        let stats = recorder.finish().context("finishing the recording")?;
        anyhow::ensure!(
            stats.dropped_queue_full + stats.dropped_not_logging == 0,
            "the recorder dropped {} records: {:?}",
            stats.dropped_queue_full + stats.dropped_not_logging,
            stats.last_error
        );
        let mut report = self.report;
        report.files = imu_bus::recording::list_recordings(&config.log.dir, &config.name)
            .with_context(|| format!("listing {}", config.log.dir.display()))?
            .into_iter()
            .filter(|f| Some(f) != report.truth.as_ref())
            .collect();
        Ok(report)
    }
}
