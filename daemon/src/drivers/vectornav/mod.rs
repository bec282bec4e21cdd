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

use std::path::PathBuf;
use std::time::{Duration, Instant};

use imu_bus::sample::device_protocol;
use imu_proto::DeviceProtocol;
use imu_proto::decoder::DecoderStats;
use imu_proto::decoder::framed::PacketEvent;
use imu_proto::vectornav::binary::group;
use imu_proto::vectornav::{
    BinaryMessage, BinaryOutputConfig, Check, OutputFields, Register, Sentence, VnCommand,
    VnDecoder, VnEvent,
};
use tracing::info;

use startup::{Configured, Outcome, Startup};

use super::DeviceIdentity;
use super::streaming::{FrameDecoder, Passive, Step, StreamingDriver, Unit};
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

/// A good frame of a VectorNav unit's stream.
// The decoded values are held inline (as in `VnEvent`): they move once, into the frame.
#[allow(clippy::large_enum_variant)]
pub enum VnFrame {
    /// A binary output message.
    Binary(BinaryMessage),
    /// An ASCII sentence (a register reply, `$VNERR`, an ASCII output).
    Ascii(Sentence),
}

/// One decoder for both kinds of frame on the port.
impl FrameDecoder for VnDecoder {
    type Frame = VnFrame;

    fn push(&mut self, bytes: &[u8]) {
        VnDecoder::push(self, bytes);
    }

    fn flush(&mut self) {
        VnDecoder::flush(self);
    }

    fn stats(&self) -> DecoderStats {
        VnDecoder::stats(self)
    }

    fn next_frame(&mut self) -> Option<PacketEvent<VnFrame>> {
        Some(match self.next_event()? {
            VnEvent::Binary { message, offset } => PacketEvent::Packet {
                packet: VnFrame::Binary(message),
                offset,
            },
            VnEvent::Ascii { sentence, offset } => PacketEvent::Packet {
                packet: VnFrame::Ascii(sentence),
                offset,
            },
            VnEvent::Rejected {
                bytes,
                offset,
                reason,
            } => PacketEvent::Rejected {
                bytes,
                offset,
                reason,
            },
        })
    }

    fn bytes(frame: &VnFrame) -> &[u8] {
        match frame {
            VnFrame::Binary(message) => message.as_bytes(),
            VnFrame::Ascii(sentence) => sentence.as_bytes(),
        }
    }
}

/// A VectorNav unit (see the module docs).
pub type VnDriver = StreamingDriver<VnUnit>;

impl VnDriver {
    /// A driver of a unit already streaming (no start-up: the offline path, which configured
    /// its simulated unit directly).
    pub fn with_session(config: &DeviceConfig) -> Self {
        Self::already_streaming(config, VnUnit::new(config))
    }

    /// Binary messages that made no sample so far.
    pub fn unusable_count(&self) -> u64 {
        self.unit.readings.unusable_count()
    }
}

/// What is a VectorNav unit's own in its driver.
pub struct VnUnit {
    path: PathBuf,
    readings: reading::Readings,
    /// The output configured, for the stop bytes.
    output: Option<BinaryOutputConfig>,
}

impl VnUnit {
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

impl Unit for VnUnit {
    const PROTOCOL: DeviceProtocol = DeviceProtocol::Vectornav;
    const PASSIVE_WANTS: &'static str =
        "VectorNav binary message with the startup time and uncompensated accel and gyro";
    type Decoder = VnDecoder;
    type Startup = Startup;

    fn new(config: &DeviceConfig) -> Self {
        Self {
            path: config.path.clone(),
            readings: reading::Readings::new(),
            output: None,
        }
    }

    fn startup(config: &DeviceConfig, timeout: Duration, now: Instant) -> anyhow::Result<Startup> {
        let divisor = config.rate_hz.map(startup::rate_divisor).transpose()?;
        Ok(Startup::new(timeout, divisor, now))
    }

    /// A binary message's reading; a sentence (logged as a frame only) carries none.
    fn content(&mut self, frame: &VnFrame) -> FrameContent {
        match frame {
            VnFrame::Binary(message) => self.readings.content(message),
            VnFrame::Ascii(_) => FrameContent::default(),
        }
    }

    /// The stream, if `frame` is a usable sample.
    fn learn(&mut self, frame: &VnFrame) -> Option<Passive> {
        let VnFrame::Binary(message) = frame else {
            return None;
        };
        let d = message.data();
        if d.startup_ns.is_none() || d.uncomp_accel_m_s2.is_none() || d.uncomp_gyro_rad_s.is_none()
        {
            return None;
        }
        self.readings.restart();
        let fields = fields_name(&message.fields());
        info!(
            "device {} (VectorNav) passive: its binary output taken as it is ({fields}; rate \
             measured; configuration not verified)",
            self.path.display()
        );
        Some(Passive {
            session: passive_session(),
            details: vec![
                ("clock".into(), "startup time (ns)".into()),
                ("outputs".into(), fields),
                ("gnss-time".into(), d.gps_ns.is_some().to_string()),
                ("compensated".into(), d.accel_m_s2.is_some().to_string()),
            ],
        })
    }

    fn outcome(&mut self, outcome: Outcome) -> Step {
        match outcome {
            Outcome::Configured(c) => {
                self.readings.restart();
                self.output = Some(c.output);
                Step::Configured {
                    session: session(),
                    identity: self.identity_of(&c),
                    // The output was turned on by the reply that ended start-up.
                    streaming: true,
                }
            }
            Outcome::Failed(e) => Step::Failed(e),
        }
    }

    fn stop_bytes(&self) -> Option<Vec<u8>> {
        // The binary output turned off, the fields kept, so a later start-up finds them as
        // written.
        let off = Register::BinaryOutput {
            index: 1,
            config: BinaryOutputConfig {
                async_mode: 0,
                ..self.output?
            },
        };
        Some(
            VnCommand::Write(off)
                .to_sentence(Check::Checksum8)
                .as_bytes()
                .to_vec(),
        )
    }

    fn initial_session(config: &DeviceConfig) -> SessionSpec {
        initial_session(config)
    }
}
