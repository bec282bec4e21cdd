//! An Xsens MTi as a driver: its message decoder, its start-up (`startup.rs`), its MTData2
//! messages as readings (`reading.rs`), and its simulated unit for the offline path
//! (`offline.rs`). An MTi always streams: a configured "polled" mode does not apply.
//!
//! Passive (`device.configure = false`): nothing is ever sent. The first MTData2 message with
//! `SampleTimeFine` and an acceleration and rate of turn (the HR ones if it has them) is the
//! session's first sample.

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
use imu_proto::xsens::{Message, MtData2, XsensCommand, XsensDecoder, XsensEvent, mid};
use tracing::info;

use reading::{CLOCK_NAME, RawSource, Readings, timebase};
pub use startup::preferred_outputs;
use startup::{Configured, Outcome, Startup};

use super::{DeviceIdentity, Driver, DriverEvent, FrameSlot, Held};
use crate::config::{AcquisitionMode, DeviceConfig};
use crate::pipeline::{Acquisition, FrameContent, Gains, SessionSpec};

/// The session of a unit streaming on `SampleTimeFine`, set up by start-up: its samples are
/// paced by the unit, so losses are counted and the data rate is measured.
pub fn session() -> SessionSpec {
    SessionSpec {
        gains: Gains::NOT_APPLICABLE,
        timebase: timebase(),
        acquisition: Acquisition::Streaming,
        status_protocol: device_protocol::XSENS,
        configuration_verified: true,
    }
}

/// The pipeline's session before a unit answered (or of a passive unit).
pub fn initial_session(config: &DeviceConfig) -> SessionSpec {
    SessionSpec {
        configuration_verified: config.configure,
        ..session()
    }
}

/// What is wrong with `config` for an Xsens unit, if anything: (the dotted key, the message).
pub fn config_problem(config: &DeviceConfig) -> Option<(&'static str, String)> {
    if config.mode == AcquisitionMode::Polled {
        return Some((
            "device.mode",
            "an Xsens unit streams: \"polled\" is a 3DM-GX1 mode".into(),
        ));
    }
    let rate = config.rate_hz?;
    (!(1.0..65535.0).contains(&rate) || rate.fract() != 0.0).then(|| {
        (
            "device.rate-hz",
            format!("{rate} is not an Xsens output rate: a whole number of Hz"),
        )
    })
}

/// An Xsens MTi (see the module docs).
pub struct XsensDriver {
    config: DeviceConfig,
    path: PathBuf,
    decoder: XsensDecoder,
    readings: Readings,
    /// Readings are made (the unit is in measurement mode).
    streaming: bool,
    startup: Option<Startup>,
    /// Passive: listening for the first usable data message until this time.
    learning: Option<Instant>,
    events: VecDeque<Held>,
    now: Instant,
}

impl XsensDriver {
    /// The driver for the unit `config` describes.
    pub fn new(config: &DeviceConfig) -> Self {
        Self {
            config: config.clone(),
            path: config.path.clone(),
            decoder: XsensDecoder::new(),
            readings: Readings::new(),
            streaming: false,
            startup: None,
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

    fn push(&mut self, ev: DriverEvent) {
        self.events.push_back(Held::Event(ev));
    }

    /// Passive: whether `msg` is a usable data message, which then sets the session.
    fn learn(&mut self, msg: &Message) -> bool {
        if msg.mid() != mid::MT_DATA2 {
            return false;
        }
        let Ok(data) = MtData2::decode(msg) else {
            return false;
        };
        let Some(raw) = RawSource::of(&data) else {
            return false;
        };
        if data.sample_time_fine.is_none() {
            return false;
        }
        self.learning = None;
        self.streaming = true;
        self.readings.restart();
        let yes_no = |b: bool| b.to_string();
        info!(
            "device {} (Xsens) passive: its stream taken as it is, clock {CLOCK_NAME}, raw \
             reading {}{}{}{} (rate measured; configuration not verified)",
            self.path.display(),
            raw.name(),
            if data.magnetic_field.is_some() {
                ", magnetometer"
            } else {
                ", no magnetometer"
            },
            if data.temperature_c.is_some() {
                ", temperature"
            } else {
                ", no temperature"
            },
            if data.utc.is_some() {
                ", UTC time"
            } else {
                ", no UTC time"
            },
        );
        self.push(DriverEvent::Session(SessionSpec {
            configuration_verified: false,
            ..session()
        }));
        let not_asked = "not asked (passive)".to_string();
        self.push(DriverEvent::Identified(Box::new(DeviceIdentity {
            protocol: DeviceProtocol::Xsens.name(),
            model: not_asked.clone(),
            firmware: not_asked.clone(),
            serial: not_asked,
            details: vec![
                ("clock".into(), CLOCK_NAME.into()),
                ("raw-reading".into(), raw.name().into()),
                ("magnetometer".into(), yes_no(data.magnetic_field.is_some())),
                ("temperature".into(), yes_no(data.temperature_c.is_some())),
                ("utc-time".into(), yes_no(data.utc.is_some())),
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
                self.readings.restart();
                self.push(DriverEvent::Session(session()));
                let identity = self.identity_of(&c);
                self.push(DriverEvent::Identified(Box::new(identity)));
            }
            Some(Outcome::Done) => {
                self.startup = None;
                self.streaming = true;
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
        let choice = c.choice;
        let serial = format!("{:08X}", c.device_id);
        info!(
            "device {} ({}) firmware {} device id {serial}: {} Hz, clock {CLOCK_NAME}, raw \
             reading {}, outputs {}",
            self.path.display(),
            c.product_code,
            c.firmware,
            c.rate_hz,
            choice.raw.name(),
            choice.describe(),
        );
        DeviceIdentity {
            protocol: DeviceProtocol::Xsens.name(),
            model: c.product_code.clone(),
            firmware: c.firmware.to_string(),
            serial,
            details: vec![
                ("rate-hz".into(), c.rate_hz.to_string()),
                ("outputs".into(), choice.describe()),
                ("clock".into(), CLOCK_NAME.into()),
                ("raw-reading".into(), choice.raw.name().into()),
                ("magnetometer".into(), choice.mag.to_string()),
                ("temperature".into(), choice.temperature.to_string()),
                ("utc-time".into(), choice.utc.to_string()),
                ("configuration-verified".into(), "true".into()),
            ],
        }
    }
}

impl Driver for XsensDriver {
    fn start(&mut self, now: Instant) {
        self.now = now;
        self.streaming = false;
        self.learning = None;
        if !self.config.configure {
            self.startup = None;
            self.learning = Some(now + Duration::from_secs_f64(self.config.silence_timeout_s));
            return;
        }
        self.startup = Some(Startup::new(
            Duration::from_secs_f64(self.config.reply_timeout_s),
            self.config.rate_hz,
            now,
        ));
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
            XsensEvent::Packet { packet, offset } => {
                // Passive: the first usable message sets the session, which goes out before it.
                let learned = self.learning.is_some() && self.learn(&packet);
                // The start-up's messages (and the data a streaming unit sends before it
                // enters config mode) are logged only: no samples before measurement mode.
                slot.content = if self.streaming {
                    self.readings.content(&packet)
                } else {
                    FrameContent::default()
                };
                if let Some(s) = &mut self.startup {
                    let outcome = s.on_message(&packet, self.now);
                    self.on_outcome(outcome);
                }
                if learned {
                    let frame = SampleFrame {
                        stream_offset: offset,
                        bytes: FrameData::from_slice(packet.as_bytes()),
                    };
                    self.events
                        .push_back(Held::frame(frame, std::mem::take(&mut slot.content)));
                    return self.events.pop_front().map(|held| held.hand_over(slot));
                }
                slot.set_frame(packet.as_bytes(), offset);
                DriverEvent::Frame
            }
            XsensEvent::Rejected {
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
                "no Xsens MTData2 message with SampleTimeFine, an acceleration and a rate of \
                 turn heard within {:.1} s (passive: nothing is sent to the unit)",
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
        // No readings until the next start: the unit is not known to stream.
        self.streaming = false;
        self.learning = None;
    }

    fn stop_bytes(&self) -> Option<Vec<u8>> {
        // A passive unit is never sent anything, not even a stop.
        self.config
            .configure
            .then(|| XsensCommand::GoToConfig.to_message().as_bytes().to_vec())
    }

    fn stats(&self) -> DecoderStats {
        self.decoder.stats()
    }

    fn initial_session(&self) -> SessionSpec {
        initial_session(&self.config)
    }
}
