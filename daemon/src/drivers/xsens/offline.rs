//! A simulated Xsens MTi for the offline path (`imud --sim --offline`): configured with the
//! live start-up's first output set (HR and compensated acceleration and rate of turn,
//! magnetic field, temperature, UTC time) at the scenario's rate, then one MTData2 message
//! each sample time.

use imu_bus::truth::TruthSample;
use imu_proto::xsens::{XsensCommand, XsensReply};
use imu_sim::DeviceCore;
use imu_sim::xsens_device::XsensDevice;

use super::{XsensDriver, preferred_outputs, session};
use crate::config::Config;
use crate::drivers::{Driver, OfflineUnit};
use crate::pipeline::{Acquisition, SessionSpec};

/// The simulated unit.
pub struct XsensOffline {
    device: XsensDevice,
    session: SessionSpec,
    driver: XsensDriver,
}

impl XsensOffline {
    /// The unit around `core`, configured.
    pub fn new(core: DeviceCore, config: &Config) -> anyhow::Result<Self> {
        let rate_hz = core.scenario().rate_hz;
        let period_s = core.sample_period_s();
        let mut device = XsensDevice::new(core);
        for cmd in [
            XsensCommand::GoToConfig,
            XsensCommand::SetOutputConfiguration(preferred_outputs(rate_hz.round() as u16)),
            XsensCommand::GoToMeasurement,
        ] {
            device.push(cmd.to_message().as_bytes());
            while let Some(request) = device.next_request() {
                let request =
                    request.map_err(|n| anyhow::anyhow!("the unit rejected {n} bytes"))?;
                if let Some(reply) = device.handle(request) {
                    let reply = XsensReply::decode(&reply)?;
                    anyhow::ensure!(
                        !matches!(reply, XsensReply::Error(_)),
                        "the simulated unit refused {cmd:?} at {rate_hz} Hz: {reply:?}"
                    );
                }
            }
        }
        Ok(Self {
            device,
            // The scenario's samples come at its own exact times: as polls, no losses to count.
            session: SessionSpec {
                acquisition: Acquisition::Polled {
                    rate_hz: 1.0 / period_s,
                },
                ..session()
            },
            driver: XsensDriver::with_session(&config.device),
        })
    }
}

impl OfflineUnit for XsensOffline {
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
                imu_proto::DeviceProtocol::Xsens.name().to_string(),
            ),
            (
                "model".to_string(),
                imu_sim::xsens_device::PRODUCT_CODE.to_string(),
            ),
        ]
    }

    fn step(&mut self, _k: u64, t_s: f64, bytes: &mut Vec<u8>, truths: &mut Vec<TruthSample>) {
        let (msg, t) = self.device.data_message(t_s);
        bytes.extend_from_slice(msg.as_bytes());
        truths.push(t);
    }
}
