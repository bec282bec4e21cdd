//! A VectorNav unit's start-up as a state machine: its ASCII output off, identify (model,
//! serial number, firmware registers), write binary output 1 (register 75) with the fields a
//! calibration needs and the rate divisor but still off, read it back and compare, then turn
//! it on. The output goes on last, like a MIP unit's resume, so every binary message after
//! that reply is a sample and none before it is: a recording replayed passively gives the
//! same samples.
//!
//! Register replies name the register they answer (`$VNRRG,03,...`, `$VNWRG,75,...`), so a
//! reply to another command is simply not the one awaited; a `$VNERR` names nothing and is
//! taken as the answer to the command outstanding. The unit may stream (its power-up `$VNYPR`
//! output, or a saved binary output) until the first write lands: those frames are logged and
//! ignored here. Time is passed in; the driver (`mod.rs`) feeds it sentences and deadlines.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail};
use imu_proto::vectornav::{
    BinaryOutputConfig, Check, IMU_RATE_HZ, Register, VnCommand, VnReply, reg,
};

use super::VnFrame;
use crate::drivers::exchange::{Exchange, Request};
use crate::drivers::streaming::StartupMachine;

/// Serial port 1 and 2 both: the unit outputs on whichever port the host is on.
pub const ASYNC_MODE_BOTH_PORTS: u16 = 3;

/// The binary output fields the start-up writes, and which models send GPS time: facts of
/// the codec (`imu_proto::vectornav`), shared with the simulated unit.
pub use imu_proto::vectornav::{calibration_fields as preferred_fields, model_has_gnss};

/// The rate divisor when neither the configuration nor the unit names one: 100 Hz.
pub const DEFAULT_DIVISOR: u16 = 8;

/// The rate divisor for `rate_hz`.
pub fn rate_divisor(rate_hz: f64) -> anyhow::Result<u16> {
    let divisor = f64::from(IMU_RATE_HZ) / rate_hz;
    if divisor < 1.0 || divisor > f64::from(u16::MAX) || (divisor - divisor.round()).abs() > 1e-6 {
        bail!(
            "device.rate-hz = {rate_hz} is not the unit's IMU rate {IMU_RATE_HZ} Hz divided by \
             a whole number"
        );
    }
    Ok(divisor.round() as u16)
}

impl Request for VnCommand {
    fn wire(&self) -> Vec<u8> {
        self.to_sentence(Check::Checksum8).as_bytes().to_vec()
    }

    fn unanswered(&self, timeout: Duration) -> anyhow::Error {
        anyhow!(
            "no reply to {} within {:.1} s",
            String::from_utf8_lossy(self.wire().trim_ascii_end()),
            timeout.as_secs_f64()
        )
    }
}

impl Exchange<VnCommand> {
    /// The register read or written, or the error code, if `reply` answers this command.
    fn reply(&self, reply: &VnReply) -> Option<Result<Register, u8>> {
        match (self.awaited()?, reply) {
            (VnCommand::Read(id), VnReply::Read(r)) if r.id() == *id => Some(Ok(r.clone())),
            (VnCommand::Write(w), VnReply::Written(r)) if r.id() == w.id() => Some(Ok(r.clone())),
            (_, VnReply::Error(code)) => Some(Err(*code)),
            _ => None,
        }
    }
}

/// Where the start-up is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Stage {
    AsyncOff,
    Model,
    Serial,
    Firmware,
    ReadCurrent,
    WriteOutput,
    ReadOutput,
    EnableOutput,
}

/// What the start-up concluded.
#[derive(Debug)]
pub enum Outcome {
    /// The output is verified and streaming: the session starts.
    Configured(Box<Configured>),
    /// Start-up failed.
    Failed(anyhow::Error),
}

/// What was set up.
#[derive(Debug, Clone, PartialEq)]
pub struct Configured {
    /// Register 1.
    pub model: String,
    /// Register 3.
    pub serial: u32,
    /// Register 4.
    pub firmware: String,
    /// Binary output 1 as read back.
    pub output: BinaryOutputConfig,
}

impl Configured {
    /// The data rate, Hz.
    pub fn rate_hz(&self) -> f64 {
        f64::from(IMU_RATE_HZ) / f64::from(self.output.rate_divisor.max(1))
    }
}

/// The start-up of one session.
#[derive(Debug)]
pub struct Startup {
    stage: Option<Stage>,
    ex: Exchange<VnCommand>,
    timeout: Duration,
    /// The divisor to configure (none: the unit's own, read before writing).
    wanted_divisor: Option<u16>,
    divisor: u16,
    model: String,
    serial: u32,
    firmware: String,
    /// Bytes to write, in order.
    pub tx: VecDeque<Vec<u8>>,
}

impl Startup {
    /// A start-up begun at `now` (the ASCII output goes off at once), configuring
    /// `wanted_divisor` (none: keeping the unit's own, or [`DEFAULT_DIVISOR`] if it has none).
    pub fn new(timeout: Duration, wanted_divisor: Option<u16>, now: Instant) -> Self {
        let mut tx = VecDeque::new();
        let ex = Exchange::new(
            VnCommand::Write(Register::AsyncOutputType(0)),
            timeout,
            now,
            &mut tx,
        );
        Self {
            stage: Some(Stage::AsyncOff),
            ex,
            timeout,
            wanted_divisor,
            divisor: wanted_divisor.unwrap_or(DEFAULT_DIVISOR),
            model: String::new(),
            serial: 0,
            firmware: String::new(),
            tx,
        }
    }

    fn send(&mut self, stage: Stage, cmd: VnCommand, now: Instant) {
        self.stage = Some(stage);
        self.ex = Exchange::new(cmd, self.timeout, now, &mut self.tx);
    }

    fn fail(&mut self, e: anyhow::Error) -> Option<Outcome> {
        self.stage = None;
        Some(Outcome::Failed(e))
    }

    /// The output wanted, still off (`on` false) or on.
    fn wanted_output(&self, on: bool) -> BinaryOutputConfig {
        BinaryOutputConfig {
            async_mode: if on { ASYNC_MODE_BOTH_PORTS } else { 0 },
            rate_divisor: self.divisor,
            fields: preferred_fields(model_has_gnss(&self.model)),
        }
    }

    fn advance(
        &mut self,
        result: anyhow::Result<Result<Register, u8>>,
        now: Instant,
    ) -> Option<Outcome> {
        let stage = self.stage?;
        let cmd = String::from_utf8_lossy(self.ex.cmd.wire().trim_ascii_end()).into_owned();
        let register = match result {
            Ok(Ok(r)) => r,
            Ok(Err(code)) => {
                return self.fail(anyhow!("the unit answered {cmd} with error {code}"));
            }
            Err(e) => return self.fail(e),
        };
        match (stage, register) {
            (Stage::AsyncOff, _) => self.send(Stage::Model, VnCommand::Read(reg::MODEL), now),
            (Stage::Model, Register::Model(m)) => {
                self.model = m;
                self.send(Stage::Serial, VnCommand::Read(reg::SERIAL_NUMBER), now);
            }
            (Stage::Serial, Register::SerialNumber(s)) => {
                self.serial = s;
                self.send(Stage::Firmware, VnCommand::Read(reg::FIRMWARE), now);
            }
            (Stage::Firmware, Register::Firmware(f)) => {
                self.firmware = f;
                if self.wanted_divisor.is_none() {
                    // No rate configured: the unit's own, as its output register holds it.
                    self.send(
                        Stage::ReadCurrent,
                        VnCommand::Read(reg::BINARY_OUTPUT_1),
                        now,
                    );
                    return None;
                }
                let write = Register::BinaryOutput {
                    index: 1,
                    config: self.wanted_output(false),
                };
                self.send(Stage::WriteOutput, VnCommand::Write(write), now);
            }
            (Stage::ReadCurrent, Register::BinaryOutput { config, .. }) => {
                if config.rate_divisor > 0 {
                    self.divisor = config.rate_divisor;
                }
                let write = Register::BinaryOutput {
                    index: 1,
                    config: self.wanted_output(false),
                };
                self.send(Stage::WriteOutput, VnCommand::Write(write), now);
            }
            (Stage::WriteOutput, _) => self.send(
                Stage::ReadOutput,
                VnCommand::Read(reg::BINARY_OUTPUT_1),
                now,
            ),
            (Stage::ReadOutput, Register::BinaryOutput { config, .. }) => {
                if config != self.wanted_output(false) {
                    return self.fail(anyhow!(
                        "the unit reads back another binary output than it acknowledged: \
                         {config:?}"
                    ));
                }
                let on = Register::BinaryOutput {
                    index: 1,
                    config: self.wanted_output(true),
                };
                self.send(Stage::EnableOutput, VnCommand::Write(on), now);
            }
            (Stage::EnableOutput, Register::BinaryOutput { config, .. }) => {
                if config != self.wanted_output(true) {
                    return self.fail(anyhow!(
                        "the unit turned on another binary output than asked: {config:?}"
                    ));
                }
                self.stage = None;
                return Some(Outcome::Configured(Box::new(Configured {
                    model: std::mem::take(&mut self.model),
                    serial: self.serial,
                    firmware: std::mem::take(&mut self.firmware),
                    output: config,
                })));
            }
            // The register named matched the one read: its value cannot be of another kind.
            (_, other) => return self.fail(anyhow!("unexpected answer to {cmd}: {other:?}")),
        }
        None
    }
}

impl StartupMachine for Startup {
    type Frame = VnFrame;
    type Outcome = Outcome;

    /// A good frame arrived at `now`: a sentence may answer, a binary message never does.
    fn on_frame(&mut self, frame: &VnFrame, now: Instant) -> Option<Outcome> {
        let VnFrame::Ascii(sentence) = frame else {
            return None;
        };
        self.stage?;
        let reply = VnReply::decode(sentence).ok()?;
        let answer = self.ex.reply(&reply)?;
        self.advance(Ok(answer), now)
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
