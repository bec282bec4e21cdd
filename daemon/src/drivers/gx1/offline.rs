//! A simulated 3DM-GX1 for the offline path (`imud --sim --offline`): its GainScales read once
//! from the EEPROM (a blank word is the configured fallback), then, each sample time, the data
//! reply of the configured command, preceded by a temperature reply at the configured rate.

use imu_bus::truth::TruthSample;
use imu_proto::command::Command;
use imu_proto::reply::Reply;
use imu_sim::DeviceCore;

use super::{Gx1Driver, sample_command, session};
use crate::config::Config;
use crate::drivers::{Driver, OfflineUnit};
use crate::pipeline::{Acquisition, GainFallback, Gains, SessionSpec};

/// The simulated unit.
pub struct Gx1Offline {
    core: DeviceCore,
    gains: Gains,
    session: SessionSpec,
    cmd: Command,
    temp_every: u64,
    driver: Gx1Driver,
}

impl Gx1Offline {
    /// The unit around `core`, read as `config` says.
    pub fn new(mut core: DeviceCore, config: &Config) -> Self {
        let period_s = core.sample_period_s();
        let fb = config.device.fallback_gains;
        let (accel, fa) = read_gain(
            &mut core,
            imu_proto::device::ACCEL_GAIN_SCALE_ADDR,
            fb.accel,
        );
        let (gyro, fg) = read_gain(&mut core, imu_proto::device::GYRO_GAIN_SCALE_ADDR, fb.gyro);
        let (mag, fm) = read_gain(&mut core, imu_proto::device::MAG_GAIN_SCALE_ADDR, fb.mag);
        let gains = Gains {
            accel,
            gyro,
            mag,
            fallback: GainFallback {
                accel: fa,
                gyro: fg,
                mag: fm,
            },
        };
        let temp_every = if config.device.temperature_rate_hz > 0.0 {
            ((1.0 / period_s) / config.device.temperature_rate_hz)
                .round()
                .max(1.0) as u64
        } else {
            u64::MAX
        };
        Self {
            core,
            gains,
            // The scenario's samples come at its own exact times: as polls, no losses to count.
            session: SessionSpec {
                acquisition: Acquisition::Polled {
                    rate_hz: 1.0 / period_s,
                },
                ..session(&config.device, gains)
            },
            cmd: sample_command(config.device.command),
            temp_every,
            driver: Gx1Driver::with_session(&config.device, gains),
        }
    }
}

fn read_gain(device: &mut DeviceCore, address: u16, fallback: u16) -> (u16, bool) {
    let reply = device
        .handle(Command::ReadEeprom { address }, 0.0)
        .reply
        .and_then(|r| Reply::decode(&r.to_bytes()).ok());
    match reply {
        Some(Reply::EepromRead { value, .. }) if value != 0 => (value, false),
        _ => (fallback, true),
    }
}

impl OfflineUnit for Gx1Offline {
    fn core(&self) -> &DeviceCore {
        &self.core
    }

    fn session(&self) -> SessionSpec {
        self.session
    }

    fn driver(&mut self) -> &mut dyn Driver {
        &mut self.driver
    }

    fn details(&self) -> Vec<(String, String)> {
        let mut d = vec![
            (
                "protocol".to_string(),
                imu_proto::DeviceProtocol::Gx1.name().to_string(),
            ),
            ("model".to_string(), super::MODEL.to_string()),
        ];
        d.extend(self.gains.metadata());
        d
    }

    fn step(&mut self, k: u64, t_s: f64, bytes: &mut Vec<u8>, truths: &mut Vec<TruthSample>) {
        if k.is_multiple_of(self.temp_every) {
            let (reply, t) = self.core.data_reply(Command::Temperature, t_s);
            reply.encode(bytes);
            truths.push(t);
        }
        let (reply, t) = self.core.data_reply(self.cmd, t_s);
        reply.encode(bytes);
        truths.push(t);
    }
}
