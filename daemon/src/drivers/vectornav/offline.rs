//! A simulated VectorNav unit for the offline path (`imud --sim --offline`): configured with
//! the live start-up's writes (ASCII output off, binary output 1 with the preferred fields at
//! the scenario's rate), then one binary message each sample time.

use imu_bus::truth::TruthSample;
use imu_proto::vectornav::{
    BinaryOutputConfig, Check, IMU_RATE_HZ, Register, VnCommand, VnDecoder, VnEvent, VnReply,
};
use imu_sim::DeviceCore;
use imu_sim::vectornav_device::VnDevice;

use super::startup::{ASYNC_MODE_BOTH_PORTS, model_has_gnss, preferred_fields};
use super::{VnDriver, fields_name, session};
use crate::config::Config;
use crate::drivers::{Driver, OfflineUnit};
use crate::pipeline::{Acquisition, SessionSpec};

/// The simulated unit.
pub struct VnOffline {
    device: VnDevice,
    session: SessionSpec,
    driver: VnDriver,
    output: BinaryOutputConfig,
}

impl VnOffline {
    /// The unit around `core`, configured.
    pub fn new(core: DeviceCore, config: &Config) -> anyhow::Result<Self> {
        let period_s = core.sample_period_s();
        let rate_hz = core.scenario().rate_hz;
        let mut device = VnDevice::new(core);
        let output = BinaryOutputConfig {
            async_mode: ASYNC_MODE_BOTH_PORTS,
            rate_divisor: (f64::from(IMU_RATE_HZ) / rate_hz).round() as u16,
            fields: preferred_fields(model_has_gnss(device.model())),
        };
        for cmd in [
            VnCommand::Write(Register::AsyncOutputType(0)),
            VnCommand::Write(Register::BinaryOutput {
                index: 1,
                config: output,
            }),
        ] {
            device.push(cmd.to_sentence(Check::Checksum8).as_bytes());
            while let Some(request) = device.next_request() {
                let request =
                    request.map_err(|n| anyhow::anyhow!("the unit rejected {n} bytes"))?;
                let mut d = VnDecoder::new();
                d.push(&device.handle(request));
                let reply = match d.next_event() {
                    Some(VnEvent::Ascii { sentence, .. }) => VnReply::decode(&sentence)?,
                    other => anyhow::bail!("the simulated unit answered {other:?}"),
                };
                anyhow::ensure!(
                    matches!(reply, VnReply::Written(_)),
                    "the simulated unit refused {cmd:?} at {rate_hz} Hz: {reply:?}"
                );
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
            driver: VnDriver::with_session(&config.device),
            output,
        })
    }
}

impl OfflineUnit for VnOffline {
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
                imu_proto::DeviceProtocol::Vectornav.name().to_string(),
            ),
            ("model".to_string(), self.device.model().to_string()),
            ("outputs".to_string(), fields_name(&self.output.fields)),
        ]
    }

    fn step(&mut self, _k: u64, t_s: f64, bytes: &mut Vec<u8>, truths: &mut Vec<TruthSample>) {
        // The temperature comes with every message (recorded once a second).
        if let Some(t) = self.device.stream_sample(t_s, bytes) {
            truths.push(t);
        }
    }
}
