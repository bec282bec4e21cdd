//! Devices as drivers: one sans-IO [`Driver`] per protocol, each in its own folder, and the
//! [`Device`] the session runs (the configured protocol's driver, or a [`probe`] that finds it).
//!
//! A driver is a value, not a task: the session hands it what the port read
//! ([`Driver::handle_input`]) and the time when a deadline it asked for passed
//! ([`Driver::handle_timeout`]), writes what it asks to send ([`Driver::poll_transmit`]) and
//! takes its events ([`Driver::poll_event`]): every frame it decoded (with the reading or
//! temperature it carried, written in the caller's [`FrameSlot`]), the session it set up for
//! the pipeline, the identity when start-up is done, or why start-up failed. Time is always
//! passed in (`now`), never read, so start-up and probing are tested at CPU speed against a
//! scripted peer (`tests.rs`), with late, corrupt, missing and out-of-order replies and no
//! sleeps.
//!
//! Only code under `drivers/` names a protocol. A protocol's folder holds its start-up state
//! machine (`startup.rs`), its frames as readings (`reading.rs`), its driver (`mod.rs`), its
//! simulated unit for `imud --sim --offline` (`offline.rs`) and its tests. A ROS 2 topic
//! taken as the device (`ros2_input/`) is one more folder: its messages arrive as a byte stream
//! of frames like a unit's, and nothing is sent.

pub mod exchange;
pub mod gx1;
pub mod mip;
pub mod probe;
pub mod ros2_input;
#[cfg(test)]
mod scripted;
pub mod streaming;
#[cfg(test)]
mod tests;
pub mod vectornav;
pub mod xsens;

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use imu_bus::recording::SampleFrame;
use imu_proto::DeviceProtocol;
use imu_proto::decoder::{DecoderStats, RejectReason};

use crate::config::{Config, DeviceConfig};
pub use crate::pipeline::FrameSlot;
use crate::pipeline::{FrameContent, Gains, SessionSpec};

/// Tries of one exchange before it counts as failed.
pub const TRIES: u32 = 3;
/// Back-off before the second try; doubled before each further one.
const BACKOFF: Duration = Duration::from_millis(200);

/// The back-off before try `attempt` (none before the first).
pub(crate) fn back_off(attempt: u32) -> Duration {
    if attempt == 0 {
        Duration::ZERO
    } else {
        BACKOFF * 2u32.pow(attempt - 1)
    }
}

/// What the device told us at start-up.
#[derive(Debug, Clone, PartialEq)]
pub struct DeviceIdentity {
    /// The protocol's name (`imu_proto::DeviceProtocol::name`).
    pub protocol: &'static str,
    /// Model name ("3DM-GX1", or what a MIP unit reports, e.g. "3DM-GX5-25").
    pub model: String,
    /// Firmware version as the vendor writes it.
    pub firmware: String,
    /// Serial number.
    pub serial: String,
    /// Protocol-specific facts for the recording metadata (key, value), the gains in force
    /// among them for a device that has them.
    pub details: Vec<(String, String)>,
}

impl DeviceIdentity {
    /// The recording metadata `imud.device` for the device at `path`.
    pub fn metadata(&self, path: &std::path::Path) -> std::collections::BTreeMap<String, String> {
        let mut m = std::collections::BTreeMap::from([
            ("path".to_string(), path.display().to_string()),
            ("protocol".to_string(), self.protocol.to_string()),
            ("model".to_string(), self.model.clone()),
            ("firmware".to_string(), self.firmware.clone()),
            ("serial-number".to_string(), self.serial.clone()),
        ]);
        m.extend(self.details.iter().cloned());
        m
    }
}

/// What a driver has for the session.
#[derive(Debug)]
pub enum DriverEvent {
    /// A good frame, in the [`FrameSlot`] passed to [`Driver::poll_event`]: logged once; its
    /// reading and temperature (if any) go through the pipeline.
    Frame,
    /// Bytes that are not (part of) a good frame.
    Rejected {
        /// The bytes.
        bytes: Vec<u8>,
        /// Stream offset of the first.
        offset: u64,
        /// Why.
        reason: RejectReason,
    },
    /// A new device session for the pipeline: readings of it follow.
    Session(SessionSpec),
    /// The device and what was set up (recorded at once, so a start-up cut short by a
    /// shutdown still says which device it was).
    Identified(Box<DeviceIdentity>),
    /// Start-up is done: the session streams (or polls).
    Ready,
    /// Start-up failed: the session ends and is retried with back-off.
    Failed(anyhow::Error),
}

/// An event a driver holds back until it is polled, with its frame if it is one (handed over
/// in the caller's slot then). Only start-up and a passive unit's first packet hold frames
/// back; a frame on the per-frame path goes straight into the slot. So the held frame is boxed:
/// the allocation is paid only off that path, and the queue's entries stay small.
#[derive(Debug)]
pub(crate) enum Held {
    /// A good frame and what it carried.
    Frame(Box<(SampleFrame, FrameContent)>),
    /// Any other event.
    Event(DriverEvent),
}

impl Held {
    /// A held frame and its content.
    pub(crate) fn frame(frame: SampleFrame, content: FrameContent) -> Held {
        Held::Frame(Box::new((frame, content)))
    }

    /// The event, its frame (if any) put into `slot`.
    pub(crate) fn hand_over(self, slot: &mut FrameSlot) -> DriverEvent {
        match self {
            Held::Frame(held) => {
                (slot.frame, slot.content) = *held;
                DriverEvent::Frame
            }
            Held::Event(e) => e,
        }
    }
}

/// One protocol's device, sans IO (see the module docs).
pub trait Driver {
    /// Starts (again, after a reconnect) the start-up sequence at `now`. The decoder is kept,
    /// so its counters and stream offsets run on across sessions.
    fn start(&mut self, now: Instant);
    /// Bytes read from the device at `now`.
    fn handle_input(&mut self, bytes: &[u8], now: Instant);
    /// The next event, if any; a [`DriverEvent::Frame`]'s frame and content are in `slot`
    /// (overwritten by each frame).
    fn poll_event(&mut self, slot: &mut FrameSlot) -> Option<DriverEvent>;
    /// Appends the next bytes to write to `out`; false when there are none.
    fn poll_transmit(&mut self, out: &mut Vec<u8>) -> bool;
    /// When [`Driver::handle_timeout`] is next due.
    fn poll_timeout(&self) -> Option<Instant>;
    /// A deadline passed; `now` is the time.
    fn handle_timeout(&mut self, now: Instant);
    /// The line closed: ends any partial frame (it is rejected as truncated) and the session,
    /// so frames decoded before the next [`Driver::start`] are logged only, as a start-up's
    /// are (a replay hands a new session's start-up bytes over before it starts the driver).
    fn flush(&mut self);
    /// What leaves the device idle on shutdown, if anything.
    fn stop_bytes(&self) -> Option<Vec<u8>>;
    /// The decoder's counters.
    fn stats(&self) -> DecoderStats;
    /// The pipeline's session before start-up set one (the configured fallbacks).
    fn initial_session(&self) -> SessionSpec;
}

/// The device on the port: the configured protocol's driver, or, with none configured, a probe
/// each session that then hands over to the driver it found. Every protocol's driver is kept
/// once made, so the status's decoder counters stay cumulative across reconnects.
pub struct Device {
    config: DeviceConfig,
    gx1: Option<gx1::Gx1Driver>,
    mip: Option<mip::MipDriver>,
    xsens: Option<xsens::XsensDriver>,
    vectornav: Option<vectornav::VnDriver>,
    /// The ROS 2 input, when one is configured (`input.ros2-topic`): then the only driver.
    ros2: Option<ros2_input::Ros2InputDriver>,
    /// The protocol of the session (the configured one, or the last one probed).
    protocol: DeviceProtocol,
    probe: Option<probe::Probe>,
    /// Events queued by the device itself (the probe's bytes, logged as frames only).
    queued: VecDeque<Held>,
}

impl Device {
    /// The device `config` describes.
    pub fn new(config: &Config) -> Self {
        Self {
            config: config.device.clone(),
            gx1: None,
            mip: None,
            xsens: None,
            vectornav: None,
            ros2: config
                .input
                .ros2_topic
                .as_deref()
                .map(|topic| ros2_input::Ros2InputDriver::new(config, topic)),
            protocol: config.device.protocol.unwrap_or_default(),
            probe: None,
            queued: VecDeque::new(),
        }
    }

    fn driver(&mut self) -> &mut dyn Driver {
        if let Some(d) = &mut self.ros2 {
            return d;
        }
        match self.protocol {
            DeviceProtocol::Gx1 => self
                .gx1
                .get_or_insert_with(|| gx1::Gx1Driver::new(&self.config)),
            DeviceProtocol::Mip => self
                .mip
                .get_or_insert_with(|| mip::MipDriver::new(&self.config)),
            DeviceProtocol::Xsens => self
                .xsens
                .get_or_insert_with(|| xsens::XsensDriver::new(&self.config)),
            DeviceProtocol::Vectornav => self
                .vectornav
                .get_or_insert_with(|| vectornav::VnDriver::new(&self.config)),
        }
    }

    fn driver_ref(&self) -> Option<&dyn Driver> {
        if let Some(d) = &self.ros2 {
            return Some(d as &dyn Driver);
        }
        match self.protocol {
            DeviceProtocol::Gx1 => self.gx1.as_ref().map(|d| d as &dyn Driver),
            DeviceProtocol::Mip => self.mip.as_ref().map(|d| d as &dyn Driver),
            DeviceProtocol::Xsens => self.xsens.as_ref().map(|d| d as &dyn Driver),
            DeviceProtocol::Vectornav => self.vectornav.as_ref().map(|d| d as &dyn Driver),
        }
    }

    /// The probe found `protocol`: its driver takes the bytes heard (logged as frames only)
    /// and starts.
    fn probed(&mut self, protocol: DeviceProtocol, heard: &[u8], now: Instant) {
        self.protocol = protocol;
        if !self.config.configure {
            // Passive: the stream heard is the session's, from its first sample.
            let driver = self.driver();
            driver.start(now);
            driver.handle_input(heard, now);
            return;
        }
        let driver = self.driver();
        driver.handle_input(heard, now);
        let mut logged = VecDeque::new();
        let mut slot = FrameSlot::default();
        while let Some(ev) = driver.poll_event(&mut slot) {
            logged.push_back(match ev {
                DriverEvent::Frame => {
                    Held::frame(std::mem::take(&mut slot.frame), FrameContent::default())
                }
                other => Held::Event(other),
            });
        }
        driver.start(now);
        self.queued.append(&mut logged);
    }
}

impl Driver for Device {
    fn start(&mut self, now: Instant) {
        self.queued.clear();
        if let Some(d) = &mut self.ros2 {
            d.start(now);
            return;
        }
        match self.config.protocol {
            Some(_) => self.driver().start(now),
            None => self.probe = Some(probe::Probe::new(&self.config, now)),
        }
    }

    fn handle_input(&mut self, bytes: &[u8], now: Instant) {
        match &mut self.probe {
            Some(p) => p.handle_input(bytes, now),
            None => self.driver().handle_input(bytes, now),
        }
    }

    fn poll_event(&mut self, slot: &mut FrameSlot) -> Option<DriverEvent> {
        if let Some(held) = self.queued.pop_front() {
            return Some(held.hand_over(slot));
        }
        if let Some(p) = &mut self.probe {
            let now = p.now();
            return match p.poll_result()? {
                Ok((protocol, heard)) => {
                    self.probe = None;
                    self.probed(protocol, &heard, now);
                    self.poll_event(slot)
                }
                Err(e) => {
                    self.probe = None;
                    Some(DriverEvent::Failed(e))
                }
            };
        }
        self.driver().poll_event(slot)
    }

    fn poll_transmit(&mut self, out: &mut Vec<u8>) -> bool {
        match &mut self.probe {
            Some(p) => p.poll_transmit(out),
            None => self.driver().poll_transmit(out),
        }
    }

    fn poll_timeout(&self) -> Option<Instant> {
        match &self.probe {
            Some(p) => p.poll_timeout(),
            None => self.driver_ref()?.poll_timeout(),
        }
    }

    fn handle_timeout(&mut self, now: Instant) {
        match &mut self.probe {
            Some(p) => p.handle_timeout(now),
            None => self.driver().handle_timeout(now),
        }
    }

    fn flush(&mut self) {
        if self.probe.is_none() {
            self.driver().flush();
        }
    }

    fn stop_bytes(&self) -> Option<Vec<u8>> {
        match &self.probe {
            Some(_) => None,
            None => self.driver_ref()?.stop_bytes(),
        }
    }

    /// Every protocol driver's counters, summed (the probe's own decoders are not counted).
    fn stats(&self) -> DecoderStats {
        let mut sum = DecoderStats::default();
        let drivers = [
            self.gx1.as_ref().map(|d| d as &dyn Driver),
            self.mip.as_ref().map(|d| d as &dyn Driver),
            self.xsens.as_ref().map(|d| d as &dyn Driver),
            self.vectornav.as_ref().map(|d| d as &dyn Driver),
            self.ros2.as_ref().map(|d| d as &dyn Driver),
        ];
        for s in drivers.into_iter().flatten().map(|d| d.stats()) {
            sum.frames += s.frames;
            sum.bytes_in += s.bytes_in;
            sum.frame_bytes += s.frame_bytes;
            sum.rejected_bytes += s.rejected_bytes;
            sum.garbage_bytes += s.garbage_bytes;
            sum.checksum_failures += s.checksum_failures;
            sum.malformed_frames += s.malformed_frames;
            sum.truncated_frames += s.truncated_frames;
            sum.resyncs += s.resyncs;
        }
        sum
    }

    fn initial_session(&self) -> SessionSpec {
        if let Some(d) = &self.ros2 {
            return d.initial_session();
        }
        match self.protocol {
            DeviceProtocol::Gx1 => gx1::initial_session(&self.config),
            DeviceProtocol::Mip => mip::initial_session(&self.config),
            DeviceProtocol::Xsens => xsens::initial_session(&self.config),
            DeviceProtocol::Vectornav => vectornav::initial_session(&self.config),
        }
    }
}

/// The configured fallback GainScales, all flagged as fallbacks.
fn fallback_gains(config: &DeviceConfig) -> Gains {
    let fb = config.fallback_gains;
    Gains {
        accel: fb.accel,
        gyro: fb.gyro,
        mag: fb.mag,
        fallback: crate::pipeline::GainFallback::ALL,
    }
}

/// The protocol's name of a status's `protocol` byte (`imu_bus::sample::device_protocol`).
pub fn status_protocol_name(code: u8) -> &'static str {
    match code {
        imu_bus::sample::device_protocol::MIP => DeviceProtocol::Mip.name(),
        imu_bus::sample::device_protocol::VECTORNAV => DeviceProtocol::Vectornav.name(),
        imu_bus::sample::device_protocol::ROS2_INPUT => ros2_input::NAME,
        imu_bus::sample::device_protocol::XSENS => DeviceProtocol::Xsens.name(),
        // 0: the GX1, and every v2 status, where the byte was reserved.
        _ => DeviceProtocol::Gx1.name(),
    }
}

/// What a driver says is wrong with the device configuration for its protocol, if anything:
/// (the dotted key, the message).
pub fn config_problem(config: &DeviceConfig) -> Option<(&'static str, String)> {
    match config.protocol {
        Some(DeviceProtocol::Mip) => mip::config_problem(config),
        Some(DeviceProtocol::Xsens) => xsens::config_problem(config),
        Some(DeviceProtocol::Vectornav) => vectornav::config_problem(config),
        // Probed: the GX1's rules hold for either (a MIP unit streams whatever the mode).
        Some(DeviceProtocol::Gx1) | None => gx1::config_problem(config),
    }
}

/// A simulated unit for the offline path (`imud --sim --offline`): configured directly (no
/// link, no start-up), then asked for the bytes it sends at each sample time, which its
/// driver decodes as on a live link.
pub trait OfflineUnit {
    /// Physics, truth and scenario.
    fn core(&self) -> &imu_sim::DeviceCore;
    /// The pipeline's session for the unit as configured.
    fn session(&self) -> SessionSpec;
    /// The driver that decodes its bytes (its session already set).
    fn driver(&mut self) -> &mut dyn Driver;
    /// The recording metadata `imud.device` beyond the path and serial number.
    fn details(&self) -> Vec<(String, String)>;
    /// Appends the bytes the unit sends for sample `k` at `t_s`, and their truth records.
    fn step(
        &mut self,
        k: u64,
        t_s: f64,
        bytes: &mut Vec<u8>,
        truths: &mut Vec<imu_bus::truth::TruthSample>,
    );
}

/// The simulated unit of `protocol` around `core`, configured as `config` says.
pub fn offline_unit(
    protocol: DeviceProtocol,
    core: imu_sim::DeviceCore,
    config: &Config,
) -> anyhow::Result<Box<dyn OfflineUnit>> {
    Ok(match protocol {
        DeviceProtocol::Gx1 => Box::new(gx1::offline::Gx1Offline::new(core, config)),
        DeviceProtocol::Mip => Box::new(mip::offline::MipOffline::new(core, config)?),
        DeviceProtocol::Xsens => Box::new(xsens::offline::XsensOffline::new(core, config)?),
        DeviceProtocol::Vectornav => Box::new(vectornav::offline::VnOffline::new(core, config)?),
    })
}
