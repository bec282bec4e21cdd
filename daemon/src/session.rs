//! The device session: open the port, run the device's driver (start-up, then streaming or
//! polling), detect loss, reconnect with backoff, and keep status, signals and calibration
//! reloads served throughout.
//!
//! This is the only async code in the workspace, and it knows no protocol: one loop over any
//! `AsyncRead + AsyncWrite` owns the port and the clock, feeds what it reads to the
//! [`Driver`](crate::drivers::Driver), writes what the driver asks, calls it back on its
//! deadlines and hands its events to the pipeline. One task owns the port, the driver and the
//! pipeline, so the per-frame path never crosses a thread; the MCAP writer has its own thread.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use anyhow::{Context, anyhow};
use imu_bus::recording::LogRecord;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::signal::unix::{Signal, SignalKind, signal};
use tokio_serial::SerialPortBuilderExt;
use tracing::{error, info, warn};

use crate::config::Config;
pub use crate::drivers::DeviceIdentity;
use crate::drivers::{Device, Driver, DriverEvent, FrameSlot};
use crate::pipeline::{ActiveCalibration, Pipeline, Sinks, log_rejected};
use crate::ros2::input::Ros2InputLink;

/// Host clocks now: (CLOCK_MONOTONIC ns, Unix wall-clock ns). CLOCK_MONOTONIC is system-wide, so
/// a subscriber in another process can compare its own receipt time with a sample's.
pub fn now_ns() -> (u64, u64) {
    let mono = nix::time::clock_gettime(nix::time::ClockId::CLOCK_MONOTONIC).map_or(0, |t| {
        t.tv_sec() as u64 * 1_000_000_000 + t.tv_nsec() as u64
    });
    let wall = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64);
    (mono, wall)
}

/// Signals the daemon reacts to.
pub struct Signals {
    hup: Signal,
    term: Signal,
    int: Signal,
}

impl Signals {
    /// Installs the handlers.
    pub fn install() -> anyhow::Result<Self> {
        Ok(Self {
            hup: signal(SignalKind::hangup()).context("installing the SIGHUP handler")?,
            term: signal(SignalKind::terminate()).context("installing the SIGTERM handler")?,
            int: signal(SignalKind::interrupt()).context("installing the SIGINT handler")?,
        })
    }
}

/// The calibration file and what is in force.
pub struct CalibrationSource {
    path: Option<PathBuf>,
    watch: bool,
    modified: Option<SystemTime>,
}

impl CalibrationSource {
    /// Watches `path` (if any).
    pub fn new(path: Option<PathBuf>, watch: bool) -> Self {
        Self {
            path,
            watch,
            modified: None,
        }
    }

    fn mtime(&self) -> Option<SystemTime> {
        self.path
            .as_ref()
            .and_then(|p| std::fs::metadata(p).ok())
            .and_then(|m| m.modified().ok())
    }

    /// Loads the file; an invalid file is reported and `None` returned (the caller keeps the
    /// previous calibration).
    pub fn load(&mut self) -> Option<Arc<ActiveCalibration>> {
        let path = self.path.as_ref()?;
        self.modified = self.mtime();
        match imu_model::Calibration::load(path) {
            Ok(model) => Some(Arc::new(ActiveCalibration::new(model))),
            Err(e) => {
                error!(
                    "calibration rejected, the previous one stays in force: {}",
                    error_chain(e)
                );
                None
            }
        }
    }

    /// True when the watched file changed since the last load.
    fn changed(&self) -> bool {
        self.watch && self.path.is_some() && self.mtime() != self.modified
    }
}

/// An error with all its causes, e.g. the OS reason of an unreadable file (the error's source).
pub fn error_chain(e: impl std::error::Error + Send + Sync + 'static) -> String {
    format!("{:#}", anyhow::Error::new(e))
}

/// What a session reads from and writes to: a serial port, or a ROS 2 input's reader.
pub trait Port: AsyncRead + AsyncWrite + Unpin {}
impl<T: AsyncRead + AsyncWrite + Unpin> Port for T {}

/// Everything the run loop owns.
pub struct Daemon {
    /// Effective configuration.
    pub config: Config,
    /// Outputs.
    pub sinks: Sinks,
    /// The per-frame state.
    pub pipeline: Pipeline,
    /// The device's driver (kept across reconnects so its counters are cumulative).
    pub device: Device,
    /// The calibration source.
    pub calibration: CalibrationSource,
    /// Reconnects so far.
    pub reconnects: u64,
    /// Set once readiness was sent to systemd.
    pub notified_ready: bool,
    /// Called with the identity once the device first answers (metadata, readiness).
    pub on_identity: IdentityHook,
    /// The calibration was logged before the data rate was known.
    pub calibration_noise_pending: bool,
    /// The DDS participant of a ROS 2 input (`input.ros2-topic`), made at start-up (or by the
    /// first session) and kept: each session opens a reader on it.
    pub input_link: Option<Ros2InputLink>,
}

/// Called with the device identity each time the device answers its start-up sequence.
pub type IdentityHook = Box<dyn FnMut(&DeviceIdentity, &Sinks)>;

/// Why a session ended.
pub enum SessionEnd {
    /// A shutdown signal.
    Shutdown,
    /// The device was lost (or its start-up failed).
    Lost(anyhow::Error),
}

impl Daemon {
    fn put_calibration(&mut self, cal: Arc<ActiveCalibration>) {
        let from_seq = self.pipeline.set_calibration(Some(cal.clone()));
        info!(
            "calibration {:016x} in force from sample {from_seq} ({})",
            cal.id,
            self.calibration
                .path
                .as_ref()
                .map_or(String::new(), |p| p.display().to_string())
        );
        let (_, wall) = now_ns();
        let rate = self.sample_rate_hz();
        self.sinks.log_calibration(wall, &cal, rate);
        // Without a known data rate the covariances stay unknown; log again once it is measured.
        self.calibration_noise_pending = rate.is_none();
    }

    /// The data rate: the poll rate when the host polls, measured when the device streams (the
    /// session's acquisition as its driver set it up, not the configured mode).
    pub fn sample_rate_hz(&self) -> Option<f64> {
        self.pipeline.sample_rate_hz()
    }

    /// Loads the configured calibration at start-up; an invalid file is a start-up error.
    pub fn load_initial_calibration(&mut self) -> anyhow::Result<()> {
        if let Some(path) = self.calibration.path.clone() {
            let model = imu_model::Calibration::load(&path)?;
            self.calibration.modified = self.calibration.mtime();
            self.put_calibration(Arc::new(ActiveCalibration::new(model)));
        } else {
            warn!(
                "no calibration configured: the corrected stream uses the device's GainScales only (flag UNCALIBRATED)"
            );
        }
        Ok(())
    }

    fn reload_calibration(&mut self, why: &str) {
        info!("reloading the calibration ({why})");
        if let Some(cal) = self.calibration.load() {
            self.put_calibration(cal);
        }
    }

    fn publish_status(&mut self, connected: bool) {
        let (mono, wall) = now_ns();
        self.publish_status_at(connected, mono, wall);
    }

    /// Publishes, records and sends the status at the host times given (a replay's are the
    /// recording's).
    pub(crate) fn publish_status_at(&mut self, connected: bool, mono: u64, wall: u64) {
        let mut status = self.pipeline.status(
            &self.device.stats(),
            &self.sinks,
            self.reconnects,
            connected,
            mono,
        );
        if let Some(d) = &self.sinks.ros2 {
            // DDS messages lost are publishing drops too; /diagnostics carries the status.
            status.publish_drops += d.drops();
            d.status(wall, &status);
        }
        if let Some(r) = &mut self.sinks.readers {
            r.send(&status);
        }
        if let Some(p) = &mut self.sinks.publishers {
            let _ = p.publish_status(&status);
            let _ = p.notify(imu_bus::shm::ShmEvent::Status);
            // Subscribers killed with SIGKILL keep their slots until someone cleans up.
            let removed = p.cleanup_dead_nodes();
            if removed > 0 {
                info!("removed {removed} dead shared-memory node(s)");
            }
        }
        if let Some(r) = &self.sinks.recorder {
            let _ = r.log(LogRecord::Status {
                t_wall_ns: wall,
                status,
            });
        }
        let _ = sd_notify::notify(false, &[sd_notify::NotifyState::Watchdog]);
        if self.calibration_noise_pending
            && let (Some(rate), Some(cal)) = (self.sample_rate_hz(), self.pipeline.calibration())
        {
            self.sinks.log_calibration(wall, cal, Some(rate));
            self.calibration_noise_pending = false;
        }
    }

    /// Hands every event the driver has to the pipeline (frames logged, readings published),
    /// the session's start and its identity included. Returns how start-up ended, if it did.
    fn take_events(&mut self) -> Option<Result<(), anyhow::Error>> {
        let (mono, wall) = now_ns();
        self.take_events_at(mono, wall)
    }

    /// [`Self::take_events`] with the host times given (a replay's are the recording's).
    pub(crate) fn take_events_at(
        &mut self,
        mono: u64,
        wall: u64,
    ) -> Option<Result<(), anyhow::Error>> {
        let mut ended = None;
        let mut slot = FrameSlot::default();
        while let Some(ev) = self.device.poll_event(&mut slot) {
            match ev {
                DriverEvent::Frame => {
                    self.pipeline
                        .on_frame(&mut slot, mono, wall, &mut self.sinks);
                }
                DriverEvent::Rejected {
                    bytes,
                    offset,
                    reason,
                } => log_rejected(bytes, offset, reason, mono, wall, &self.sinks),
                DriverEvent::Session(spec) => self.pipeline.new_session(spec),
                DriverEvent::Identified(identity) => (self.on_identity)(&identity, &self.sinks),
                DriverEvent::Ready => ended = Some(Ok(())),
                DriverEvent::Failed(e) => ended = Some(Err(e)),
            }
        }
        ended
    }

    /// Opens the device's port: the serial line, or a new reader of the ROS 2 input.
    fn open(&mut self) -> anyhow::Result<Box<dyn Port>> {
        if let Some(topic) = &self.config.input.ros2_topic {
            let link = match &mut self.input_link {
                Some(link) => link,
                None => self
                    .input_link
                    .insert(Ros2InputLink::new(&self.config.ros2, topic)?),
            };
            return Ok(Box::new(link.open()?));
        }
        let cfg = &self.config.device;
        let port = tokio_serial::new(cfg.path.to_string_lossy(), cfg.baud)
            .open_native_async()
            .with_context(|| format!("opening {}", cfg.path.display()))?;
        Ok(Box::new(port))
    }

    /// Runs until SIGTERM/SIGINT: sessions with reconnects in between.
    pub async fn run(&mut self, signals: &mut Signals) -> anyhow::Result<()> {
        let cfg = self.config.device.clone();
        let mut backoff = Duration::from_secs_f64(cfg.reconnect_min_s);
        let mut had_session = false;
        loop {
            let end = match self.open() {
                Ok(port) => {
                    let mut link = SessionLink {
                        had_session: &mut had_session,
                        backoff: &mut backoff,
                    };
                    self.session(port, signals, &mut link).await
                }
                Err(e) => SessionEnd::Lost(e),
            };
            self.device.flush();
            let _ = self.take_events();
            match end {
                SessionEnd::Shutdown => {
                    // A last status, so the recording ends with the final counters.
                    self.publish_status(false);
                    return Ok(());
                }
                SessionEnd::Lost(e) => {
                    warn!(
                        "device {} unavailable: {e:#}; retrying in {:.1} s",
                        self.config.input_name(),
                        backoff.as_secs_f64()
                    );
                }
            }
            // Wait for the next attempt while still serving status and signals.
            let deadline = tokio::time::Instant::now() + backoff;
            let mut status = tokio::time::interval(Duration::from_secs_f64(
                self.config.publish.status_interval_s,
            ));
            loop {
                tokio::select! {
                    _ = tokio::time::sleep_until(deadline) => break,
                    _ = status.tick() => self.publish_status(false),
                    _ = signals.hup.recv() => self.reload_calibration("SIGHUP"),
                    _ = signals.term.recv() => return Ok(()),
                    _ = signals.int.recv() => return Ok(()),
                }
            }
            backoff = (backoff * 2).min(Duration::from_secs_f64(cfg.reconnect_max_s));
        }
    }

    /// Start-up is done: a reconnect counted (a session that follows a lost one, not a failed
    /// attempt), the back-off reset, readiness sent once.
    fn on_ready(&mut self, link: &mut SessionLink<'_>) {
        let cfg = &self.config.device;
        if *link.had_session {
            self.reconnects += 1;
            info!(
                "device {} is back (reconnect {})",
                self.config.input_name(),
                self.reconnects
            );
        }
        *link.had_session = true;
        *link.backoff = Duration::from_secs_f64(cfg.reconnect_min_s);
        if !self.notified_ready {
            let _ = sd_notify::notify(false, &[sd_notify::NotifyState::Ready]);
            self.notified_ready = true;
        }
    }

    /// Writes everything the driver has to send.
    async fn transmit<W: AsyncWrite + Unpin>(
        &mut self,
        port: &mut W,
        out: &mut Vec<u8>,
    ) -> anyhow::Result<()> {
        out.clear();
        while self.device.poll_transmit(out) {}
        if !out.is_empty() {
            port.write_all(out).await.context("writing to the device")?;
        }
        Ok(())
    }

    /// One session on an open port: the driver's start-up, then streaming (or polling) until
    /// the device is lost or a shutdown signal arrives. Knows no protocol.
    async fn session<P: AsyncRead + AsyncWrite + Unpin>(
        &mut self,
        port: P,
        signals: &mut Signals,
        link: &mut SessionLink<'_>,
    ) -> SessionEnd {
        let (mut rd, mut wr) = tokio::io::split(port);
        let cfg = self.config.device.clone();
        self.device.start(std::time::Instant::now());
        let mut ready = false;
        let mut status = tokio::time::interval(Duration::from_secs_f64(
            self.config.publish.status_interval_s,
        ));
        let mut watch = tokio::time::interval(Duration::from_secs(1));
        let silence = Duration::from_secs_f64(cfg.silence_timeout_s);
        let mut buf = vec![0u8; 8192];
        let mut out = Vec::with_capacity(512);
        let mut last_bytes = tokio::time::Instant::now();
        // A shutdown asked during start-up takes effect when start-up ends (done or failed),
        // so the recording and the status say which device and gains it was.
        let mut shutdown = false;
        loop {
            match self.take_events() {
                Some(Ok(())) => {
                    ready = true;
                    last_bytes = tokio::time::Instant::now();
                    self.on_ready(link);
                }
                Some(Err(e)) if shutdown => {
                    warn!("start-up ended by the shutdown: {e:#}");
                    return SessionEnd::Shutdown;
                }
                Some(Err(e)) => return SessionEnd::Lost(e),
                None => {}
            }
            if shutdown && ready {
                self.stop_device(&mut wr).await;
                return SessionEnd::Shutdown;
            }
            if let Err(e) = self.transmit(&mut wr, &mut out).await {
                return SessionEnd::Lost(e);
            }
            let deadline = self.device.poll_timeout();
            let sleep = tokio::time::sleep_until(
                deadline.map_or_else(far_future, tokio::time::Instant::from_std),
            );
            tokio::select! {
                read = rd.read(&mut buf) => match read {
                    Ok(0) => return SessionEnd::Lost(anyhow!("the device closed the line")),
                    Ok(n) => {
                        last_bytes = tokio::time::Instant::now();
                        self.device.handle_input(&buf[..n], std::time::Instant::now());
                    }
                    Err(e) => return SessionEnd::Lost(anyhow!(e).context("reading from the device")),
                },
                _ = sleep, if deadline.is_some() => {
                    self.device.handle_timeout(std::time::Instant::now());
                }
                _ = status.tick() => {
                    self.publish_status(ready);
                    if ready && last_bytes.elapsed() > silence {
                        return SessionEnd::Lost(anyhow!("no data for {:.1} s", silence.as_secs_f64()));
                    }
                }
                _ = watch.tick() => {
                    if self.calibration.changed() {
                        self.reload_calibration("file changed");
                    }
                }
                _ = signals.hup.recv() => self.reload_calibration("SIGHUP"),
                _ = signals.term.recv() => shutdown = true,
                _ = signals.int.recv() => shutdown = true,
            }
        }
    }

    /// Leaves the device idle on shutdown (best effort).
    async fn stop_device<W: AsyncWrite + Unpin>(&mut self, port: &mut W) {
        if let Some(stop) = self.device.stop_bytes() {
            let _ = port.write_all(&stop).await;
        }
    }
}

/// What a session updates of the reconnect loop.
pub struct SessionLink<'a> {
    had_session: &'a mut bool,
    backoff: &'a mut Duration,
}

/// A deadline that never comes (a sleep that is not polled).
fn far_future() -> tokio::time::Instant {
    tokio::time::Instant::now() + Duration::from_secs(86_400)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_calibration_reload_error_names_the_os_reason() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("gone.toml");
        let e = imu_model::Calibration::load(&path).unwrap_err();
        let message = error_chain(e);
        assert!(message.contains("gone.toml"), "{message}");
        assert!(message.contains("No such file or directory"), "{message}");
    }
}
