//! An Xsens MTi's start-up sequence as a state machine: config mode, identify (device id,
//! product code, firmware), read the output configuration in force (for its rate when none is
//! configured), write the outputs and rate, read them back to verify, measurement mode.
//!
//! A unit powers up streaming, so the `GoToConfig` acknowledgement may come after data
//! messages already in flight: every request is answered by the next message id (0x30 ->
//! 0x31), so a message of another id is simply not the one awaited. An `Error` message
//! refuses the request awaited. The outputs ask for the HR acceleration and rate of turn (the
//! reading imud calibrates), the compensated ones beside them, the magnetic field, the
//! temperature and the UTC time; what the unit refuses is dropped in a fixed order
//! ([`CHOICES`]) and what was configured is said in the log and the metadata. Time is passed
//! in; the driver (`mod.rs`) feeds it messages and deadlines.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail};
use imu_proto::xsens::command::error_name;
use imu_proto::xsens::data::id;
use imu_proto::xsens::{
    DataId, FirmwareRev, Message, OutputConfiguration, OutputSetting, XsensCommand, XsensReply, mid,
};
use tracing::{info, warn};

use super::reading::RawSource;
use crate::drivers::exchange::{Exchange, Request};
use crate::drivers::streaming::StartupMachine;

/// The rate configured when neither the configuration nor the unit names one, Hz.
const DEFAULT_RATE_HZ: u16 = 100;
/// Rate word of the items sent with every sample (counter, clock).
const EVERY_SAMPLE: u16 = 0xFFFF;

/// One set of outputs to try.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutputChoice {
    /// Which outputs are the raw reading.
    pub raw: RawSource,
    /// With the HR outputs, the compensated ones beside them (always there when they are the
    /// raw reading).
    pub compensated: bool,
    /// With the magnetic field.
    pub mag: bool,
    /// With the temperature.
    pub temperature: bool,
    /// With the UTC time.
    pub utc: bool,
}

/// The output sets tried in order: the first the unit accepts is used. The HR outputs alone
/// (fourth) serve a unit that refuses its compensated outputs and magnetic field at the HR
/// rate: they come from its filter, whose rate is lower than the HR outputs' on some series.
pub const CHOICES: [OutputChoice; 7] = [
    OutputChoice {
        raw: RawSource::HighRate,
        compensated: true,
        mag: true,
        temperature: true,
        utc: true,
    },
    OutputChoice {
        raw: RawSource::HighRate,
        compensated: true,
        mag: true,
        temperature: true,
        utc: false,
    },
    OutputChoice {
        raw: RawSource::HighRate,
        compensated: true,
        mag: false,
        temperature: false,
        utc: false,
    },
    OutputChoice {
        raw: RawSource::HighRate,
        compensated: false,
        mag: false,
        temperature: true,
        utc: true,
    },
    OutputChoice {
        raw: RawSource::Compensated,
        compensated: true,
        mag: true,
        temperature: true,
        utc: true,
    },
    OutputChoice {
        raw: RawSource::Compensated,
        compensated: true,
        mag: true,
        temperature: false,
        utc: false,
    },
    OutputChoice {
        raw: RawSource::Compensated,
        compensated: true,
        mag: false,
        temperature: false,
        utc: false,
    },
];

impl OutputChoice {
    /// The output configuration at `rate_hz` (float32; the counter and the clock with every
    /// sample). With the HR outputs, the compensated ones (if chosen) come at the same rate
    /// beside them.
    pub fn outputs(self, rate_hz: u16) -> OutputConfiguration {
        let mut out = vec![
            (id::PACKET_COUNTER, EVERY_SAMPLE),
            (id::SAMPLE_TIME_FINE, EVERY_SAMPLE),
        ];
        if self.utc {
            out.push((id::UTC_TIME, rate_hz));
        }
        if self.temperature {
            out.push((id::TEMPERATURE, rate_hz));
        }
        if self.raw == RawSource::HighRate {
            out.extend([
                (id::ACCELERATION_HR, rate_hz),
                (id::RATE_OF_TURN_HR, rate_hz),
            ]);
        }
        if self.compensated || self.raw == RawSource::Compensated {
            out.extend([(id::ACCELERATION, rate_hz), (id::RATE_OF_TURN, rate_hz)]);
        }
        if self.mag {
            out.push((id::MAGNETIC_FIELD, rate_hz));
        }
        OutputConfiguration(
            out.into_iter()
                .map(|(data_id, rate_hz)| OutputSetting { data_id, rate_hz })
                .collect(),
        )
    }

    /// The outputs' names, for the metadata.
    pub fn describe(self) -> String {
        let mut parts = vec!["PacketCounter", "SampleTimeFine"];
        if self.utc {
            parts.push("UtcTime");
        }
        if self.temperature {
            parts.push("Temperature");
        }
        if self.raw == RawSource::HighRate {
            parts.extend(["AccelerationHR", "RateOfTurnHR"]);
        }
        if self.compensated || self.raw == RawSource::Compensated {
            parts.extend(["Acceleration", "RateOfTurn"]);
        }
        if self.mag {
            parts.push("MagneticField");
        }
        parts.join(",")
    }
}

/// The outputs a start-up writes first at `rate_hz`: also what the offline path configures its
/// simulated unit with.
pub fn preferred_outputs(rate_hz: u16) -> OutputConfiguration {
    CHOICES[0].outputs(rate_hz)
}

/// The MID that answers a request: the next one.
fn reply_mid(cmd: &XsensCommand) -> u8 {
    cmd.to_message().mid().wrapping_add(1)
}

impl Request for XsensCommand {
    fn wire(&self) -> Vec<u8> {
        self.to_message().as_bytes().to_vec()
    }

    fn unanswered(&self, timeout: Duration) -> anyhow::Error {
        anyhow!(
            "no answer to Xsens message 0x{:02X} within {:.1} s",
            self.to_message().mid(),
            timeout.as_secs_f64()
        )
    }
}

impl Exchange<XsensCommand> {
    /// The answer to this request, if `msg` is it: its reply, or `Err(code)` for an `Error`
    /// message (but not while entering config mode: a streaming unit may report a stream
    /// error then, which is no refusal of `GoToConfig`).
    fn reply(&self, msg: &Message) -> Option<Result<XsensReply, u8>> {
        let cmd = self.awaited()?;
        if msg.mid() == mid::ERROR && *cmd != XsensCommand::GoToConfig {
            return match XsensReply::decode(msg) {
                Ok(XsensReply::Error(code)) => Some(Err(code)),
                _ => None,
            };
        }
        if msg.mid() != reply_mid(cmd) {
            return None;
        }
        XsensReply::decode(msg).ok().map(Ok)
    }
}

/// Why the output configuration is read.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Purpose {
    /// The configuration in force, for its rate.
    Current,
    /// Verifying the outputs of `CHOICES[choice]` just written.
    Verify { choice: usize },
}

/// Where the start-up is.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Stage {
    Config,
    DeviceId,
    ProductCode,
    Firmware,
    ReadOutputs(Purpose),
    WriteOutputs { choice: usize },
    Measurement,
}

/// What the start-up concluded.
#[derive(Debug)]
pub enum Outcome {
    /// The outputs are in force and `GoToMeasurement` is out: the session can start.
    Configured(Box<Configured>),
    /// The unit is in measurement mode: start-up is done.
    Done,
    /// Start-up failed.
    Failed(anyhow::Error),
}

/// What was set up.
#[derive(Debug, Clone, PartialEq)]
pub struct Configured {
    /// The device id (the serial number).
    pub device_id: u64,
    /// The product code (the model).
    pub product_code: String,
    /// The firmware revision.
    pub firmware: FirmwareRev,
    /// The output rate, Hz.
    pub rate_hz: u16,
    /// The outputs in force.
    pub choice: OutputChoice,
}

/// The start-up of one session.
#[derive(Debug)]
pub struct Startup {
    stage: Option<Stage>,
    ex: Exchange<XsensCommand>,
    timeout: Duration,
    /// Output rate to configure, Hz (none: the unit's).
    wanted_rate_hz: Option<f64>,
    rate_hz: u16,
    device_id: u64,
    product_code: String,
    firmware: FirmwareRev,
    configured: Option<Configured>,
    /// Bytes to write, in order.
    pub tx: VecDeque<Vec<u8>>,
}

impl Startup {
    /// A start-up begun at `now` (`GoToConfig` goes out at once).
    pub fn new(timeout: Duration, wanted_rate_hz: Option<f64>, now: Instant) -> Self {
        let mut tx = VecDeque::new();
        let ex = Exchange::new(XsensCommand::GoToConfig, timeout, now, &mut tx);
        Self {
            stage: Some(Stage::Config),
            ex,
            timeout,
            wanted_rate_hz,
            rate_hz: DEFAULT_RATE_HZ,
            device_id: 0,
            product_code: String::new(),
            firmware: FirmwareRev::default(),
            configured: None,
            tx,
        }
    }

    fn send(&mut self, stage: Stage, cmd: XsensCommand, now: Instant) {
        self.stage = Some(stage);
        self.ex = Exchange::new(cmd, self.timeout, now, &mut self.tx);
    }

    fn write_outputs(&mut self, choice: usize, now: Instant) {
        let outputs = CHOICES[choice].outputs(self.rate_hz);
        self.send(
            Stage::WriteOutputs { choice },
            XsensCommand::SetOutputConfiguration(outputs),
            now,
        );
    }

    fn fail(&mut self, e: anyhow::Error) -> Option<Outcome> {
        self.stage = None;
        Some(Outcome::Failed(e))
    }

    /// The next stage after the reply (or the lack of one) to the current request.
    fn advance(&mut self, result: anyhow::Result<XsensReply>, now: Instant) -> Option<Outcome> {
        let stage = self.stage?;
        match (stage, result) {
            (Stage::Config, Ok(_)) => self.send(Stage::DeviceId, XsensCommand::ReqDeviceId, now),
            (Stage::Config, Err(e)) => return self.fail(e.context("entering config mode")),
            (Stage::DeviceId, Ok(XsensReply::DeviceId(id))) => {
                self.device_id = id;
                self.send(Stage::ProductCode, XsensCommand::ReqProductCode, now);
            }
            (Stage::ProductCode, Ok(XsensReply::ProductCode(code))) => {
                self.product_code = code;
                self.send(Stage::Firmware, XsensCommand::ReqFirmwareRev, now);
            }
            (Stage::Firmware, Ok(XsensReply::FirmwareRev(fw))) => {
                self.firmware = fw;
                self.send(
                    Stage::ReadOutputs(Purpose::Current),
                    XsensCommand::ReqOutputConfiguration,
                    now,
                );
            }
            (Stage::ReadOutputs(purpose), Ok(XsensReply::OutputConfiguration(config))) => {
                match purpose {
                    Purpose::Current => {
                        match output_rate(self.wanted_rate_hz, &config) {
                            Ok(rate) => self.rate_hz = rate,
                            Err(e) => return self.fail(e),
                        }
                        self.write_outputs(0, now);
                    }
                    Purpose::Verify { choice } => {
                        if config != CHOICES[choice].outputs(self.rate_hz) {
                            return self.fail(anyhow!(
                                "the unit reads back other outputs than it acknowledged: \
                                 {config:?}"
                            ));
                        }
                        self.configured = Some(Configured {
                            device_id: self.device_id,
                            product_code: self.product_code.clone(),
                            firmware: self.firmware,
                            rate_hz: self.rate_hz,
                            choice: CHOICES[choice],
                        });
                        self.send(Stage::Measurement, XsensCommand::GoToMeasurement, now);
                        let configured = self.configured.clone()?;
                        return Some(Outcome::Configured(Box::new(configured)));
                    }
                }
            }
            (Stage::WriteOutputs { choice }, Ok(XsensReply::OutputConfiguration(_))) => {
                self.send(
                    Stage::ReadOutputs(Purpose::Verify { choice }),
                    XsensCommand::ReqOutputConfiguration,
                    now,
                );
            }
            (Stage::WriteOutputs { choice }, Err(e)) => {
                info!(
                    "the unit refuses the outputs {} at {} Hz ({e:#}); trying the next set",
                    CHOICES[choice].describe(),
                    self.rate_hz
                );
                if choice + 1 >= CHOICES.len() {
                    return self.fail(anyhow!(
                        "the unit accepts no output configuration with SampleTimeFine, an \
                         acceleration and a rate of turn at {} Hz",
                        self.rate_hz
                    ));
                }
                self.write_outputs(choice + 1, now);
            }
            (Stage::Measurement, result) => {
                self.stage = None;
                return match result {
                    Ok(_) => Some(Outcome::Done),
                    Err(e) => Some(Outcome::Failed(e.context("entering measurement mode"))),
                };
            }
            (stage, Ok(other)) => {
                return self.fail(anyhow!(
                    "unexpected answer {other:?} in start-up stage {stage:?}"
                ));
            }
            (stage, Err(e)) => {
                warn!("Xsens start-up stage {stage:?}: {e:#}");
                return self.fail(e);
            }
        }
        None
    }
}

impl StartupMachine for Startup {
    type Frame = Message;
    type Outcome = Outcome;

    /// A good message arrived at `now`.
    fn on_frame(&mut self, msg: &Message, now: Instant) -> Option<Outcome> {
        self.stage?;
        let reply = self.ex.reply(msg)?;
        self.advance(
            reply.map_err(|code| anyhow!("error {code}: {}", error_name(code))),
            now,
        )
    }

    /// A deadline passed.
    fn on_timeout(&mut self, now: Instant) -> Option<Outcome> {
        self.stage?;
        let e = self.ex.on_timeout(now, &mut self.tx)?;
        self.advance(Err(e), now)
    }

    /// When `on_timeout` is next due.
    fn deadline(&self) -> Option<Instant> {
        self.stage.map(|_| self.ex.until())
    }

    fn transmit(&mut self) -> Option<Vec<u8>> {
        self.tx.pop_front()
    }
}

/// The output rate for the wanted one, or the one the unit is set to (its first output with a
/// rate), or [`DEFAULT_RATE_HZ`].
fn output_rate(wanted_rate_hz: Option<f64>, current: &OutputConfiguration) -> anyhow::Result<u16> {
    let Some(rate_hz) = wanted_rate_hz else {
        return Ok(current
            .0
            .iter()
            .filter(|s| DataId(s.data_id).base() != id::PACKET_COUNTER)
            .map(|s| s.rate_hz)
            .find(|&r| r != 0 && r != EVERY_SAMPLE)
            .unwrap_or(DEFAULT_RATE_HZ));
    };
    if !(1.0..65535.0).contains(&rate_hz) || rate_hz.fract() != 0.0 {
        bail!("device.rate-hz = {rate_hz} is not an Xsens output rate (a whole number of Hz)");
    }
    Ok(rate_hz as u16)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn output_sets_drop_optional_outputs_then_the_hr_ones() {
        let ids: Vec<u16> = CHOICES[0]
            .outputs(400)
            .0
            .iter()
            .map(|s| s.data_id)
            .collect();
        assert_eq!(
            ids,
            [
                0x1020, 0x1060, 0x1010, 0x0810, 0x4040, 0x8040, 0x4020, 0x8020, 0xC020
            ]
        );
        assert!(
            CHOICES[0].outputs(400).0[2..]
                .iter()
                .all(|s| s.rate_hz == 400)
        );
        let last = CHOICES[CHOICES.len() - 1];
        assert_eq!(last.outputs(100).0.len(), 4);
        assert_eq!(last.raw, RawSource::Compensated);
        assert_eq!(
            CHOICES[2].describe(),
            "PacketCounter,SampleTimeFine,AccelerationHR,RateOfTurnHR,Acceleration,RateOfTurn"
        );
    }

    #[test]
    fn the_rate_is_the_configured_one_or_the_unit_s() {
        let current = CHOICES[3].outputs(200);
        assert_eq!(output_rate(None, &current).unwrap(), 200);
        assert_eq!(output_rate(Some(1000.0), &current).unwrap(), 1000);
        assert_eq!(
            output_rate(None, &OutputConfiguration::default()).unwrap(),
            DEFAULT_RATE_HZ
        );
        let e = output_rate(Some(99.5), &current).unwrap_err().to_string();
        assert!(e.contains("device.rate-hz"), "{e}");
    }
}
