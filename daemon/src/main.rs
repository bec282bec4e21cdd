//! `imud`: the acquisition daemon. Reads a 3DM-GX1 over serial, applies the calibration in real
//! time, publishes raw and corrected samples over iceoryx2 and logs every frame to MCAP.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context;
use clap::Parser;
use imu_bus::recording::{Recorder, RecordingConfig};
use imu_bus::shm::{Publishers, ShmOptions};
use tracing::{info, warn};

use imud::config::{self, Config};
use imud::drivers::{Device, Driver};
use imud::pipeline::{Pipeline, Sinks};
use imud::session::{CalibrationSource, Daemon, DeviceIdentity, Signals};

/// The default `--sim` scenario and truth model, built in so `imud --sim` works from anywhere.
const DEMO_SCENARIO: &str = include_str!("../../config/scenarios/demo.toml");
const DEMO_TRUTH: &str = imu_model::EXAMPLE_GX1_MODEL_TOML;

/// imud: MEMS IMU acquisition daemon (MicroStrain 3DM-GX1).
///
/// Reads the device over a serial port, applies the loaded calibration to every sample, publishes
/// raw and corrected samples over iceoryx2 shared memory (services imud/<name>/...; see imu-echo)
/// and logs every frame to MCAP (ros2 profile: /imu/data is sensor_msgs/msg/Imu); with --ros2 it
/// also publishes the ROS 2 topics over DDS (`ros2 topic echo /imu/data` on the same domain). Configuration:
/// --config FILE, else $IMUD_CONFIG, else /etc/imud/imud.toml, else built-in defaults (documented
/// in config/imud.toml); the flags below override the file. SIGHUP reloads the calibration;
/// SIGTERM finishes the MCAP file and exits. At start-up, recordings of this instance that a
/// crash left unfinished in the log directory are repaired (see `imud recover`).
#[derive(Debug, Parser)]
#[command(name = "imud", version, args_conflicts_with_subcommands = true)]
struct Args {
    #[command(subcommand)]
    command: Option<Command>,
    /// Configuration file (TOML).
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Serial device path (overrides device.path).
    #[arg(long, value_name = "PATH")]
    device: Option<PathBuf>,
    /// The device's protocol, `3dm-gx1`, `mip`, `xsens` or `vectornav` (default: probed; with
    /// --sim, the simulated device's protocol too).
    #[arg(long, value_name = "PROTOCOL")]
    protocol: Option<imu_proto::DeviceProtocol>,
    /// Baud rate (overrides device.baud).
    #[arg(long, value_name = "N")]
    baud: Option<u32>,
    /// Send the unit nothing: take its stream as it is (set up with the vendor's tool, shared
    /// with another host, or a one-way tap); the same as `device.configure = false`.
    #[arg(long)]
    passive: bool,
    /// Where sample stamps come from: `host` (receive time as is), `device` (the device clock
    /// fitted to the host's) or `gnss` (wall stamps follow the unit's GNSS time); overrides
    /// device.time-source.
    #[arg(long, value_name = "host|device|gnss")]
    time_source: Option<imud::config::TimeSource>,
    /// Calibration file (overrides calibration.path).
    #[arg(long, value_name = "FILE")]
    calibration: Option<PathBuf>,
    /// MCAP log directory (overrides log.dir).
    #[arg(long, value_name = "DIR")]
    log_dir: Option<PathBuf>,
    /// Instance name (overrides name).
    #[arg(long, value_name = "NAME")]
    name: Option<String>,
    /// Serve imud's streams to other users' processes on this socket (overrides
    /// publish.readers-socket).
    #[arg(long, value_name = "PATH")]
    readers_socket: Option<PathBuf>,
    /// Run against a built-in virtual 3DM-GX1 on a pty instead of a real device; optionally with
    /// a scenario file (default: a built-in demo tour, then still forever). The simulator's
    /// ground truth is written next to the recordings.
    #[arg(long, value_name = "SCENARIO", num_args = 0..=1)]
    #[allow(clippy::option_option)]
    sim: Option<Option<PathBuf>>,
    /// With --sim: run the scenario through the real decode, calibration and logging path as fast
    /// as possible (no pty, no shared memory, synthetic timestamps), write the recording and the
    /// truth to the log directory, and exit. Hours of scenario take seconds.
    #[arg(long, requires = "sim")]
    offline: bool,
    /// Seed for --sim (default: the scenario's).
    #[arg(long, value_name = "N", requires = "sim")]
    seed: Option<u64>,
    /// Publish the ROS 2 topics over DDS (sets ros2.enabled; see the [ros2] section).
    #[arg(long)]
    ros2: bool,
    /// Take a live ROS 2 IMU as the device: subscribe to this sensor_msgs/msg/Imu topic over
    /// DDS (domain ros2.domain-id) instead of opening a serial unit (sets input.ros2-topic).
    #[arg(long, value_name = "TOPIC", conflicts_with_all = ["sim", "device", "protocol"])]
    ros2_input: Option<String>,
    /// Print the effective configuration and exit.
    #[arg(long)]
    print_config: bool,
}

#[derive(Debug, clap::Subcommand)]
enum Command {
    /// Repair recordings whose writer died (kill -9, power loss), like `ros2 bag reindex`.
    ///
    /// Every complete record is rewritten with summary, index and footer, so every MCAP reader
    /// opens the file with its default options. The repaired file is verified before it
    /// replaces the original. Finished files are left as they are.
    Recover {
        /// MCAP recordings.
        #[arg(required = true, value_name = "FILE")]
        files: Vec<PathBuf>,
        /// Keep each original as FILE.orig.
        #[arg(long)]
        keep_original: bool,
    },
    /// Replay a byte capture through the same driver and pipeline as a live unit, with the same
    /// outputs: an imud recording (its /imu/raw_frame records, at their recorded host times:
    /// its /imu/data is reproduced bit for bit), a raw byte capture (.bin) or a hex dump (.hex,
    /// .txt), paced at the line's baud rate.
    Replay {
        /// The capture.
        #[arg(value_name = "FILE")]
        file: PathBuf,
        /// The pace: 1 as recorded, 10 ten times faster, max as fast as the CPU allows.
        #[arg(long, value_name = "1|10|max", default_value = "1")]
        speed: imud::replay::Speed,
        /// The calibration to correct with (a recording's own configuration's otherwise).
        #[arg(long, value_name = "FILE")]
        calibration: Option<PathBuf>,
        /// The protocol of a raw capture (default: recognised from its stream; a recording
        /// says its own).
        #[arg(long, value_name = "PROTOCOL")]
        protocol: Option<imu_proto::DeviceProtocol>,
        /// Configuration file (a recording's own configuration takes its place).
        #[arg(long, value_name = "FILE")]
        config: Option<PathBuf>,
        /// Line rate that paces a raw capture, bits/s (default: device.baud).
        #[arg(long, value_name = "N")]
        baud: Option<u32>,
        /// Directory for the replay's recording.
        #[arg(long, value_name = "DIR")]
        log_dir: Option<PathBuf>,
        /// Instance name of the replay's outputs.
        #[arg(long, value_name = "NAME")]
        name: Option<String>,
        /// Also publish the ROS 2 topics.
        #[arg(long)]
        ros2: bool,
    },
}

fn main() -> std::process::ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_env("IMUD_LOG")
                // rustdds (the ROS 2 output) logs protocol details at WARN (e.g. a peer that
                // advertises no usable locator); they are for debugging it, with IMUD_LOG.
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info,rustdds=error")),
        )
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    imu_bus::shm::quiet_iceoryx2_logs();
    imu_cli::main("imud", |args: Args| {
        if let Some(Command::Recover {
            files,
            keep_original,
        }) = &args.command
        {
            return Ok(recover_files(files, *keep_original));
        }
        if let Some(Command::Replay { .. }) = &args.command {
            replay_file(args)?;
            return Ok(std::process::ExitCode::SUCCESS);
        }
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .context("starting the runtime")?;
        runtime.block_on(run(args))?;
        Ok(std::process::ExitCode::SUCCESS)
    })
}

/// `imud recover FILE...`: one line per file on stdout; failures on stderr, the exit code of
/// the first (66 for a file that cannot be opened).
fn recover_files(files: &[PathBuf], keep_original: bool) -> std::process::ExitCode {
    let mut code = std::process::ExitCode::SUCCESS;
    let mut failed = false;
    for f in files {
        match imu_bus::recover::recover(f, keep_original) {
            Ok(None) => println!("{}: finished already, left as it is", f.display()),
            Ok(Some(r)) => println!("{}", recovered_line(&r)),
            Err(e) => {
                let e = anyhow::Error::new(e);
                eprintln!("imud: error: {e:#}");
                if !failed {
                    code = std::process::ExitCode::from(imu_cli::exit::exit_code_of(&e));
                    failed = true;
                }
            }
        }
    }
    code
}

fn recovered_line(r: &imu_bus::recover::Recovered) -> String {
    let until = r.last_log_time_ns.map_or("no message".into(), |t| {
        format!("up to log time {}", imu_cli::unfinished::utc_ms(t))
    });
    format!(
        "{}: repaired: {} messages and {} metadata records kept, {until}; {} -> {} bytes{} ({})",
        r.path.display(),
        r.n_messages,
        r.n_metadata,
        r.original_bytes,
        r.repaired_bytes,
        r.original_kept.as_ref().map_or(String::new(), |o| format!(
            "; original kept as {}",
            o.display()
        )),
        r.reason
    )
}

/// Repairs what a crash left unfinished in the log directory (this instance's files only: no
/// other process writes them; the recorder's file lock guards against one that does). Runs
/// before the simulator or the recorder create their files.
fn repair_log_dir(config: &Config) {
    let dir = &config.log.dir;
    if !config.log.enabled || !dir.is_dir() {
        return;
    }
    match imu_bus::recover::recover_dir(dir, &format!("{}-", config.name)) {
        Ok(results) => {
            for (path, result) in results {
                match result {
                    Ok(r) => info!("{}", recovered_line(&r)),
                    Err(e) => warn!(
                        "{}: cannot repair this unfinished recording: {:#}",
                        path.display(),
                        anyhow::Error::new(e)
                    ),
                }
            }
        }
        Err(e) => warn!(
            "cannot list {} for unfinished recordings: {e}",
            dir.display()
        ),
    }
}

fn effective_config(args: &Args) -> anyhow::Result<Config> {
    let (mut config, source) = Config::load(args.config.as_deref())?;
    if let Some(d) = &args.device {
        config.device.path = d.clone();
    }
    if let Some(p) = args.protocol {
        config.device.protocol = Some(p);
    }
    if let Some(b) = args.baud {
        config.device.baud = b;
    }
    if args.passive {
        config.device.configure = false;
    }
    if let Some(t) = args.time_source {
        config.device.time_source = t;
    }
    if let Some(c) = &args.calibration {
        config.calibration.path = Some(c.clone());
    }
    if let Some(l) = &args.log_dir {
        config.log.dir = l.clone();
    }
    if let Some(n) = &args.name {
        config.name = n.clone();
    }
    if let Some(r) = &args.readers_socket {
        config.publish.readers_socket = Some(r.clone());
    }
    if args.ros2 {
        config.ros2.enabled = true;
    }
    if let Some(t) = &args.ros2_input {
        config.input.ros2_topic = Some(t.clone());
    }
    config.validate(&config::Source {
        file: format!("{} with command-line flags", source.file),
        text: source.text.clone(),
    })?;
    info!("configuration from {}", source.file);
    Ok(config)
}

fn sim_options(
    scenario: Option<&std::path::Path>,
    seed: Option<u64>,
    protocol: Option<imu_proto::DeviceProtocol>,
) -> anyhow::Result<imu_sim::SimOptions> {
    let mut opts = if let Some(path) = scenario {
        imu_sim::SimOptions::from_files(path, None)?
    } else {
        let scenario = imu_sim::Scenario::from_toml_str(DEMO_SCENARIO, "built-in demo scenario")?;
        let truth =
            imu_model::Calibration::from_toml_str(DEMO_TRUTH, "built-in example truth model")?;
        let seed = scenario.seed;
        imu_sim::SimOptions {
            scenario,
            scenario_text: DEMO_SCENARIO.into(),
            truth,
            seed,
            truth_out: None,
            link: None,
            pacing: imu_sim::Pacing::RealTime,
            linger: Duration::from_secs(1),
        }
    };
    if let Some(seed) = seed {
        opts.seed = seed;
    }
    if let Some(p) = protocol {
        opts.scenario.set_protocol(p, "--protocol")?;
    }
    Ok(opts)
}

fn start_sim(mut opts: imu_sim::SimOptions, config: &Config) -> anyhow::Result<imu_sim::SimHandle> {
    if config.log.enabled {
        std::fs::create_dir_all(&config.log.dir)
            .with_context(|| format!("creating the log directory {}", config.log.dir.display()))?;
        let stamp = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs());
        opts.truth_out = Some(
            config
                .log
                .dir
                .join(format!("{}-sim-truth-{stamp}.mcap", config.name)),
        );
    }
    let opts_protocol = opts.scenario.device.protocol;
    let handle = imu_sim::spawn(opts)?;
    info!(
        "simulated {} device on {} (truth: {})",
        opts_protocol,
        handle.device_path().display(),
        config.log.dir.display()
    );
    Ok(handle)
}

async fn run(args: Args) -> anyhow::Result<()> {
    let mut config = effective_config(&args)?;
    if args.print_config {
        print!("{}", config.to_toml());
        return Ok(());
    }
    if args.offline {
        let mut opts = sim_options(
            args.sim.as_ref().and_then(|s| s.as_deref()),
            args.seed,
            args.protocol,
        )?;
        opts.truth_out = Some(config.log.dir.join(format!("{}-truth.mcap", config.name)));
        let report = imud::offline::record(opts, &config)?;
        for f in &report.files {
            println!("{}", f.display());
        }
        if let Some(t) = &report.truth {
            println!("{}", t.display());
        }
        info!(
            "offline: {} samples and {} temperatures recorded",
            report.samples, report.temperatures
        );
        if report.dropped > 0 {
            info!(
                "offline: {} samples lost in the scenario's link dropouts ({} counted lost from \
                 the device clock; the truth has them all)",
                report.dropped, report.samples_lost
            );
        }
        return Ok(());
    }
    if args.sim.is_some()
        && let Some(topic) = &config.input.ros2_topic
    {
        anyhow::bail!(
            "--sim simulates a serial unit, but the configuration takes the ROS 2 topic {topic} \
             as the device (input.ros2-topic): run one or the other"
        );
    }
    repair_log_dir(&config);
    let _sim = match &args.sim {
        Some(scenario) => {
            let opts = sim_options(scenario.as_deref(), args.seed, args.protocol)?;
            // The daemon speaks what the simulated device speaks (no probe needed).
            config.device.protocol = Some(opts.scenario.device.protocol);
            let h = start_sim(opts, &config)?;
            config.device.path = h.device_path().to_path_buf();
            Some(h)
        }
        None => None,
    };
    let mut signals = Signals::install()?;

    let mut daemon = build_daemon(config, Vec::new())?;
    // A ROS 2 input's participant is made now, so a DDS problem is a start-up error (a replay
    // makes none: its frames come from the file).
    if let Some(topic) = &daemon.config.input.ros2_topic {
        daemon.input_link = Some(
            imud::ros2::input::Ros2InputLink::new(&daemon.config.ros2, topic)
                .context("starting the ROS 2 (DDS) input")?,
        );
    }
    daemon.load_initial_calibration()?;
    let result = daemon.run(&mut signals).await;
    info!("shutting down");
    finish_outputs(&mut daemon);
    result
}

/// The outputs `config` asks for; `extra` metadata is recorded with the configuration.
fn open_sinks(
    config: &Config,
    extra: Vec<(String, BTreeMap<String, String>)>,
) -> anyhow::Result<Sinks> {
    let publishers = if config.publish.enabled {
        let options = ShmOptions {
            subscriber_buffer_size: config.publish.subscriber_buffer,
            history_size: config.publish.history,
            max_subscribers: config.publish.max_subscribers,
        };
        Some(
            Publishers::open(&config.name, &options)
                .context("opening the shared-memory services")?,
        )
    } else {
        None
    };
    let readers = match config.publish.readers_socket_path(&config.name) {
        Some(path) => Some(
            imud::pipeline::readers::ReadersServer::open(&path, config.publish.group.as_deref())
                .context("opening the readers' socket")?,
        ),
        None => None,
    };
    let recorder = if config.log.enabled {
        let rc = RecordingConfig {
            dir: config.log.dir.clone(),
            prefix: config.name.clone(),
            rotate_size_bytes: config.log.rotate_size_mib * 1024 * 1024,
            rotate_interval_s: config.log.rotate_interval_s,
            queue_capacity: config.log.queue_capacity,
            frame_id: config.log.frame_id.clone(),
            ..RecordingConfig::default()
        };
        let mut metadata = vec![(
            "imud.config".to_string(),
            BTreeMap::from([("toml".to_string(), config.to_toml())]),
        )];
        metadata.extend(extra);
        Some(Recorder::start(rc, metadata).context("starting the MCAP recorder")?)
    } else {
        None
    };
    let ros2 = if config.ros2.enabled {
        Some(
            imud::ros2::Ros2Sink::start(&config.ros2, &config.log.frame_id, &config.name)
                .context("starting the ROS 2 (DDS) output")?,
        )
    } else {
        None
    };
    Ok(Sinks {
        publishers,
        readers,
        recorder,
        ros2,
    })
}

/// The daemon for `config`: its outputs, its device's driver, the pipeline.
fn build_daemon(
    config: Config,
    extra: Vec<(String, BTreeMap<String, String>)>,
) -> anyhow::Result<Daemon> {
    let sinks = open_sinks(&config, extra)?;
    let device = Device::new(&config);
    let mut pipeline = Pipeline::new(device.initial_session(), None);
    pipeline.set_health(Some(config.health.clone()));
    pipeline.set_time_source(config.device.time_source);
    // The metadata's `path`: the device's, or the ROS 2 input's topic.
    let device_path = match &config.input.ros2_topic {
        Some(topic) => PathBuf::from(topic),
        None => config.device.path.clone(),
    };
    Ok(Daemon {
        calibration: CalibrationSource::new(
            config.calibration.path.clone(),
            config.calibration.watch,
        ),
        config,
        sinks,
        pipeline,
        device,
        reconnects: 0,
        notified_ready: false,
        on_identity: Box::new(move |id: &DeviceIdentity, sinks: &Sinks| {
            if let Some(r) = &sinks.recorder {
                r.update_metadata("imud.device", id.metadata(&device_path));
            }
        }),
        calibration_noise_pending: false,
        input_link: None,
    })
}

/// Finishes the recording and the ROS 2 output, saying what they wrote.
fn finish_outputs(daemon: &mut Daemon) {
    if let Some(r) = daemon.sinks.recorder.take() {
        match r.finish() {
            Ok(stats) => info!(
                "MCAP log finished: {} records written, {} dropped",
                stats.written,
                stats.dropped_queue_full + stats.dropped_not_logging
            ),
            Err(e) => warn!("finishing the MCAP log failed: {e:#}"),
        }
    }
    if let Some(d) = daemon.sinks.ros2.take() {
        let s = d.finish();
        info!(
            "ROS 2 output finished: {} DDS messages written, {} dropped (queue full), {} refused, \
             {} not sent (no reader matched)",
            s.written, s.dropped_queue_full, s.write_failures, s.not_sent_unmatched
        );
    }
}

/// `imud replay`: the capture through a passive device, its outputs as a live run's.
fn replay_file(args: Args) -> anyhow::Result<()> {
    let Some(Command::Replay {
        file,
        speed,
        calibration,
        protocol,
        config,
        baud,
        log_dir,
        name,
        ros2,
    }) = args.command
    else {
        unreachable!("called for the replay subcommand");
    };
    let (base, source) = Config::load(config.as_deref())?;
    let baud = baud.unwrap_or(base.device.baud);
    let capture = imud::replay::Capture::read(&file, baud, imud::replay::start_times())?;
    let mut config = capture.config(&base)?;
    config.device.path = file.clone();
    if let Some(p) = protocol {
        config.device.protocol = Some(p);
    }
    if let Some(c) = calibration {
        config.calibration.path = Some(c);
    }
    config.calibration.watch = false;
    if let Some(l) = log_dir {
        config.log.dir = l;
    }
    if let Some(n) = name {
        config.name = n;
    }
    if ros2 {
        config.ros2.enabled = true;
    }
    // Checked as a configured unit: polling is refused only for a live passive one.
    let mut checked = config.clone();
    checked.device.configure = true;
    checked.validate(&config::Source {
        file: format!("{} with command-line flags", source.file),
        text: source.text.clone(),
    })?;
    let metadata = vec![(
        "imud.replay".to_string(),
        BTreeMap::from([
            ("source".to_string(), file.display().to_string()),
            (
                "kind".to_string(),
                format!("{:?}", capture.kind).to_lowercase(),
            ),
            ("speed".to_string(), format!("{speed:?}")),
        ]),
    )];
    let mut daemon = build_daemon(config, metadata)?;
    daemon.load_initial_calibration()?;
    let result = daemon.replay(&capture, speed);
    finish_outputs(&mut daemon);
    let report = result?;
    info!(
        "replayed {}: {} reads, {} samples",
        file.display(),
        report.chunks,
        report.samples
    );
    Ok(())
}
