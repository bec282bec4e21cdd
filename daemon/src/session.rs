//! The device session: open the port, run the start-up sequence, stream or poll, detect loss,
//! reconnect with backoff, and keep status, signals and calibration reloads served throughout.
//!
//! This is the only async code in the workspace. One task owns the port, the decoder and the
//! pipeline, so the per-frame path never crosses a thread; the MCAP writer has its own thread.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use anyhow::{Context, anyhow};
use imu_bus::recording::LogRecord;
use imu_proto::DeviceProtocol;
use imu_proto::command::Command;
use imu_proto::mip::MipCommand;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::signal::unix::{Signal, SignalKind, signal};
use tokio_serial::SerialStream;
use tracing::{error, info, warn};

use crate::config::{AcquisitionMode, Config};
use crate::link::Link;
use crate::pipeline::{ActiveCalibration, Gains, Pipeline, Sinks};

/// What the device told us at start-up.
#[derive(Debug, Clone, PartialEq)]
pub struct DeviceIdentity {
    /// The protocol it speaks.
    pub protocol: DeviceProtocol,
    /// Model name ("3DM-GX1", or what a MIP unit reports, e.g. "3DM-GX5-25").
    pub model: String,
    /// Firmware version as the vendor writes it.
    pub firmware: String,
    /// Serial number.
    pub serial: String,
    /// GainScales in force (each read from the device or the configured fallback; a MIP unit
    /// has none: [`Gains::NOT_APPLICABLE`]).
    pub gains: Gains,
    /// Protocol-specific facts for the recording metadata (key, value).
    pub details: Vec<(String, String)>,
}

impl DeviceIdentity {
    /// The recording metadata `imud.device` for the device at `path`.
    pub fn metadata(&self, path: &std::path::Path) -> std::collections::BTreeMap<String, String> {
        let mut m = std::collections::BTreeMap::from([
            ("path".to_string(), path.display().to_string()),
            ("protocol".to_string(), self.protocol.name().to_string()),
            ("model".to_string(), self.model.clone()),
            ("firmware".to_string(), self.firmware.clone()),
            ("serial-number".to_string(), self.serial.clone()),
        ]);
        if self.protocol == DeviceProtocol::Gx1 {
            m.extend(self.gains.metadata());
        }
        m.extend(self.details.iter().cloned());
        m
    }
}

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

/// Everything the run loop owns.
pub struct Daemon {
    /// Effective configuration.
    pub config: Config,
    /// Outputs.
    pub sinks: Sinks,
    /// The per-frame state.
    pub pipeline: Pipeline,
    /// The decoders (kept across reconnects so their counters are cumulative).
    pub link: Link,
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
}

/// Called with the device identity each time the device answers its start-up sequence.
pub type IdentityHook = Box<dyn FnMut(&DeviceIdentity, &Sinks)>;

/// Why a streaming session ended.
enum SessionEnd {
    Shutdown,
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

    /// The data rate: configured when polling, measured when streaming.
    fn sample_rate_hz(&self) -> Option<f64> {
        match self.config.device.mode {
            AcquisitionMode::Polled => Some(self.config.device.poll_rate_hz),
            AcquisitionMode::Continuous => self.pipeline.sample_rate_hz(),
        }
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
        let mut status = self.pipeline.status(
            &self.link.stats(),
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
            let (_, wall) = now_ns();
            self.sinks.log_calibration(wall, cal, Some(rate));
            self.calibration_noise_pending = false;
        }
    }

    pub(crate) fn drain_decoder(&mut self) {
        let (mono, wall) = now_ns();
        self.link
            .drain_into(&mut self.pipeline, mono, wall, &mut self.sinks);
    }

    /// Runs until SIGTERM/SIGINT: sessions with reconnects in between.
    pub async fn run(&mut self, signals: &mut Signals) -> anyhow::Result<()> {
        let cfg = self.config.device.clone();
        let mut backoff = Duration::from_secs_f64(cfg.reconnect_min_s);
        let mut had_session = false;
        loop {
            let end = match self.open_and_start().await {
                Ok((port, identity)) => {
                    // A reconnect is a session that follows a lost one (not a failed attempt).
                    if had_session {
                        self.reconnects += 1;
                        info!(
                            "device {} is back (reconnect {})",
                            cfg.path.display(),
                            self.reconnects
                        );
                    }
                    had_session = true;
                    backoff = Duration::from_secs_f64(cfg.reconnect_min_s);
                    (self.on_identity)(&identity, &self.sinks);
                    if !self.notified_ready {
                        let _ = sd_notify::notify(false, &[sd_notify::NotifyState::Ready]);
                        self.notified_ready = true;
                    }
                    self.stream(port, signals).await
                }
                Err(e) => SessionEnd::Lost(e),
            };
            self.link.flush();
            self.drain_decoder();
            match end {
                SessionEnd::Shutdown => {
                    // A last status, so the recording ends with the final counters.
                    self.publish_status(false);
                    return Ok(());
                }
                SessionEnd::Lost(e) => {
                    warn!(
                        "device {} unavailable: {e:#}; retrying in {:.1} s",
                        cfg.path.display(),
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

    /// Streams (or polls) until the device is lost or a shutdown signal arrives.
    async fn stream(&mut self, mut port: SerialStream, signals: &mut Signals) -> SessionEnd {
        let cfg = self.config.device.clone();
        let polled =
            cfg.mode == AcquisitionMode::Polled && self.link.protocol() == DeviceProtocol::Gx1;
        let poll_period = Duration::from_secs_f64(1.0 / cfg.poll_rate_hz);
        let mut poll = tokio::time::interval(poll_period);
        poll.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
        let temp_every = if cfg.temperature_rate_hz > 0.0 {
            (cfg.poll_rate_hz / cfg.temperature_rate_hz)
                .round()
                .max(1.0) as u64
        } else {
            u64::MAX
        };
        let mut n_polls: u64 = 0;
        let mut status = tokio::time::interval(Duration::from_secs_f64(
            self.config.publish.status_interval_s,
        ));
        let mut watch = tokio::time::interval(Duration::from_secs(1));
        let silence = Duration::from_secs_f64(cfg.silence_timeout_s);
        let mut buf = vec![0u8; 8192];
        let mut last_bytes = tokio::time::Instant::now();
        let poll_cmd = cfg.command.command().to_bytes();
        let temp_cmd = Command::Temperature.to_bytes();
        loop {
            tokio::select! {
                read = port.read(&mut buf) => match read {
                    Ok(0) => return SessionEnd::Lost(anyhow!("the device closed the line")),
                    Ok(n) => {
                        last_bytes = tokio::time::Instant::now();
                        let (mono, wall) = now_ns();
                        self.link.push(&buf[..n]);
                        self.link.drain_into(&mut self.pipeline, mono, wall, &mut self.sinks);
                    }
                    Err(e) => return SessionEnd::Lost(anyhow!(e).context("reading from the device")),
                },
                _ = poll.tick(), if polled => {
                    n_polls += 1;
                    let bytes = if n_polls.is_multiple_of(temp_every) { &temp_cmd } else { &poll_cmd };
                    if let Err(e) = port.write_all(bytes).await {
                        return SessionEnd::Lost(anyhow!(e).context("writing to the device"));
                    }
                }
                _ = status.tick() => {
                    self.publish_status(true);
                    if last_bytes.elapsed() > silence {
                        return SessionEnd::Lost(anyhow!("no data for {:.1} s", silence.as_secs_f64()));
                    }
                }
                _ = watch.tick() => {
                    if self.calibration.changed() {
                        self.reload_calibration("file changed");
                    }
                }
                _ = signals.hup.recv() => self.reload_calibration("SIGHUP"),
                _ = signals.term.recv() => { self.stop_device(&mut port).await; return SessionEnd::Shutdown; }
                _ = signals.int.recv() => { self.stop_device(&mut port).await; return SessionEnd::Shutdown; }
            }
        }
    }

    /// Leaves the device idle on shutdown (best effort).
    async fn stop_device(&mut self, port: &mut SerialStream) {
        let stop = match self.link.protocol() {
            DeviceProtocol::Mip => MipCommand::SetToIdle.to_packet().as_bytes().to_vec(),
            DeviceProtocol::Gx1 if self.config.device.mode == AcquisitionMode::Continuous => {
                Command::SetContinuous { command: 0 }.to_bytes()
            }
            DeviceProtocol::Gx1 => return,
        };
        let _ = port.write_all(&stop).await;
    }
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
