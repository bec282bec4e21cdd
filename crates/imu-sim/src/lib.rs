//! imu-sim: a virtual MicroStrain 3DM-GX1 (or MIP unit) on a pseudo-terminal, driven by known
//! physics and a known error model, that writes down the truth behind every reply.
//!
//! - [`scenario`]: the TOML scenario format (the paper's tests as segments).
//! - [`motion`]: exact analytic motion (orientation, rates, specific force) over time.
//! - [`device`]: the sans-IO device: commands in, replies and truth out (3DM-GX1), and the
//!   physics and truth every protocol shares; [`mip_device`]: the same device speaking MIP;
//!   [`vectornav_device`]: the same device speaking VectorNav's protocol;
//!   [`virtual_device`]: the enum over the protocols that the link runs.
//! - [`link`]: the pty and the loop that paces replies in real time or as fast as the host reads.
//!
//! [`spawn`] runs all of it on a thread and returns once the device path exists, so the daemon
//! (`imud --sim`) and tests can embed a simulator; the `imu-sim` binary is a thin front end.

pub mod device;
pub mod export;
pub mod link;
pub mod mip_device;
pub mod motion;
pub mod scenario;
pub mod tremor;
pub mod vectornav_device;
pub mod virtual_device;
pub mod xsens_device;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use imu_model::Calibration;
use imu_rec::truth::{TruthSegment, TruthWriter};

pub use device::DeviceCore;
pub use link::{LinkReport, Pacing};
pub use scenario::Scenario;
pub use virtual_device::VirtualDevice;

/// Errors starting or running the simulator.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// The scenario file is unusable.
    #[error(transparent)]
    Scenario(#[from] scenario::ScenarioError),
    /// The truth model file is unusable.
    #[error(transparent)]
    Model(#[from] imu_model::ModelError),
    /// The pty could not be set up.
    #[error(transparent)]
    Link(#[from] link::LinkError),
    /// The truth file could not be written.
    #[error(transparent)]
    Truth(#[from] imu_rec::truth::TruthWriteError),
    /// I/O on the pty failed while running.
    #[error("virtual device I/O failed")]
    Io(#[from] std::io::Error),
    /// A text export could not be made.
    #[error("{path}: cannot export: {message}")]
    Export {
        /// The export directory.
        path: PathBuf,
        /// Why.
        message: String,
    },
    /// A stable device link could not be made.
    #[error("{path}: cannot create the device link: {message}")]
    DeviceLink {
        /// The requested link path.
        path: PathBuf,
        /// Why.
        message: String,
    },
}

/// Everything one simulator run needs.
#[derive(Debug, Clone)]
pub struct SimOptions {
    /// The scenario.
    pub scenario: Scenario,
    /// Its text (stored in the truth file so a run can be reproduced).
    pub scenario_text: String,
    /// The truth error model.
    pub truth: Calibration,
    /// Random seed for the noise and random poses.
    pub seed: u64,
    /// Where to write the truth MCAP file, if anywhere.
    pub truth_out: Option<PathBuf>,
    /// A stable symlink to the device path, if wanted (e.g. `/tmp/imu-sim0`).
    pub link: Option<PathBuf>,
    /// Real time or fast.
    pub pacing: Pacing,
    /// How long to wait at the end for the host to read the last bytes.
    pub linger: Duration,
}

impl SimOptions {
    /// Loads a scenario file and the truth model it names (or `truth_override`, or a perfect
    /// sensor when neither is given).
    pub fn from_files(
        scenario_path: &Path,
        truth_override: Option<&Path>,
    ) -> Result<Self, SimError> {
        let file = scenario_path.display().to_string();
        let scenario_text = std::fs::read_to_string(scenario_path).map_err(|source| {
            scenario::ScenarioError::Io {
                file: file.clone(),
                source,
            }
        })?;
        let scenario = Scenario::from_toml_str(&scenario_text, &file)?;
        let truth_path = match (truth_override, &scenario.truth) {
            (Some(p), _) => Some(p.to_path_buf()),
            (None, Some(rel)) => Some(scenario_path.parent().unwrap_or(Path::new(".")).join(rel)),
            (None, None) => None,
        };
        let truth = match truth_path {
            Some(p) => Calibration::load(&p)?,
            None => Calibration::identity(),
        };
        let seed = scenario.seed;
        Ok(Self {
            scenario,
            scenario_text,
            truth,
            seed,
            truth_out: None,
            link: None,
            pacing: Pacing::RealTime,
            linger: Duration::from_secs(5),
        })
    }
}

/// A running simulator.
pub struct SimHandle {
    device_path: PathBuf,
    stop: Arc<AtomicBool>,
    unplug_ms: Arc<AtomicU64>,
    inject: Arc<std::sync::Mutex<Vec<u8>>>,
    thread: Option<JoinHandle<Result<LinkReport, SimError>>>,
}

impl SimHandle {
    /// The path a host opens: the stable link if one was asked for, else the pty slave.
    pub fn device_path(&self) -> &Path {
        &self.device_path
    }

    /// Asks the simulator to stop (the truth file is still finished properly).
    pub fn stop(&self) {
        self.stop.store(true, Ordering::Relaxed);
    }

    /// Simulates pulling the device's cable for `off`: the pty closes, then a new one appears
    /// (at the same `link` path, if the simulator has one).
    pub fn unplug(&self, off: Duration) {
        self.unplug_ms
            .store(off.as_millis().max(1) as u64, Ordering::Relaxed);
    }

    /// Puts `bytes` on the line before the next streamed reply (line noise); the host's decoder
    /// must skip and count them.
    pub fn inject(&self, bytes: &[u8]) {
        if let Ok(mut q) = self.inject.lock() {
            q.extend_from_slice(bytes);
        }
    }

    /// True once the simulator thread has ended.
    pub fn is_finished(&self) -> bool {
        self.thread.as_ref().is_none_or(JoinHandle::is_finished)
    }

    /// Waits for the run to end and returns what it did.
    pub fn join(mut self) -> Result<LinkReport, SimError> {
        self.join_inner()
    }

    fn join_inner(&mut self) -> Result<LinkReport, SimError> {
        match self.thread.take() {
            Some(t) => t.join().unwrap_or_else(|_| {
                Err(SimError::Io(std::io::Error::other(
                    "simulator thread panicked",
                )))
            }),
            None => Ok(LinkReport::default()),
        }
    }
}

impl Drop for SimHandle {
    fn drop(&mut self) {
        self.stop();
        let _ = self.join_inner();
    }
}

/// The truth-file record of a scenario segment.
pub fn segment_record(s: &motion::SegmentInfo) -> TruthSegment {
    TruthSegment {
        index: s.index,
        kind: s.kind.clone(),
        label: s.label.clone(),
        start_s: s.start_s,
        end_s: s.end_s,
        gravity_dir_sensor: s.gravity_dir_sensor.into(),
        axis_sensor: s.axis_sensor.map(Into::into),
        table_rate_rad_s: s.table_rate_rad_s,
    }
}

/// The truth file's run metadata key of the link's dropout windows ([`dropouts_text`]).
pub const DROPOUTS_KEY: &str = "dropouts-s";

/// The link's dropout windows of `timeline` as the truth's run metadata says them:
/// `start..end` in scenario seconds, comma-separated (empty without any); the data samples of
/// the truth inside them never reached the host.
pub fn dropouts_text(timeline: &motion::Timeline) -> String {
    timeline
        .dropouts()
        .iter()
        .map(|d| format!("{}..{}", d.start_s, d.end_s))
        .collect::<Vec<_>>()
        .join(",")
}

/// The run identity stored in the truth file.
fn run_metadata(opts: &SimOptions, device_path: &Path) -> BTreeMap<String, String> {
    let s = &opts.scenario;
    BTreeMap::from([
        ("scenario-name".into(), s.name.clone()),
        ("seed".into(), opts.seed.to_string()),
        ("rate-hz".into(), s.rate_hz.to_string()),
        ("tick-period-s".into(), s.device.tick_period_s.to_string()),
        (
            "clock-drift-ppm".into(),
            s.device.clock_drift_ppm.to_string(),
        ),
        ("protocol".into(), s.device.protocol.to_string()),
        ("serial-number".into(), s.device.serial_number.to_string()),
        ("firmware".into(), s.device.firmware.to_string()),
        (
            "power-up-streaming".into(),
            s.device.power_up_streaming.to_string(),
        ),
        // A sample's true GNSS time is gnss-epoch-utc-s + its truth `t_s`.
        ("gnss-time".into(), s.device.gnss_time.to_string()),
        (
            "gnss-epoch-utc-s".into(),
            s.device.gnss_epoch_utc_s.to_string(),
        ),
        (
            "gnss-outages-s".into(),
            s.device
                .gnss_outage
                .iter()
                .map(|o| format!("{}..{}", o.start_s, o.end_s))
                .collect::<Vec<_>>()
                .join(","),
        ),
        (
            "gain-scale-accel".into(),
            s.device.gain_scale.accel.to_string(),
        ),
        (
            "gain-scale-gyro".into(),
            s.device.gain_scale.gyro.to_string(),
        ),
        ("gain-scale-mag".into(), s.device.gain_scale.mag.to_string()),
        ("gravity-m-s2".into(), s.gravity_m_s2.to_string()),
        ("latitude-deg".into(), s.latitude_deg.to_string()),
        ("pacing".into(), format!("{:?}", opts.pacing).to_lowercase()),
        ("device-path".into(), device_path.display().to_string()),
        ("imu-sim-version".into(), env!("CARGO_PKG_VERSION").into()),
    ])
}

/// Starts a simulator on a new pty and returns once its device path is ready.
pub fn spawn(opts: SimOptions) -> Result<SimHandle, SimError> {
    let mut pty = link::Pty::open()?;
    let device_path = device_path(&opts, pty.slave_path())?;
    let core = DeviceCore::new(opts.scenario.clone(), opts.truth.clone(), opts.seed);
    let writer = open_truth(&opts, &core, &device_path)?;
    let mut device = VirtualDevice::new(opts.scenario.device.protocol, core);
    let stop = Arc::new(AtomicBool::new(false));
    let stop_thread = stop.clone();
    let link_path = opts.link.clone();
    let unplug_ms = Arc::new(AtomicU64::new(0));
    let inject = Arc::new(std::sync::Mutex::new(Vec::new()));
    let link_options = link::LinkOptions {
        pacing: opts.pacing,
        linger: opts.linger,
        link: opts.link.clone(),
        unplug_ms: unplug_ms.clone(),
        inject: inject.clone(),
    };
    let thread = std::thread::Builder::new()
        .name("imu-sim".into())
        .spawn(move || {
            let (tx, rx) = mpsc::sync_channel(8192);
            let writer_thread = writer.map(|w| truth_thread(w, rx));
            let sender = writer_thread.as_ref().map(|_| &tx);
            let result = link::run(&mut pty, &mut device, sender, link_options, &stop_thread);
            drop(tx);
            let truth_result = writer_thread
                .map(|t| {
                    t.join().unwrap_or_else(|_| {
                        Err(SimError::Io(std::io::Error::other("truth writer panicked")))
                    })
                })
                .unwrap_or(Ok(()));
            if let Some(l) = &link_path {
                let _ = std::fs::remove_file(l);
            }
            let report = result?;
            truth_result?;
            Ok(report)
        })
        .map_err(SimError::Io)?;
    Ok(SimHandle {
        device_path,
        stop,
        unplug_ms,
        inject,
        thread: Some(thread),
    })
}

/// The path a host opens: the stable link (made now) if one was asked for, else the pty slave.
fn device_path(opts: &SimOptions, slave: &Path) -> Result<PathBuf, SimError> {
    match &opts.link {
        Some(l) => {
            link::make_link(l, slave).map_err(|e| SimError::DeviceLink {
                path: l.clone(),
                message: e.to_string(),
            })?;
            Ok(l.clone())
        }
        None => Ok(slave.to_path_buf()),
    }
}

/// Creates the truth file, if one was asked for, with the run's identity and segments.
fn open_truth(
    opts: &SimOptions,
    core: &DeviceCore,
    device_path: &Path,
) -> Result<Option<TruthWriter>, SimError> {
    let Some(path) = &opts.truth_out else {
        return Ok(None);
    };
    let mut run = run_metadata(opts, device_path);
    run.insert(DROPOUTS_KEY.into(), dropouts_text(core.timeline()));
    let mut w = TruthWriter::create(
        path,
        &run,
        &opts.scenario_text,
        &opts.truth.to_toml_string(),
    )?;
    for s in core.timeline().segments() {
        w.write_segment(&segment_record(s))?;
    }
    w.flush()?;
    Ok(Some(w))
}

/// The truth file is written on its own thread so that disk latency never delays a reply; it
/// is flushed at least twice a second so a killed run leaves a readable file.
fn truth_thread(
    mut w: TruthWriter,
    rx: mpsc::Receiver<imu_rec::truth::TruthSample>,
) -> JoinHandle<Result<(), SimError>> {
    std::thread::spawn(move || -> Result<(), SimError> {
        let mut last_flush = Instant::now();
        loop {
            match rx.recv_timeout(Duration::from_millis(200)) {
                Ok(sample) => w.write_sample(&sample)?,
                Err(mpsc::RecvTimeoutError::Timeout) => {}
                Err(mpsc::RecvTimeoutError::Disconnected) => break,
            }
            if last_flush.elapsed() >= Duration::from_millis(500) {
                w.flush()?;
                last_flush = Instant::now();
            }
        }
        w.finish()?;
        Ok(())
    })
}
