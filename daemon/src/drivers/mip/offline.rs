//! A simulated MIP unit for the offline path (`imud --sim --offline`): configured with the
//! live start-up's first message format (accel, gyro, mag, temperature, reference time) at its
//! own rate and resumed, then one IMU data packet each sample time.

use imu_bus::truth::TruthSample;
use imu_proto::mip::{AckCode, MipCommand, MipReply, Setting};
use imu_sim::DeviceCore;
use imu_sim::mip_device::MipDevice;

use super::{MipDriver, MipTimebase, preferred_mip_format, session};
use crate::config::Config;
use crate::drivers::{Driver, OfflineUnit};
use crate::pipeline::{Acquisition, SessionSpec};

/// The simulated unit.
pub struct MipOffline {
    device: MipDevice,
    session: SessionSpec,
    driver: MipDriver,
}

impl MipOffline {
    /// The unit around `core`, configured.
    pub fn new(core: DeviceCore, config: &Config) -> anyhow::Result<Self> {
        let period_s = core.sample_period_s();
        let mut device = MipDevice::new(core);
        let format = preferred_mip_format(device.decimation());
        for cmd in [
            MipCommand::ImuMessageFormat(Setting::Write(format)),
            MipCommand::Resume,
        ] {
            device.push(cmd.to_packet().as_bytes());
            while let Some(request) = device.next_request() {
                let request =
                    request.map_err(|n| anyhow::anyhow!("the unit rejected {n} bytes"))?;
                let reply = device.handle(request);
                let replies = MipReply::decode_packet(&reply)?;
                anyhow::ensure!(
                    replies.iter().all(|r| r.code == AckCode::Ok),
                    "the simulated unit refused {cmd:?} at {:.0} Hz: {replies:?}",
                    1.0 / period_s
                );
            }
        }
        let timebase = MipTimebase::ReferenceTime;
        Ok(Self {
            device,
            // The scenario's samples come at its own exact times: as polls, no losses to count.
            session: SessionSpec {
                acquisition: Acquisition::Polled {
                    rate_hz: 1.0 / period_s,
                },
                ..session(timebase)
            },
            driver: MipDriver::with_session(&config.device, timebase),
        })
    }
}

impl OfflineUnit for MipOffline {
    fn core(&self) -> &DeviceCore {
        self.device.core()
    }

    fn session(&self) -> SessionSpec {
        self.session
    }

    fn driver(&mut self) -> &mut dyn Driver {
        &mut self.driver
    }

    fn details(&self) -> Vec<(String, String)> {
        vec![
            (
                "protocol".to_string(),
                imu_proto::DeviceProtocol::Mip.name().to_string(),
            ),
            (
                "model".to_string(),
                imu_sim::mip_device::MODEL_NAME.to_string(),
            ),
        ]
    }

    fn step(&mut self, _k: u64, t_s: f64, bytes: &mut Vec<u8>, truths: &mut Vec<TruthSample>) {
        // The temperature comes with every packet (recorded once a second).
        let (packet, t) = self.device.data_packet(t_s);
        bytes.extend_from_slice(packet.as_bytes());
        truths.push(t);
    }
}
