//! A VectorNav VN-100/200/300 as a driver: its decoder (binary messages and ASCII sentences on
//! one port), its start-up (`startup.rs`), its binary messages as readings (`reading.rs`), and
//! its simulated unit for the offline path (`offline.rs`). A VectorNav unit always streams: a
//! configured "polled" mode does not apply.
//!
//! Passive (`device.configure = false`): nothing is ever sent. The first binary message with
//! the startup time and the uncompensated accel and gyro is the session's first sample; ASCII
//! sentences (a unit's `$VNYPR` output) are logged as frames only.

pub mod offline;
pub mod reading;
pub mod startup;
#[cfg(test)]
mod tests;

use std::collections::VecDeque;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use imu_bus::recording::{FrameData, SampleFrame};
use imu_bus::sample::device_protocol;
use imu_proto::DeviceProtocol;
use imu_proto::decoder::DecoderStats;
use imu_proto::vectornav::binary::group;
use imu_proto::vectornav::{
    BinaryMessage, BinaryOutputConfig, Check, OutputFields, Register, VnCommand, VnDecoder, VnEvent,
};
use tracing::info;

use startup::{Configured, Outcome, Startup};

use super::{DeviceIdentity, Driver, DriverEvent, FrameSlot, Held};
use crate::config::{AcquisitionMode, DeviceConfig};
use crate::pipeline::{Acquisition, FrameContent, Gains, SessionSpec};

/// The session of a unit streaming binary messages, set up by start-up: its samples are paced
/// by the unit, so losses are counted and the data rate is measured.
pub fn session() -> SessionSpec {
    SessionSpec {
        gains: Gains::NOT_APPLICABLE,
        timebase: reading::timebase(),
        acquisition: Acquisition::Streaming,
        status_protocol: device_protocol::VECTORNAV,
        configuration_verified: true,
    }
}

/// The session of a passive unit: asked nothing.
pub fn passive_session() -> SessionSpec {
    SessionSpec {
        configuration_verified: false,
        ..session()
    }
}

/// The pipeline's session before a unit answered.
pub fn initial_session(config: &DeviceConfig) -> SessionSpec {
    SessionSpec {
        configuration_verified: config.configure,
        ..session()
    }
}

/// What is wrong with `config` for a VectorNav unit, if anything: (the dotted key, the message).
pub fn config_problem(config: &DeviceConfig) -> Option<(&'static str, String)> {
    if config.mode == AcquisitionMode::Polled {
        return Some((
            "device.mode",
            "a VectorNav unit streams: \"polled\" is a 3DM-GX1 mode".into(),
        ));
    }
    config
        .rate_hz
        .and_then(|r| startup::rate_divisor(r).err())
        .map(|e| ("device.rate-hz", e.to_string()))
}

/// The output's fields as the metadata names them: `group:0xWORD` for each group present.
pub fn fields_name(fields: &OutputFields) -> String {
    (0..group::COUNT)
        .filter(|&g| fields.words[g] != 0)
        .map(|g| {
            format!(
                "{}:0x{:04X}",
                imu_proto::vectornav::ascii::group_name(g),
                fields.words[g]
            )
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// A VectorNav unit (see the module docs).
pub struct VnDriver {
    config: DeviceConfig,
    path: PathBuf,
    decoder: VnDecoder,
    readings: reading::Readings,
    /// Readings are made (the output is verified, or a passive unit's stream was taken).
    streaming: bool,
    startup: Option<Startup>,
    /// The output configured, for the stop bytes.
    output: Option<BinaryOutputConfig>,
    /// Passive: listening for the first usable binary message until this time.
    learning: Option<Instant>,
    events: VecDeque<Held>,
    now: Instant,
}

impl VnDriver {
    /// The driver for the unit `config` describes.
    pub fn new(config: &DeviceConfig) -> Self {
        Self {
            config: config.clone(),
            path: config.path.clone(),
            decoder: VnDecoder::new(),
            readings: reading::Readings::new(),
            streaming: false,
            startup: None,
            output: None,
            learning: None,
            events: VecDeque::new(),
            now: Instant::now(),
        }
    }

    /// A driver of a unit already streaming (no start-up: the offline path, which configured
    /// its simulated unit directly).
    pub fn with_session(config: &DeviceConfig) -> Self {
        let mut d = Self::new(config);
        d.streaming = true;
        d
    }

    /// Binary messages that made no sample so far.
    pub fn unusable_count(&self) -> u64 {
        self.readings.unusable_count()
    }

    fn push(&mut self, ev: DriverEvent) {
        self.events.push_back(Held::Event(ev));
    }

    /// Passive: takes the stream if `message` is a usable sample.
    fn learn(&mut self, message: &BinaryMessage) -> bool {
        let d = message.data();
        if d.startup_ns.is_none() || d.uncomp_accel_m_s2.is_none() || d.uncomp_gyro_rad_s.is_none()
        {
            return false;
        }
        self.learning = None;
        self.streaming = true;
        self.readings.restart();
        let fields = fields_name(&message.fields());
        info!(
            "device {} (VectorNav) passive: its binary output taken as it is ({fields}; rate \
             measured; configuration not verified)",
            self.path.display()
        );
        self.push(DriverEvent::Session(passive_session()));
        let not_asked = "not asked (passive)".to_string();
        self.push(DriverEvent::Identified(Box::new(DeviceIdentity {
            protocol: DeviceProtocol::Vectornav.name(),
            model: not_asked.clone(),
            firmware: not_asked.clone(),
            serial: not_asked,
            details: vec![
                ("clock".into(), "startup time (ns)".into()),
                ("outputs".into(), fields),
                ("gnss-time".into(), d.gps_ns.is_some().to_string()),
                ("compensated".into(), d.accel_m_s2.is_some().to_string()),
                ("configuration-verified".into(), "false".into()),
            ],
        })));
        self.push(DriverEvent::Ready);
        true
    }

    fn on_outcome(&mut self, outcome: Option<Outcome>) {
        match outcome {
            None => {}
            Some(Outcome::Configured(c)) => {
                self.startup = None;
                self.readings.restart();
                self.output = Some(c.output);
                self.streaming = true;
                self.push(DriverEvent::Session(session()));
                let identity = self.identity_of(&c);
                self.push(DriverEvent::Identified(Box::new(identity)));
                self.push(DriverEvent::Ready);
            }
            Some(Outcome::Failed(e)) => {
                self.startup = None;
                self.push(DriverEvent::Failed(e));
            }
        }
    }

    /// Says what was set up; the identity and metadata.
    fn identity_of(&self, c: &Configured) -> DeviceIdentity {
        let fields = fields_name(&c.output.fields);
        let gnss = startup::model_has_gnss(&c.model);
        info!(
            "device {} ({}) firmware {} serial {}: {} Hz (IMU rate / {}), outputs {fields}{}",
            self.path.display(),
            c.model,
            c.firmware,
            c.serial,
            c.rate_hz(),
            c.output.rate_divisor,
            if gnss { ", GPS time" } else { "" },
        );
        DeviceIdentity {
            protocol: DeviceProtocol::Vectornav.name(),
            model: c.model.clone(),
            firmware: c.firmware.clone(),
            serial: c.serial.to_string(),
            details: vec![
                ("rate-hz".into(), c.rate_hz().to_string()),
                ("rate-divisor".into(), c.output.rate_divisor.to_string()),
                ("binary-output".into(), "1 (register 75)".into()),
                ("outputs".into(), fields),
                ("clock".into(), "startup time (ns)".into()),
                ("gnss-time".into(), gnss.to_string()),
                ("compensated".into(), "true".into()),
                ("configuration-verified".into(), "true".into()),
            ],
        }
    }
}

impl Driver for VnDriver {
    fn start(&mut self, now: Instant) {
        self.now = now;
        self.streaming = false;
        self.learning = None;
        if !self.config.configure {
            self.startup = None;
            self.learning = Some(now + Duration::from_secs_f64(self.config.silence_timeout_s));
            return;
        }
        match self.config.rate_hz.map(startup::rate_divisor).transpose() {
            Ok(divisor) => {
                self.startup = Some(Startup::new(
                    Duration::from_secs_f64(self.config.reply_timeout_s),
                    divisor,
                    now,
                ));
            }
            Err(e) => self.push(DriverEvent::Failed(e)),
        }
    }

    fn handle_input(&mut self, bytes: &[u8], now: Instant) {
        self.now = now;
        self.decoder.push(bytes);
    }

    fn poll_event(&mut self, slot: &mut FrameSlot) -> Option<DriverEvent> {
        if let Some(held) = self.events.pop_front() {
            return Some(held.hand_over(slot));
        }
        Some(match self.decoder.next_event()? {
            VnEvent::Binary { message, offset } => {
                let learned = self.learning.is_some() && self.learn(&message);
                slot.content = if self.streaming {
                    self.readings.content(&message)
                } else {
                    FrameContent::default()
                };
                if learned {
                    // The session (queued by `learn`) goes out before its first sample.
                    let frame = SampleFrame {
                        stream_offset: offset,
                        bytes: FrameData::from_slice(message.as_bytes()),
                    };
                    self.events
                        .push_back(Held::frame(frame, std::mem::take(&mut slot.content)));
                    return self.events.pop_front().map(|held| held.hand_over(slot));
                }
                slot.set_frame(message.as_bytes(), offset);
                DriverEvent::Frame
            }
            VnEvent::Ascii { sentence, offset } => {
                slot.content = FrameContent::default();
                if let Some(s) = &mut self.startup {
                    let outcome = s.on_sentence(&sentence, self.now);
                    self.on_outcome(outcome);
                }
                // The start-up's events (queued above) go out after the reply that ended it.
                slot.set_frame(sentence.as_bytes(), offset);
                DriverEvent::Frame
            }
            VnEvent::Rejected {
                bytes,
                offset,
                reason,
            } => DriverEvent::Rejected {
                bytes,
                offset,
                reason,
            },
        })
    }

    fn poll_transmit(&mut self, out: &mut Vec<u8>) -> bool {
        match self.startup.as_mut().and_then(|s| s.tx.pop_front()) {
            Some(bytes) => {
                out.extend_from_slice(&bytes);
                true
            }
            None => false,
        }
    }

    fn poll_timeout(&self) -> Option<Instant> {
        match &self.startup {
            Some(s) => s.deadline(),
            None => self.learning,
        }
    }

    fn handle_timeout(&mut self, now: Instant) {
        self.now = now;
        if self.learning.is_some_and(|t| now >= t) {
            self.learning = None;
            self.push(DriverEvent::Failed(anyhow::anyhow!(
                "no VectorNav binary message with the startup time and uncompensated accel and \
                 gyro heard within {:.1} s (passive: nothing is sent to the unit)",
                self.config.silence_timeout_s
            )));
        }
        if let Some(s) = &mut self.startup {
            let outcome = s.on_timeout(now);
            self.on_outcome(outcome);
        }
    }

    fn flush(&mut self) {
        self.decoder.flush();
        self.streaming = false;
        self.learning = None;
    }

    fn stop_bytes(&self) -> Option<Vec<u8>> {
        // A passive unit is never sent anything; a configured one has its binary output
        // turned off (the fields kept, so a later start-up finds them as written).
        let output = self.output.filter(|_| self.config.configure)?;
        let off = Register::BinaryOutput {
            index: 1,
            config: BinaryOutputConfig {
                async_mode: 0,
                ..output
            },
        };
        Some(
            VnCommand::Write(off)
                .to_sentence(Check::Checksum8)
                .as_bytes()
                .to_vec(),
        )
    }

    fn stats(&self) -> DecoderStats {
        self.decoder.stats()
    }

    fn initial_session(&self) -> SessionSpec {
        initial_session(&self.config)
    }
}
