//! Offline recording: run a simulator scenario through the daemon's real decode, calibration and
//! logging path as fast as the CPU allows, without a pty, shared memory or wall-clock pacing.
//!
//! The bytes are the simulator's replies, encoded and decoded by the same codec as on a serial
//! line, and the recording is written by the same `Recorder`, so a file made here is exactly what
//! `imud` would have logged for the same scenario, seed and truth model (host timestamps are
//! synthetic: the scenario clock from the scenario's UTC of time 0, `[device]
//! gnss-epoch-utc-s`, which also dates the file names and their `started-utc`). This is how hours of data for the offline
//! tools' accuracy tests are produced in seconds: `imud --sim SCENARIO --offline`.
//!
//! Whatever the scenario's device speaks (`[device] protocol`, or `--protocol`), its simulated
//! unit (`drivers::OfflineUnit`, one per protocol folder) is configured directly and its bytes
//! are decoded by its driver, as on a live link.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::Context;
use imu_bus::recording::{Recorder, RecordingConfig};
use imu_bus::truth::TruthWriter;
use imu_sim::{DeviceCore, SimOptions};

use crate::config::Config;
use crate::drivers::{DriverEvent, FrameSlot, OfflineUnit, offline_unit};
use crate::pipeline::{ActiveCalibration, Pipeline, SampleClock, Sinks, log_rejected};

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

/// Host wall-clock time the synthetic timestamps start at, Unix epoch ns: the scenario's UTC of
/// its time 0 (`[device] gnss-epoch-utc-s`, validated after 1980), so a fleet's simulated
/// recordings are dated as the scenarios say, months apart if they say so.
fn wall_origin_ns(sim: &SimOptions) -> u64 {
    (sim.scenario.device.gnss_epoch_utc_s * 1e9).round() as u64
}

/// Synthetic host monotonic time at scenario start, ns.
const MONO_ORIGIN_NS: u64 = 1_000_000_000_000;

/// Runs `sim` through the daemon's pipeline into `config.log.dir`. Temperature is polled at
/// `config.device.temperature-rate-hz` (as in polled mode) so thermal analyses have it.
pub fn record(sim: SimOptions, config: &Config) -> anyhow::Result<OfflineReport> {
    std::fs::create_dir_all(&config.log.dir)
        .with_context(|| format!("creating {}", config.log.dir.display()))?;
    let sinks = Sinks {
        publishers: None,
        readers: None,
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
        let core = DeviceCore::new(sim.scenario.clone(), sim.truth.clone(), sim.seed);
        let truth = open_truth(&sim, &core)?;
        let period_s = core.sample_period_s();
        anyhow::ensure!(
            core.timeline().duration_s().is_finite(),
            "offline recording needs a scenario that ends (the last segment has no duration-s)"
        );
        let unit = offline_unit(sim.scenario.device.protocol, core, config)?;
        let pipeline = start_pipeline(&sim, config, unit.as_ref(), period_s, &mut sinks)?;
        Ok(Run {
            wall_origin_ns: wall_origin_ns(&sim),
            unit,
            pipeline,
            sinks,
            truth,
            queue_capacity: config.log.queue_capacity,
            report: OfflineReport {
                samples: 0,
                temperatures: 0,
                files: Vec::new(),
                truth: sim.truth_out.clone(),
            },
            slot: FrameSlot::default(),
        })
    }

    fn for_each_sample(&mut self, mut after: impl FnMut(&mut Pipeline)) -> anyhow::Result<()> {
        let period_s = self.unit.core().sample_period_s();
        let duration_s = self.unit.core().timeline().duration_s();
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
            // Files are dated by the synthetic clock: names and `started-utc` say the
            // scenario's date, not the day the simulation ran.
            synthetic_start_wall_ns: Some(wall_origin_ns(sim)),
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

/// The pipeline for a new session with `gains` on `timebase`, the configured calibration
/// applied and logged, and the device metadata written to the recorder.
fn start_pipeline(
    sim: &SimOptions,
    config: &Config,
    unit: &dyn OfflineUnit,
    period_s: f64,
    sinks: &mut Sinks,
) -> anyhow::Result<Pipeline> {
    let calibration = match &config.calibration.path {
        Some(p) => Some(std::sync::Arc::new(ActiveCalibration::new(
            imu_model::Calibration::load(p)?,
        ))),
        None => None,
    };
    let mut pipeline = Pipeline::new(unit.session(), None);
    // The synthetic host time is the scenario's exact sample time: stamp with it (the clock fit
    // would place samples on whole 6.5536 ms ticks, coarser than a 100 Hz sample interval).
    pipeline.set_sample_clock(SampleClock::Host);
    pipeline.set_health(Some(config.health.clone()));
    if let Some(cal) = calibration {
        pipeline.set_calibration(Some(cal.clone()));
        sinks.log_calibration(wall_origin_ns(sim), &cal, Some(1.0 / period_s));
    }
    if let Some(r) = &sinks.recorder {
        let mut metadata = BTreeMap::from([
            ("path".to_string(), "offline simulation".to_string()),
            (
                "serial-number".to_string(),
                sim.scenario.device.serial_number.to_string(),
            ),
        ]);
        metadata.extend(unit.details());
        r.update_metadata("imud.device", metadata);
    }
    Ok(pipeline)
}

/// One offline run: the simulated unit, the pipeline and the outputs.
struct Run {
    /// Host wall time of scenario time 0, ns.
    wall_origin_ns: u64,
    unit: Box<dyn OfflineUnit>,
    pipeline: Pipeline,
    sinks: Sinks,
    truth: Option<TruthWriter>,
    queue_capacity: usize,
    report: OfflineReport,
    /// Where the driver puts each frame.
    slot: FrameSlot,
}

impl Run {
    /// Sample `k` at `t_s`: the device's replies encoded into `bytes`, decoded, run through the
    /// pipeline, and their truth written.
    fn step(&mut self, k: u64, t_s: f64, bytes: &mut Vec<u8>) -> anyhow::Result<()> {
        bytes.clear();
        let mut truths = Vec::with_capacity(2);
        let (mono, wall) = {
            let t_ns = (t_s * 1e9) as u64;
            (MONO_ORIGIN_NS + t_ns, self.wall_origin_ns + t_ns)
        };
        self.unit.step(k, t_s, bytes, &mut truths);
        let driver = self.unit.driver();
        driver.handle_input(bytes, std::time::Instant::now());
        while let Some(ev) = driver.poll_event(&mut self.slot) {
            match ev {
                DriverEvent::Frame => {
                    self.pipeline
                        .on_frame(&mut self.slot, mono, wall, &mut self.sinks);
                }
                DriverEvent::Rejected {
                    bytes,
                    offset,
                    reason,
                } => log_rejected(bytes, offset, reason, mono, wall, &self.sinks),
                // A unit configured directly makes no start-up events.
                DriverEvent::Session(_)
                | DriverEvent::Identified(_)
                | DriverEvent::Ready
                | DriverEvent::Failed(_) => {}
            }
        }
        self.report.temperatures = self.pipeline.counters().temperatures;
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
