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

use std::path::PathBuf;
use std::time::{Duration, Instant};

use imu_bus::sample::device_protocol;
use imu_proto::DeviceProtocol;
use imu_proto::mip::{MipCommand, MipDecoder, Packet};
use tracing::info;

pub use reading::MipTimebase;
pub use startup::preferred_mip_format;
use startup::{Configured, Outcome, Startup};

use super::DeviceIdentity;
use super::streaming::{Passive, Step, StreamingDriver, Unit};
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
pub type MipDriver = StreamingDriver<MipUnit>;

impl MipDriver {
    /// Packets of data sets other than the IMU's, by descriptor set.
    pub fn other_sets(&self) -> &std::collections::BTreeMap<u8, u64> {
        self.unit.readings.other_sets()
    }

    /// A driver of a unit already streaming on `timebase` (no start-up: the offline path,
    /// which configured its simulated unit directly).
    pub fn with_session(config: &DeviceConfig, timebase: MipTimebase) -> Self {
        let mut unit = MipUnit::new(config);
        unit.readings.restart(timebase);
        Self::already_streaming(config, unit)
    }
}

/// What is a MIP unit's own in its driver.
pub struct MipUnit {
    path: PathBuf,
    readings: reading::Readings,
}

impl MipUnit {
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
            protocol: DeviceProtocol::Mip.name(),
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

impl Unit for MipUnit {
    const PROTOCOL: DeviceProtocol = DeviceProtocol::Mip;
    const PASSIVE_WANTS: &'static str = "MIP IMU data packet with accel, gyro and a timestamp";
    type Decoder = MipDecoder;
    type Startup = Startup;

    fn new(config: &DeviceConfig) -> Self {
        Self {
            path: config.path.clone(),
            readings: reading::Readings::new(MipTimebase::ReferenceTime),
        }
    }

    fn startup(config: &DeviceConfig, timeout: Duration, now: Instant) -> anyhow::Result<Startup> {
        Ok(Startup::new(timeout, config.rate_hz, now))
    }

    fn content(&mut self, packet: &Packet) -> FrameContent {
        self.readings.content(packet)
    }

    /// The clock a packet sets, if it is a usable IMU data packet.
    fn learn(&mut self, packet: &Packet) -> Option<Passive> {
        if packet.descriptor_set() != imu_proto::mip::descriptor_set::IMU_DATA {
            return None;
        }
        let data = imu_proto::mip::ImuData::decode_packet(packet).ok()?;
        let timebase = match (data.reference_time_ns, data.internal_ticks) {
            (Some(_), _) => MipTimebase::ReferenceTime,
            (None, Some(_)) => MipTimebase::InternalTimestamp,
            (None, None) => return None,
        };
        if data.accel_g.is_none() || data.gyro_rad_s.is_none() {
            return None;
        }
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
        Some(Passive {
            session: passive_session(timebase),
            details: vec![
                ("clock".into(), timebase.name().into()),
                ("magnetometer".into(), data.mag_gauss.is_some().to_string()),
                ("temperature".into(), data.temperature.is_some().to_string()),
                ("gps-timestamp".into(), data.gps_time.is_some().to_string()),
            ],
        })
    }

    fn outcome(&mut self, outcome: Outcome) -> Step {
        match outcome {
            Outcome::Configured(c) => {
                self.readings.restart(c.choice.timebase);
                Step::Configured {
                    session: session(c.choice.timebase),
                    identity: self.identity_of(&c),
                    // The resume follows.
                    streaming: false,
                }
            }
            Outcome::Done => Step::Done,
            Outcome::Failed(e) => Step::Failed(e),
        }
    }

    fn stop_bytes(&self) -> Option<Vec<u8>> {
        Some(MipCommand::SetToIdle.to_packet().as_bytes().to_vec())
    }

    fn initial_session(config: &DeviceConfig) -> SessionSpec {
        initial_session(config)
    }
}

/// A MIP firmware number as the vendor writes it: 1141 -> "1.1.41".
fn format_mip_firmware(v: u16) -> String {
    format!("{}.{}.{:02}", v / 1000, (v / 100) % 10, v % 100)
}
