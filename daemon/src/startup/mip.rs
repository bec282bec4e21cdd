//! A MIP unit's start-up sequence (3DM-GX3/GX4/GX5, CV5/CV7, GQ7): idle, identify, configure
//! the IMU message format and rate, read the format back to verify it, enable the stream and
//! resume.
//!
//! MIP replies name the command they answer (descriptor set and field descriptor), so unlike
//! the GX1's no fencing is needed: a reply to another command is simply not the one awaited.
//! The format asks for scaled accel, gyro and mag, a timestamp and the temperature; what the
//! unit refuses (a nack) is dropped in a fixed order (the temperature, the magnetometer, then
//! the reference time for the older internal timestamp), and what was configured is said in
//! the log and the metadata.

use std::time::Duration;

use anyhow::{Context, anyhow, bail};
use imu_proto::DeviceProtocol;
use imu_proto::mip::command::cmd_3dm;
use imu_proto::mip::data::field;
use imu_proto::mip::descriptor_set::IMU_DATA;
use imu_proto::mip::{
    AckCode, DescriptorRate, MessageFormat, MipCommand, MipReply, Response, Setting,
};
use tokio::io::AsyncWriteExt;
use tokio_serial::SerialStream;
use tracing::{info, warn};

use super::{TRIES, back_off, no_reply};
use crate::pipeline::{Gains, MipTimebase};
use crate::session::{Daemon, DeviceIdentity, now_ns};

/// One message format to try: its clock and optional fields.
#[derive(Debug, Clone, Copy, PartialEq)]
struct FormatChoice {
    timebase: MipTimebase,
    mag: bool,
    temperature: bool,
}

/// The formats tried in order: the first the unit accepts is used.
const CHOICES: [FormatChoice; 6] = [
    FormatChoice {
        timebase: MipTimebase::ReferenceTime,
        mag: true,
        temperature: true,
    },
    FormatChoice {
        timebase: MipTimebase::ReferenceTime,
        mag: true,
        temperature: false,
    },
    FormatChoice {
        timebase: MipTimebase::ReferenceTime,
        mag: false,
        temperature: false,
    },
    FormatChoice {
        timebase: MipTimebase::InternalTimestamp,
        mag: true,
        temperature: true,
    },
    FormatChoice {
        timebase: MipTimebase::InternalTimestamp,
        mag: true,
        temperature: false,
    },
    FormatChoice {
        timebase: MipTimebase::InternalTimestamp,
        mag: false,
        temperature: false,
    },
];

impl std::fmt::Display for FormatChoice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "accel, gyro{}{}, {}",
            if self.mag { ", mag" } else { "" },
            if self.temperature {
                ", temperature"
            } else {
                ""
            },
            self.timebase.name()
        )
    }
}

impl FormatChoice {
    /// The message format at `decimation` (every field at the data rate: units that allow a
    /// slower temperature field are few, and it costs 14 bytes a packet).
    fn format(self, decimation: u16) -> MessageFormat {
        let mut fields = vec![field::SCALED_ACCEL, field::SCALED_GYRO];
        if self.mag {
            fields.push(field::SCALED_MAG);
        }
        if self.temperature {
            fields.push(field::TEMPERATURE_ABS);
        }
        fields.push(self.timebase.field());
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
enum FormatCommand {
    /// 3DM 0x08, the IMU message format (3DM-GX3/GX4/GX5).
    Legacy,
    /// 3DM 0x0F for data set 0x80 (the 7-series).
    Generic,
}

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
}

/// The message format a MIP start-up writes first (every field it wants, the reference time
/// as the clock) at `decimation`: also what the offline path configures its simulated unit with.
pub fn preferred_mip_format(decimation: u16) -> MessageFormat {
    CHOICES[0].format(decimation)
}

impl Daemon {
    /// Sends `cmd` and waits for its reply (ack or nack, with its response), tried [`TRIES`]
    /// times. Data packets that arrive meanwhile are logged as frames.
    async fn mip_exchange(
        &mut self,
        port: &mut SerialStream,
        cmd: &MipCommand,
    ) -> anyhow::Result<MipReply> {
        let timeout = Duration::from_secs_f64(self.config.device.reply_timeout_s);
        let what = format!(
            "MIP command {:02X} {:02X}",
            cmd.descriptor().0,
            cmd.descriptor().1
        );
        let mut last_error = anyhow!("not tried");
        for attempt in 0..TRIES {
            back_off(attempt).await;
            port.write_all(cmd.to_packet().as_bytes())
                .await
                .context("writing to the device")?;
            match tokio::time::timeout(timeout, self.await_mip_reply(port, cmd.descriptor())).await
            {
                Ok(Ok(reply)) => return Ok(reply),
                Ok(Err(e)) => return Err(e),
                Err(_) => last_error = no_reply(&what, timeout),
            }
        }
        Err(last_error)
    }

    /// Logs the MIP decoder's events as frames (no samples before the session's clock is set)
    /// until the reply to `awaited` (set, descriptor), which is returned.
    fn log_mip_events(&mut self, awaited: (u8, u8)) -> Option<MipReply> {
        while let Some(ev) = self.link.mip.next_event() {
            let (mono, wall) = now_ns();
            let Some(packet) = self.pipeline.log_mip_event(ev, mono, wall, &self.sinks) else {
                continue;
            };
            let reply = MipReply::decode_packet(&packet).ok().and_then(|r| {
                r.into_iter()
                    .find(|r| (r.descriptor_set, r.command) == awaited)
            });
            if reply.is_some() {
                return reply;
            }
        }
        None
    }

    /// Reads until the reply to the command `(set, descriptor)` arrives.
    async fn await_mip_reply(
        &mut self,
        port: &mut SerialStream,
        command: (u8, u8),
    ) -> anyhow::Result<MipReply> {
        let mut buf = [0u8; 512];
        loop {
            if let Some(r) = self.log_mip_events(command) {
                return Ok(r);
            }
            self.read_into_link(port, &mut buf).await?;
        }
    }

    /// [`Self::mip_exchange`] that must be acknowledged.
    async fn mip_ok(
        &mut self,
        port: &mut SerialStream,
        cmd: &MipCommand,
    ) -> anyhow::Result<Option<Response>> {
        let reply = self.mip_exchange(port, cmd).await?;
        match reply.code {
            AckCode::Ok => Ok(reply.response),
            code => bail!("the unit refused {cmd:?}: {code:?}"),
        }
    }

    /// The IMU data's base rate, Hz: the legacy command, else the generic one.
    async fn mip_base_rate(&mut self, port: &mut SerialStream) -> anyhow::Result<u16> {
        if let Ok(Some(Response::ImuBaseRate { rate_hz })) =
            self.mip_ok(port, &MipCommand::GetImuBaseRate).await
        {
            return Ok(rate_hz);
        }
        match self
            .mip_ok(
                port,
                &MipCommand::GetBaseRate {
                    descriptor_set: IMU_DATA,
                },
            )
            .await?
        {
            Some(Response::BaseRate { rate_hz, .. }) => Ok(rate_hz),
            other => bail!("unexpected base-rate response {other:?}"),
        }
    }

    /// The message format in force, and which command form the unit took.
    async fn mip_read_format(
        &mut self,
        port: &mut SerialStream,
    ) -> anyhow::Result<(MessageFormat, FormatCommand)> {
        for form in [FormatCommand::Legacy, FormatCommand::Generic] {
            match self.mip_ok(port, &form.command(Setting::Read)).await {
                Ok(Some(Response::ImuMessageFormat(f)))
                | Ok(Some(Response::MessageFormat { format: f, .. })) => return Ok((f, form)),
                Ok(other) => warn!("unexpected message-format response {other:?}"),
                Err(e) => warn!("{e:#}"),
            }
        }
        bail!("the unit reads back no IMU message format (neither 3DM 0x08 nor 0x0F)")
    }

    /// The decimation for the configured rate, or the one the unit is set to.
    fn mip_decimation(&self, base_rate_hz: u16, current: &MessageFormat) -> anyhow::Result<u16> {
        let Some(rate_hz) = self.config.device.rate_hz else {
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

    /// Writes the first format the unit accepts and verifies it by reading it back.
    async fn mip_configure(
        &mut self,
        port: &mut SerialStream,
        form: FormatCommand,
        decimation: u16,
    ) -> anyhow::Result<FormatChoice> {
        for choice in CHOICES {
            let format = choice.format(decimation);
            let reply = self
                .mip_exchange(port, &form.command(Setting::Write(format.clone())))
                .await?;
            if reply.code != AckCode::Ok {
                info!(
                    "the unit refuses {choice:?} ({:?}); trying the next format",
                    reply.code
                );
                continue;
            }
            let (back, _) = self.mip_read_format(port).await?;
            if back != format {
                bail!("the unit reads back another message format than it acknowledged: {back:?}");
            }
            return Ok(choice);
        }
        bail!("the unit accepts no message format with scaled accel, gyro and a timestamp")
    }

    /// The MIP start-up sequence on an open port.
    pub(super) async fn start_mip(
        &mut self,
        port: &mut SerialStream,
    ) -> anyhow::Result<DeviceIdentity> {
        let path = self.config.device.path.clone();
        self.mip_ok(port, &MipCommand::SetToIdle)
            .await
            .context("setting the unit to idle")?;
        let info = match self.mip_ok(port, &MipCommand::GetDeviceInfo).await? {
            Some(Response::DeviceInfo(i)) => i,
            other => bail!("unexpected device-info response {other:?}"),
        };
        let base_rate_hz = self.mip_base_rate(port).await?;
        let (current, form) = self.mip_read_format(port).await?;
        let decimation = self.mip_decimation(base_rate_hz, &current)?;
        let choice = self.mip_configure(port, form, decimation).await?;
        let stream = MipCommand::DataStream {
            descriptor_set: IMU_DATA,
            setting: Setting::Write(true),
        };
        if let Err(e) = self.mip_ok(port, &stream).await {
            warn!("enabling the IMU data stream: {e:#} (resuming anyway)");
        }
        let rate_hz = f64::from(base_rate_hz) / f64::from(decimation);
        self.pipeline
            .new_session(Gains::NOT_APPLICABLE, choice.timebase.timebase());
        self.pipeline.set_continuous(true);
        self.mip_ok(port, &MipCommand::Resume)
            .await
            .context("resuming the unit")?;
        let firmware = format_mip_firmware(info.firmware_version);
        info!(
            "device {} ({} {}) firmware {firmware} serial {}: {rate_hz} Hz, clock {}{}{}",
            path.display(),
            info.model_name,
            info.model_number,
            info.serial_number,
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
        );
        Ok(DeviceIdentity {
            protocol: DeviceProtocol::Mip,
            model: info.model_name.clone(),
            firmware,
            serial: info.serial_number.clone(),
            gains: Gains::NOT_APPLICABLE,
            details: vec![
                ("model-number".into(), info.model_number),
                ("device-options".into(), info.device_options),
                ("base-rate-hz".into(), base_rate_hz.to_string()),
                ("rate-hz".into(), rate_hz.to_string()),
                ("clock".into(), choice.timebase.name().into()),
                ("magnetometer".into(), choice.mag.to_string()),
                ("temperature".into(), choice.temperature.to_string()),
                (
                    "message-format-command".into(),
                    match form {
                        FormatCommand::Legacy => {
                            format!("0x0C 0x{:02X}", cmd_3dm::IMU_MESSAGE_FORMAT)
                        }
                        FormatCommand::Generic => format!("0x0C 0x{:02X}", cmd_3dm::MESSAGE_FORMAT),
                    },
                ),
            ],
        })
    }
}

/// A MIP firmware number as the vendor writes it: 1141 -> "1.1.41".
fn format_mip_firmware(v: u16) -> String {
    format!("{}.{}.{:02}", v / 1000, (v / 100) % 10, v % 100)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn firmware_numbers_read_as_the_vendor_writes_them() {
        assert_eq!(format_mip_firmware(1141), "1.1.41");
        assert_eq!(format_mip_firmware(2004), "2.0.04");
    }

    #[test]
    fn formats_drop_optional_fields_before_the_clock() {
        let f = CHOICES[0].format(4);
        let descriptors: Vec<u8> = f.fields.iter().map(|d| d.descriptor).collect();
        assert_eq!(descriptors, [0x04, 0x05, 0x06, 0x14, 0xD5]);
        assert!(f.fields.iter().all(|d| d.decimation == 4));
        assert_eq!(CHOICES[5].format(1).fields.len(), 3);
        assert_eq!(CHOICES[5].timebase, MipTimebase::InternalTimestamp);
    }
}
