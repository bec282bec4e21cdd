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

use std::path::PathBuf;
use std::time::{Duration, Instant};

use imu_bus::sample::device_protocol;
use imu_proto::DeviceProtocol;
use imu_proto::xsens::{Message, MtData2, XsensCommand, XsensDecoder, mid};
use tracing::info;

use reading::{CLOCK_NAME, RawSource, Readings, timebase};
pub use startup::preferred_outputs;
use startup::{Configured, Outcome, Startup};

use super::DeviceIdentity;
use super::streaming::{Passive, Step, StreamingDriver, Unit};
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

/// What an MTi's magnetic field is in, for the metadata: the recording carries it in the
/// magnetometer's gauss slot (and on `/imu/mag` as that times 1e-4 T) as the unit sends it.
pub const MAGNETOMETER_UNIT: &str =
    "ratio to the field where the unit was calibrated (1 there), not gauss";

/// An Xsens MTi (see the module docs).
pub type XsensDriver = StreamingDriver<XsensUnit>;

impl XsensDriver {
    /// A driver of a unit already streaming (no start-up: the offline path, which configured
    /// its simulated unit directly).
    pub fn with_session(config: &DeviceConfig) -> Self {
        Self::already_streaming(config, XsensUnit::new(config))
    }
}

/// What is an MTi's own in its driver.
pub struct XsensUnit {
    path: PathBuf,
    readings: Readings,
}

impl XsensUnit {
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
                ("magnetometer-unit".into(), MAGNETOMETER_UNIT.into()),
                ("temperature".into(), choice.temperature.to_string()),
                ("utc-time".into(), choice.utc.to_string()),
                ("configuration-verified".into(), "true".into()),
            ],
        }
    }
}

impl Unit for XsensUnit {
    const PROTOCOL: DeviceProtocol = DeviceProtocol::Xsens;
    const PASSIVE_WANTS: &'static str =
        "Xsens MTData2 message with SampleTimeFine, an acceleration and a rate of turn";
    type Decoder = XsensDecoder;
    type Startup = Startup;

    fn new(config: &DeviceConfig) -> Self {
        Self {
            path: config.path.clone(),
            readings: Readings::new(),
        }
    }

    fn startup(config: &DeviceConfig, timeout: Duration, now: Instant) -> anyhow::Result<Startup> {
        Ok(Startup::new(timeout, config.rate_hz, now))
    }

    fn content(&mut self, msg: &Message) -> FrameContent {
        self.readings.content(msg)
    }

    /// The stream, if `msg` is a usable data message.
    fn learn(&mut self, msg: &Message) -> Option<Passive> {
        if msg.mid() != mid::MT_DATA2 {
            return None;
        }
        let data = MtData2::decode(msg).ok()?;
        let raw = RawSource::of(&data)?;
        data.sample_time_fine?;
        self.readings.restart();
        let yes_no = |b: bool| b.to_string();
        info!(
            "device {} (Xsens) passive: its stream taken as it is, clock {CLOCK_NAME}, raw \
             reading {}{}{}{} (rate measured; configuration not verified)",
            self.path.display(),
            raw.name(),
            if data.magnetic_field_normalised.is_some() {
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
        Some(Passive {
            session: SessionSpec {
                configuration_verified: false,
                ..session()
            },
            details: vec![
                ("clock".into(), CLOCK_NAME.into()),
                ("raw-reading".into(), raw.name().into()),
                (
                    "magnetometer".into(),
                    yes_no(data.magnetic_field_normalised.is_some()),
                ),
                ("magnetometer-unit".into(), MAGNETOMETER_UNIT.into()),
                ("temperature".into(), yes_no(data.temperature_c.is_some())),
                ("utc-time".into(), yes_no(data.utc.is_some())),
            ],
        })
    }

    fn outcome(&mut self, outcome: Outcome) -> Step {
        match outcome {
            Outcome::Configured(c) => {
                self.readings.restart();
                Step::Configured {
                    session: session(),
                    identity: self.identity_of(&c),
                    // Measurement mode follows.
                    streaming: false,
                }
            }
            Outcome::Done => Step::Done,
            Outcome::Failed(e) => Step::Failed(e),
        }
    }

    fn stop_bytes(&self) -> Option<Vec<u8>> {
        Some(XsensCommand::GoToConfig.to_message().as_bytes().to_vec())
    }

    fn initial_session(config: &DeviceConfig) -> SessionSpec {
        initial_session(config)
    }
}
