//! A MIP unit as a driver: its packet decoder, its start-up (`startup.rs`), its IMU data
//! packets as readings (`reading.rs`), and its simulated unit for the offline path
//! (`offline.rs`). A MIP unit always streams: a configured "polled" mode does not apply.
//!
//! Passive (`device.configure = false`): nothing is ever sent. The clock is learned from the
//! first IMU data packet with accel, gyro and a timestamp (the shared reference time 0xD5 if
//! it has one, else the internal timestamp), and that packet is the session's first sample;
//! other data sets a 7-series unit interleaves (estimation filter 0x82, system 0xA0, GNSS) are
//! logged as frames and counted, not decoded into samples.

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
use imu_proto::decoder::DecoderStats;
use imu_proto::mip::{MipCommand, MipDecoder, MipEvent};
use tracing::info;

pub use reading::MipTimebase;
pub use startup::preferred_mip_format;
use startup::{Configured, Outcome, Startup};

use super::{DeviceIdentity, Driver, DriverEvent, FrameSlot, Held};
use crate::config::{AcquisitionMode, DeviceConfig};
use crate::pipeline::{Acquisition, FrameContent, Gains, SessionSpec};

/// The session of a unit streaming on `timebase`'s clock, set up by start-up. It streams
/// whatever mode the configuration names: its samples are paced by the unit, so losses are
/// counted and the data rate is measured.
pub fn session(timebase: MipTimebase) -> SessionSpec {
    SessionSpec {
        gains: Gains::NOT_APPLICABLE,
        timebase: timebase.timebase(),
        acquisition: Acquisition::Streaming,
        status_protocol: device_protocol::MIP,
        configuration_verified: true,
    }
}

/// The session of a passive unit streaming on `timebase`'s clock: asked nothing.
pub fn passive_session(timebase: MipTimebase) -> SessionSpec {
    SessionSpec {
        configuration_verified: false,
        ..session(timebase)
    }
}

/// The pipeline's session before a unit answered.
pub fn initial_session(config: &DeviceConfig) -> SessionSpec {
    SessionSpec {
        configuration_verified: config.configure,
        ..session(MipTimebase::ReferenceTime)
    }
}

/// What is wrong with `config` for a MIP unit, if anything: (the dotted key, the message).
pub fn config_problem(config: &DeviceConfig) -> Option<(&'static str, String)> {
    (config.mode == AcquisitionMode::Polled).then(|| {
        (
            "device.mode",
            "a MIP unit streams: \"polled\" is a 3DM-GX1 mode".into(),
        )
    })
}

/// A MIP unit (see the module docs).
pub struct MipDriver {
    config: DeviceConfig,
    path: PathBuf,
    decoder: MipDecoder,
    readings: reading::Readings,
    /// Readings are made (the unit resumed).
    streaming: bool,
    startup: Option<Startup>,
    /// Passive: listening for the first usable IMU packet until this time.
    learning: Option<Instant>,
    events: VecDeque<Held>,
    now: Instant,
}

impl MipDriver {
    /// The driver for the unit `config` describes.
    pub fn new(config: &DeviceConfig) -> Self {
        Self {
            config: config.clone(),
            path: config.path.clone(),
            decoder: MipDecoder::new(),
            readings: reading::Readings::new(MipTimebase::ReferenceTime),
            streaming: false,
            startup: None,
            learning: None,
            events: VecDeque::new(),
            now: Instant::now(),
        }
    }

    /// Queues an event for the session.
    fn push(&mut self, ev: DriverEvent) {
        self.events.push_back(Held::Event(ev));
    }

    /// Packets of data sets other than the IMU's, by descriptor set.
    pub fn other_sets(&self) -> &std::collections::BTreeMap<u8, u64> {
        self.readings.other_sets()
    }

    /// A driver of a unit already streaming on `timebase` (no start-up: the offline path,
    /// which configured its simulated unit directly).
    pub fn with_session(config: &DeviceConfig, timebase: MipTimebase) -> Self {
        let mut d = Self::new(config);
        d.readings.restart(timebase);
        d.streaming = true;
        d
    }

    /// Passive: the clock a packet would set, if it is a usable IMU data packet.
    fn learn(&mut self, packet: &imu_proto::mip::Packet) -> bool {
        if packet.descriptor_set() != imu_proto::mip::descriptor_set::IMU_DATA {
            return false;
        }
        let Ok(data) = imu_proto::mip::ImuData::decode_packet(packet) else {
            return false;
        };
        let timebase = match (data.reference_time_ns, data.internal_ticks) {
            (Some(_), _) => MipTimebase::ReferenceTime,
            (None, Some(_)) => MipTimebase::InternalTimestamp,
            (None, None) => return false,
        };
        if data.accel_g.is_none() || data.gyro_rad_s.is_none() {
            return false;
        }
        self.learning = None;
        self.streaming = true;
        self.readings.restart(timebase);
        info!(
            "device {} (MIP) passive: its IMU stream taken as it is, clock {}{}{} (rate \
             measured; configuration not verified)",
            self.path.display(),
            timebase.name(),
            if data.mag_gauss.is_some() {
                ", magnetometer"
            } else {
                ", no magnetometer"
            },
            if data.temperature.is_some() {
                ", temperature"
            } else {
                ", no temperature"
            },
        );
        self.push(DriverEvent::Session(passive_session(timebase)));
        let not_asked = "not asked (passive)".to_string();
        self.push(DriverEvent::Identified(Box::new(DeviceIdentity {
            protocol: imu_proto::DeviceProtocol::Mip.name(),
            model: not_asked.clone(),
            firmware: not_asked.clone(),
            serial: not_asked,
            details: vec![
                ("clock".into(), timebase.name().into()),
                ("magnetometer".into(), data.mag_gauss.is_some().to_string()),
                ("temperature".into(), data.temperature.is_some().to_string()),
                ("gps-timestamp".into(), data.gps_time.is_some().to_string()),
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
                self.readings.restart(c.choice.timebase);
                self.push(DriverEvent::Session(session(c.choice.timebase)));
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
        let info = &c.info;
        let firmware = format_mip_firmware(info.firmware_version);
        let choice = c.choice;
        info!(
            "device {} ({} {}) firmware {firmware} serial {}: {} Hz, clock {}{}{}{}",
            self.path.display(),
            info.model_name,
            info.model_number,
            info.serial_number,
            c.rate_hz,
            choice.timebase.name(),
            if choice.mag {
                ", magnetometer"
            } else {
                ", no magnetometer"
            },
            if choice.temperature {
                ", temperature"
            } else {
                ", no temperature"
            },
            if choice.gps_time {
                ", GPS timestamp"
            } else {
                ", no GPS timestamp"
            },
        );
        DeviceIdentity {
            protocol: imu_proto::DeviceProtocol::Mip.name(),
            model: info.model_name.clone(),
            firmware,
            serial: info.serial_number.clone(),
            details: vec![
                ("model-number".into(), info.model_number.clone()),
                ("device-options".into(), info.device_options.clone()),
                ("base-rate-hz".into(), c.base_rate_hz.to_string()),
                ("rate-hz".into(), c.rate_hz.to_string()),
                ("clock".into(), choice.timebase.name().into()),
                ("magnetometer".into(), choice.mag.to_string()),
                ("temperature".into(), choice.temperature.to_string()),
                ("gps-timestamp".into(), choice.gps_time.to_string()),
                ("message-format-command".into(), c.form.name()),
                ("configuration-verified".into(), "true".into()),
            ],
        }
    }
}

impl Driver for MipDriver {
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
            MipEvent::Packet { packet, offset } => {
                // Passive: the first usable packet sets the session, which goes out before it.
                let learned = self.learning.is_some() && self.learn(&packet);
                // The start-up's packets are logged only: no samples before the unit resumed.
                // Written in place: the content is most of a frame's bytes on this path.
                slot.content = if self.streaming {
                    self.readings.content(&packet)
                } else {
                    FrameContent::default()
                };
                if let Some(s) = &mut self.startup {
                    let outcome = s.on_packet(&packet, self.now);
                    self.on_outcome(outcome);
                }
                if learned {
                    // The session (queued by `learn`) goes out before its first sample.
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
            MipEvent::Rejected {
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
                "no MIP IMU data packet with accel, gyro and a timestamp heard within {:.1} s \
                 (passive: nothing is sent to the unit)",
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
            .then(|| MipCommand::SetToIdle.to_packet().as_bytes().to_vec())
    }

    fn stats(&self) -> DecoderStats {
        self.decoder.stats()
    }

    fn initial_session(&self) -> SessionSpec {
        initial_session(&self.config)
    }
}

/// A MIP firmware number as the vendor writes it: 1141 -> "1.1.41".
fn format_mip_firmware(v: u16) -> String {
    format!("{}.{}.{:02}", v / 1000, (v / 100) % 10, v % 100)
}
