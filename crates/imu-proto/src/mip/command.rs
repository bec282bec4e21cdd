//! The MIP commands a host needs to identify, configure and stream an IMU, as typed values
//! with `encode` (host side) and `decode` (device side).

use super::descriptor_set::{BASE_COMMAND, COMMAND_3DM};
use super::packet::{Field, Reader, Writer};
use super::{MipError, Packet, PacketBuilder};

/// Base command descriptors (set 0x01).
pub mod base {
    /// Ping: the device acks.
    pub const PING: u8 = 0x01;
    /// Stop streaming and wait for commands.
    pub const SET_TO_IDLE: u8 = 0x02;
    /// Model, serial number, firmware.
    pub const GET_DEVICE_INFO: u8 = 0x03;
    /// Back to the mode before set-to-idle (streaming, if it was).
    pub const RESUME: u8 = 0x06;
}

/// 3DM command descriptors (set 0x0C).
pub mod cmd_3dm {
    /// The IMU data's base rate, Hz.
    pub const GET_IMU_BASE_RATE: u8 = 0x06;
    /// Which IMU fields are streamed, each at base rate / decimation.
    pub const IMU_MESSAGE_FORMAT: u8 = 0x08;
    /// The base rate of any data set, Hz (the 5- and 7-series' generic form of 0x06).
    pub const GET_BASE_RATE: u8 = 0x0E;
    /// The message format of any data set (the generic form of 0x08).
    pub const MESSAGE_FORMAT: u8 = 0x0F;
    /// Turn the stream of one data set on or off.
    pub const DATA_STREAM: u8 = 0x11;
}

/// A settings command's function selector and, for a write, the value written.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Setting<T> {
    /// Use the new value (selector 1).
    Write(T),
    /// Report the current value (selector 2).
    Read,
    /// Save the current value as the start-up value (selector 3).
    Save,
    /// Load the saved start-up value (selector 4).
    Load,
    /// Restore the factory default (selector 5).
    Reset,
}

impl<T> Setting<T> {
    /// The function selector byte.
    pub fn selector(&self) -> u8 {
        match self {
            Setting::Write(_) => 1,
            Setting::Read => 2,
            Setting::Save => 3,
            Setting::Load => 4,
            Setting::Reset => 5,
        }
    }

    /// Reads the selector; a write reads its value with `value`.
    fn decode(
        r: &mut Reader<'_>,
        value: impl FnOnce(&mut Reader<'_>) -> Result<T, MipError>,
    ) -> Result<Self, MipError> {
        let selector = r.u8()?;
        Self::from_selector(selector, r, value)
    }

    /// The setting of a selector already read (some commands put an argument between the
    /// selector and the value); a write reads its value with `value`.
    fn from_selector(
        selector: u8,
        r: &mut Reader<'_>,
        value: impl FnOnce(&mut Reader<'_>) -> Result<T, MipError>,
    ) -> Result<Self, MipError> {
        Ok(match selector {
            1 => Setting::Write(value(r)?),
            2 => Setting::Read,
            3 => Setting::Save,
            4 => Setting::Load,
            5 => Setting::Reset,
            _ => return Err(r.error("function selector is not 1..=5")),
        })
    }
}

/// One data field of a message format and its decimation (rate = base rate / decimation).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DescriptorRate {
    /// Field descriptor in the data set.
    pub descriptor: u8,
    /// Base-rate divider, at least 1.
    pub decimation: u16,
}

/// The fields of one data set's message, in order.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct MessageFormat {
    /// The fields and their decimations.
    pub fields: Vec<DescriptorRate>,
}

impl MessageFormat {
    /// Most fields a format carries: the reply's response field shares the packet with the
    /// 4-byte ack, leaving 249 data bytes: a data set byte (0x8F), the count and 82 x 3 bytes.
    /// Encoding writes at most this many (the first ones).
    pub const MAX_FIELDS: usize = 82;

    pub(crate) fn encode(&self, w: &mut Writer) {
        let fields = &self.fields[..self.fields.len().min(Self::MAX_FIELDS)];
        w.u8(fields.len() as u8);
        for f in fields {
            w.u8(f.descriptor).u16(f.decimation);
        }
    }

    pub(crate) fn decode(r: &mut Reader<'_>) -> Result<Self, MipError> {
        let n = usize::from(r.u8()?);
        if r.remaining() != 3 * n {
            return Err(r.error("descriptor count disagrees with the field length"));
        }
        let fields = (0..n)
            .map(|_| {
                Ok(DescriptorRate {
                    descriptor: r.u8()?,
                    decimation: r.u16()?,
                })
            })
            .collect::<Result<_, MipError>>()?;
        Ok(Self { fields })
    }
}

/// A command from the host.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum MipCommand {
    /// Base 0x01: is anyone there.
    Ping,
    /// Base 0x02: stop streaming, wait for commands.
    SetToIdle,
    /// Base 0x03: model, serial number, firmware.
    GetDeviceInfo,
    /// Base 0x06: back to the mode before idle.
    Resume,
    /// 3DM 0x06: the IMU data's base rate.
    GetImuBaseRate,
    /// 3DM 0x08: the IMU message format.
    ImuMessageFormat(Setting<MessageFormat>),
    /// 3DM 0x0E: the base rate of a data set.
    GetBaseRate {
        /// Which data set (0x80 for the IMU).
        descriptor_set: u8,
    },
    /// 3DM 0x0F: the message format of a data set.
    MessageFormat {
        /// Which data set (0x80 for the IMU).
        descriptor_set: u8,
        /// The format to write, or another function.
        setting: Setting<MessageFormat>,
    },
    /// 3DM 0x11: the stream of one data set on or off.
    DataStream {
        /// Which data set (0x80 for the IMU).
        descriptor_set: u8,
        /// Enable (`true`) or disable, or another function.
        setting: Setting<bool>,
    },
}

impl MipCommand {
    /// The descriptor set and field descriptor.
    pub fn descriptor(&self) -> (u8, u8) {
        match self {
            MipCommand::Ping => (BASE_COMMAND, base::PING),
            MipCommand::SetToIdle => (BASE_COMMAND, base::SET_TO_IDLE),
            MipCommand::GetDeviceInfo => (BASE_COMMAND, base::GET_DEVICE_INFO),
            MipCommand::Resume => (BASE_COMMAND, base::RESUME),
            MipCommand::GetImuBaseRate => (COMMAND_3DM, cmd_3dm::GET_IMU_BASE_RATE),
            MipCommand::ImuMessageFormat(_) => (COMMAND_3DM, cmd_3dm::IMU_MESSAGE_FORMAT),
            MipCommand::GetBaseRate { .. } => (COMMAND_3DM, cmd_3dm::GET_BASE_RATE),
            MipCommand::MessageFormat { .. } => (COMMAND_3DM, cmd_3dm::MESSAGE_FORMAT),
            MipCommand::DataStream { .. } => (COMMAND_3DM, cmd_3dm::DATA_STREAM),
        }
    }

    /// The command's field data.
    fn encode_data(&self) -> Vec<u8> {
        let mut w = Writer::default();
        match self {
            MipCommand::ImuMessageFormat(s) => {
                w.u8(s.selector());
                if let Setting::Write(format) = s {
                    format.encode(&mut w);
                }
            }
            MipCommand::GetBaseRate { descriptor_set } => {
                w.u8(*descriptor_set);
            }
            MipCommand::MessageFormat {
                descriptor_set,
                setting,
            } => {
                w.u8(setting.selector()).u8(*descriptor_set);
                if let Setting::Write(format) = setting {
                    format.encode(&mut w);
                }
            }
            MipCommand::DataStream {
                descriptor_set,
                setting,
            } => {
                w.u8(setting.selector()).u8(*descriptor_set);
                if let Setting::Write(enable) = setting {
                    w.u8(u8::from(*enable));
                }
            }
            _ => {}
        }
        w.data
    }

    /// The command alone in one packet, ready to send. A message format longer than
    /// [`MessageFormat::MAX_FIELDS`] is cut to that many fields.
    pub fn to_packet(&self) -> Packet {
        let (set, descriptor) = self.descriptor();
        let mut b = PacketBuilder::new(set);
        // Cannot fail: the longest command, a full message format (0x0F), is 2 + 3 + 82 x 3
        // bytes.
        let _ = b.field(descriptor, &self.encode_data());
        b.build()
    }

    /// Decodes one command field of a packet of descriptor set `set` (device side).
    pub fn decode(set: u8, field: Field<'_>) -> Result<Self, MipError> {
        let mut r = Reader::new(set, field);
        let cmd = match (set, field.descriptor) {
            (BASE_COMMAND, base::PING) => MipCommand::Ping,
            (BASE_COMMAND, base::SET_TO_IDLE) => MipCommand::SetToIdle,
            (BASE_COMMAND, base::GET_DEVICE_INFO) => MipCommand::GetDeviceInfo,
            (BASE_COMMAND, base::RESUME) => MipCommand::Resume,
            (COMMAND_3DM, cmd_3dm::GET_IMU_BASE_RATE) => MipCommand::GetImuBaseRate,
            (COMMAND_3DM, cmd_3dm::IMU_MESSAGE_FORMAT) => {
                MipCommand::ImuMessageFormat(Setting::decode(&mut r, MessageFormat::decode)?)
            }
            (COMMAND_3DM, cmd_3dm::GET_BASE_RATE) => MipCommand::GetBaseRate {
                descriptor_set: r.u8()?,
            },
            (COMMAND_3DM, cmd_3dm::MESSAGE_FORMAT) => {
                let selector = r.u8()?;
                let descriptor_set = r.u8()?;
                MipCommand::MessageFormat {
                    descriptor_set,
                    setting: Setting::from_selector(selector, &mut r, MessageFormat::decode)?,
                }
            }
            (COMMAND_3DM, cmd_3dm::DATA_STREAM) => {
                let selector = r.u8()?;
                let descriptor_set = r.u8()?;
                let setting = Setting::from_selector(selector, &mut r, |r| match r.u8()? {
                    0 => Ok(false),
                    1 => Ok(true),
                    _ => Err(r.error("enable flag is not 0 or 1")),
                })?;
                MipCommand::DataStream {
                    descriptor_set,
                    setting,
                }
            }
            (set, descriptor) => return Err(MipError::UnknownCommand { set, descriptor }),
        };
        r.end()?;
        Ok(cmd)
    }

    /// Every command field of a packet, in order (a packet may carry several commands).
    pub fn decode_packet(
        packet: &Packet,
    ) -> impl Iterator<Item = (u8, Result<Self, MipError>)> + '_ {
        let set = packet.descriptor_set();
        packet
            .fields()
            .map(move |f| (f.descriptor, Self::decode(set, f)))
    }
}
