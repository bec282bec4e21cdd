//! A MIP unit's start-up sequence (3DM-GX3/GX4/GX5, CV5/CV7, GQ7) as a state machine: idle,
//! identify, configure the IMU message format and rate, read the format back to verify it,
//! enable the stream and resume.
//!
//! MIP replies name the command they answer (descriptor set and field descriptor), so unlike
//! the GX1's no fencing is needed: a reply to another command is simply not the one awaited.
//! The format asks for scaled accel, gyro and mag, a timestamp, the temperature and the GPS
//! timestamp (the unit's GNSS time, valid or not); what the
//! unit refuses (a nack) is dropped in a fixed order (the GPS timestamp, the temperature, the
//! magnetometer, then the reference time for the older internal timestamp), and what was configured is said in
//! the log and the metadata. Time is passed in; the driver (`mod.rs`) feeds it packets and
//! deadlines.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail};
use imu_proto::mip::command::cmd_3dm;
use imu_proto::mip::data::field;
use imu_proto::mip::descriptor_set::IMU_DATA;
use imu_proto::mip::{
    AckCode, DescriptorRate, DeviceInfo, MessageFormat, MipCommand, MipReply, Packet, Response,
    Setting,
};
use tracing::{info, warn};

use super::reading::MipTimebase;
use crate::drivers::exchange::{Exchange, Request};
use crate::drivers::streaming::StartupMachine;

/// One message format to try: its clock and optional fields.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FormatChoice {
    /// The sample clock.
    pub timebase: MipTimebase,
    /// With the magnetometer.
    pub mag: bool,
    /// With the temperature.
    pub temperature: bool,
    /// With the GPS timestamp (0x12: the unit's GNSS time of each sample, for
    /// `device.time-source = "gnss"`; its valid flags say whether the unit has GNSS time).
    pub gps_time: bool,
}

/// The formats tried in order: the first the unit accepts is used.
pub const CHOICES: [FormatChoice; 7] = [
    FormatChoice {
        timebase: MipTimebase::ReferenceTime,
        mag: true,
        temperature: true,
        gps_time: true,
    },
    FormatChoice {
        timebase: MipTimebase::ReferenceTime,
        mag: true,
        temperature: true,
        gps_time: false,
    },
    FormatChoice {
        timebase: MipTimebase::ReferenceTime,
        mag: true,
        temperature: false,
        gps_time: false,
    },
    FormatChoice {
        timebase: MipTimebase::ReferenceTime,
        mag: false,
        temperature: false,
        gps_time: false,
    },
    FormatChoice {
        timebase: MipTimebase::InternalTimestamp,
        mag: true,
        temperature: true,
        gps_time: false,
    },
    FormatChoice {
        timebase: MipTimebase::InternalTimestamp,
        mag: true,
        temperature: false,
        gps_time: false,
    },
    FormatChoice {
        timebase: MipTimebase::InternalTimestamp,
        mag: false,
        temperature: false,
        gps_time: false,
    },
];

impl FormatChoice {
    /// The message format at `decimation` (every field at the data rate: units that allow a
    /// slower temperature field are few, and it costs 14 bytes a packet).
    pub fn format(self, decimation: u16) -> MessageFormat {
        let mut fields = vec![field::SCALED_ACCEL, field::SCALED_GYRO];
        if self.mag {
            fields.push(field::SCALED_MAG);
        }
        if self.temperature {
            fields.push(field::TEMPERATURE_ABS);
        }
        fields.push(self.timebase.field());
        if self.gps_time {
            fields.push(field::GPS_TIMESTAMP);
        }
        MessageFormat {
            fields: fields
                .into_iter()
                .map(|descriptor| DescriptorRate {
                    descriptor,
                    decimation,
                })
                .collect(),
        }
    }
}

/// Which form of the message-format command the unit takes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FormatCommand {
    /// 3DM 0x08, the IMU message format (3DM-GX3/GX4/GX5).
    Legacy,
    /// 3DM 0x0F for data set 0x80 (the 7-series).
    Generic,
}

const FORMS: [FormatCommand; 2] = [FormatCommand::Legacy, FormatCommand::Generic];

impl FormatCommand {
    fn command(self, setting: Setting<MessageFormat>) -> MipCommand {
        match self {
            FormatCommand::Legacy => MipCommand::ImuMessageFormat(setting),
            FormatCommand::Generic => MipCommand::MessageFormat {
                descriptor_set: IMU_DATA,
                setting,
            },
        }
    }

    /// The command's bytes as the metadata says them.
    pub fn name(self) -> String {
        match self {
            FormatCommand::Legacy => format!("0x0C 0x{:02X}", cmd_3dm::IMU_MESSAGE_FORMAT),
            FormatCommand::Generic => format!("0x0C 0x{:02X}", cmd_3dm::MESSAGE_FORMAT),
        }
    }
}

/// The message format a MIP start-up writes first (every field it wants, the reference time
/// as the clock) at `decimation`: also what the offline path configures its simulated unit with.
pub fn preferred_mip_format(decimation: u16) -> MessageFormat {
    CHOICES[0].format(decimation)
}

impl Request for MipCommand {
    fn wire(&self) -> Vec<u8> {
        self.to_packet().as_bytes().to_vec()
    }

    fn unanswered(&self, timeout: Duration) -> anyhow::Error {
        let (set, descriptor) = self.descriptor();
        anyhow!(
            "no reply to MIP command {set:02X} {descriptor:02X} within {:.1} s",
            timeout.as_secs_f64()
        )
    }
}

impl Exchange<MipCommand> {
    /// The reply (ack or nack) to this command, if `packet` holds it.
    fn reply(&self, packet: &Packet) -> Option<MipReply> {
        let awaited = self.awaited()?.descriptor();
        MipReply::decode_packet(packet).ok().and_then(|r| {
            r.into_iter()
                .find(|r| (r.descriptor_set, r.command) == awaited)
        })
    }
}

/// Why the message format is read.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Purpose {
    /// The format in force, for its decimation and the command form the unit takes.
    Current,
    /// Verifying the format of `CHOICES[choice]` just written.
    Verify { choice: usize },
}

/// Where the start-up is.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Stage {
    Idle,
    Info,
    ImuBaseRate,
    BaseRate,
    ReadFormat { form: usize, purpose: Purpose },
    WriteFormat { choice: usize },
    Stream,
    Resume,
}

/// What the start-up concluded.
#[derive(Debug)]
pub enum Outcome {
    /// The format is in force and the stream enabled: the session can start (the resume
    /// follows).
    Configured(Box<Configured>),
    /// The unit resumed: start-up is done.
    Done,
    /// Start-up failed.
    Failed(anyhow::Error),
}

/// What was set up.
#[derive(Debug, Clone)]
pub struct Configured {
    /// The unit's identity.
    pub info: DeviceInfo,
    /// The IMU data's base rate, Hz.
    pub base_rate_hz: u16,
    /// The data rate, Hz.
    pub rate_hz: f64,
    /// The format in force.
    pub choice: FormatChoice,
    /// The command form the unit took.
    pub form: FormatCommand,
}

/// The start-up of one session.
#[derive(Debug)]
pub struct Startup {
    stage: Option<Stage>,
    ex: Exchange<MipCommand>,
    timeout: Duration,
    /// Data rate to configure, Hz (none: the unit's).
    wanted_rate_hz: Option<f64>,
    info: Option<DeviceInfo>,
    base_rate_hz: u16,
    form: FormatCommand,
    decimation: u16,
    configured: Option<Configured>,
    /// Bytes to write, in order.
    pub tx: VecDeque<Vec<u8>>,
}

impl Startup {
    /// A start-up begun at `now` (the "set to idle" goes out at once).
    pub fn new(timeout: Duration, wanted_rate_hz: Option<f64>, now: Instant) -> Self {
        let mut tx = VecDeque::new();
        let ex = Exchange::new(MipCommand::SetToIdle, timeout, now, &mut tx);
        Self {
            stage: Some(Stage::Idle),
            ex,
            timeout,
            wanted_rate_hz,
            info: None,
            base_rate_hz: 0,
            form: FormatCommand::Legacy,
            decimation: 1,
            configured: None,
            tx,
        }
    }

    fn send(&mut self, stage: Stage, cmd: MipCommand, now: Instant) {
        self.stage = Some(stage);
        self.ex = Exchange::new(cmd, self.timeout, now, &mut self.tx);
    }

    fn read_format(&mut self, form: usize, purpose: Purpose, now: Instant) {
        self.send(
            Stage::ReadFormat { form, purpose },
            FORMS[form].command(Setting::Read),
            now,
        );
    }

    fn write_format(&mut self, choice: usize, now: Instant) {
        let format = CHOICES[choice].format(self.decimation);
        self.send(
            Stage::WriteFormat { choice },
            self.form.command(Setting::Write(format)),
            now,
        );
    }

    fn fail(&mut self, e: anyhow::Error) -> Option<Outcome> {
        self.stage = None;
        Some(Outcome::Failed(e))
    }

    /// The next stage after the reply (or the lack of one) to the current command.
    fn advance(&mut self, result: anyhow::Result<MipReply>, now: Instant) -> Option<Outcome> {
        let stage = self.stage?;
        let cmd = self.ex.cmd.clone();
        // The reply acknowledged (`mip_ok`), its response.
        let ok = |r: anyhow::Result<MipReply>| -> anyhow::Result<Option<Response>> {
            let reply = r?;
            match reply.code {
                AckCode::Ok => Ok(reply.response),
                code => bail!("the unit refused {cmd:?}: {code:?}"),
            }
        };
        match stage {
            Stage::Idle => match ok(result) {
                Ok(_) => self.send(Stage::Info, MipCommand::GetDeviceInfo, now),
                Err(e) => return self.fail(e.context("setting the unit to idle")),
            },
            Stage::Info => match ok(result) {
                Ok(Some(Response::DeviceInfo(i))) => {
                    self.info = Some(i);
                    self.send(Stage::ImuBaseRate, MipCommand::GetImuBaseRate, now);
                }
                Ok(other) => {
                    return self.fail(anyhow!("unexpected device-info response {other:?}"));
                }
                Err(e) => return self.fail(e),
            },
            Stage::ImuBaseRate => match ok(result) {
                Ok(Some(Response::ImuBaseRate { rate_hz })) => {
                    self.base_rate_hz = rate_hz;
                    self.read_format(0, Purpose::Current, now);
                }
                // The legacy command failed: the generic one.
                _ => self.send(
                    Stage::BaseRate,
                    MipCommand::GetBaseRate {
                        descriptor_set: IMU_DATA,
                    },
                    now,
                ),
            },
            Stage::BaseRate => match ok(result) {
                Ok(Some(Response::BaseRate { rate_hz, .. })) => {
                    self.base_rate_hz = rate_hz;
                    self.read_format(0, Purpose::Current, now);
                }
                Ok(other) => return self.fail(anyhow!("unexpected base-rate response {other:?}")),
                Err(e) => return self.fail(e),
            },
            Stage::ReadFormat { form, purpose } => {
                let format = match ok(result) {
                    Ok(Some(Response::ImuMessageFormat(f)))
                    | Ok(Some(Response::MessageFormat { format: f, .. })) => Some(f),
                    Ok(other) => {
                        warn!("unexpected message-format response {other:?}");
                        None
                    }
                    Err(e) => {
                        warn!("{e:#}");
                        None
                    }
                };
                let Some(format) = format else {
                    if form + 1 < FORMS.len() {
                        self.read_format(form + 1, purpose, now);
                        return None;
                    }
                    return self.fail(anyhow!(
                        "the unit reads back no IMU message format (neither 3DM 0x08 nor 0x0F)"
                    ));
                };
                match purpose {
                    Purpose::Current => {
                        self.form = FORMS[form];
                        match decimation(self.wanted_rate_hz, self.base_rate_hz, &format) {
                            Ok(d) => self.decimation = d,
                            Err(e) => return self.fail(e),
                        }
                        self.write_format(0, now);
                    }
                    Purpose::Verify { choice } => {
                        if format != CHOICES[choice].format(self.decimation) {
                            return self.fail(anyhow!(
                                "the unit reads back another message format than it \
                                 acknowledged: {format:?}"
                            ));
                        }
                        self.configured = Some(Configured {
                            info: self.info.clone().unwrap_or_default(),
                            base_rate_hz: self.base_rate_hz,
                            rate_hz: f64::from(self.base_rate_hz) / f64::from(self.decimation),
                            choice: CHOICES[choice],
                            form: self.form,
                        });
                        self.send(
                            Stage::Stream,
                            MipCommand::DataStream {
                                descriptor_set: IMU_DATA,
                                setting: Setting::Write(true),
                            },
                            now,
                        );
                    }
                }
            }
            Stage::WriteFormat { choice } => {
                let reply = match result {
                    Ok(r) => r,
                    Err(e) => return self.fail(e),
                };
                if reply.code == AckCode::Ok {
                    self.read_format(0, Purpose::Verify { choice }, now);
                } else {
                    info!(
                        "the unit refuses {:?} ({:?}); trying the next format",
                        CHOICES[choice], reply.code
                    );
                    if choice + 1 >= CHOICES.len() {
                        return self.fail(anyhow!(
                            "the unit accepts no message format with scaled accel, gyro and a \
                             timestamp"
                        ));
                    }
                    self.write_format(choice + 1, now);
                }
            }
            Stage::Stream => {
                if let Err(e) = ok(result) {
                    warn!("enabling the IMU data stream: {e:#} (resuming anyway)");
                }
                self.send(Stage::Resume, MipCommand::Resume, now);
                let configured = self.configured.clone()?;
                return Some(Outcome::Configured(Box::new(configured)));
            }
            Stage::Resume => {
                self.stage = None;
                return match ok(result) {
                    Ok(_) => Some(Outcome::Done),
                    Err(e) => Some(Outcome::Failed(e.context("resuming the unit"))),
                };
            }
        }
        None
    }
}

impl StartupMachine for Startup {
    type Frame = Packet;
    type Outcome = Outcome;

    /// A good packet arrived at `now`.
    fn on_frame(&mut self, packet: &Packet, now: Instant) -> Option<Outcome> {
        self.stage?;
        let reply = self.ex.reply(packet)?;
        self.advance(Ok(reply), now)
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

/// The decimation for the wanted rate, or the one the unit is set to.
fn decimation(
    wanted_rate_hz: Option<f64>,
    base_rate_hz: u16,
    current: &MessageFormat,
) -> anyhow::Result<u16> {
    let Some(rate_hz) = wanted_rate_hz else {
        return Ok(current
            .fields
            .iter()
            .find(|f| f.descriptor == field::SCALED_ACCEL)
            .or(current.fields.first())
            .map_or(u16::max(base_rate_hz / 100, 1), |f| f.decimation.max(1)));
    };
    let decimation = f64::from(base_rate_hz) / rate_hz;
    if decimation < 1.0 || (decimation - decimation.round()).abs() > 1e-6 {
        bail!(
            "device.rate-hz = {rate_hz} is not the unit's base rate {base_rate_hz} Hz divided \
             by a whole number"
        );
    }
    Ok(decimation.round() as u16)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_drop_optional_fields_before_the_clock() {
        let f = CHOICES[0].format(4);
        let descriptors: Vec<u8> = f.fields.iter().map(|d| d.descriptor).collect();
        assert_eq!(descriptors, [0x04, 0x05, 0x06, 0x14, 0xD5, 0x12]);
        assert!(f.fields.iter().all(|d| d.decimation == 4));
        // The GPS timestamp goes first.
        let descriptors: Vec<u8> = CHOICES[1]
            .format(4)
            .fields
            .iter()
            .map(|d| d.descriptor)
            .collect();
        assert_eq!(descriptors, [0x04, 0x05, 0x06, 0x14, 0xD5]);
        assert_eq!(CHOICES[6].format(1).fields.len(), 3);
        assert_eq!(CHOICES[6].timebase, MipTimebase::InternalTimestamp);
    }
}
