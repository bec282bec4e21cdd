//! Device replies to commands: the ack/nack field (0xF1) and the response fields a host reads
//! back (device info, IMU base rate, IMU message format, data stream state).

use super::command::MessageFormat;
use super::descriptor_set::{BASE_COMMAND, COMMAND_3DM};
use super::packet::{Field, Reader, Writer};
use super::{MipError, Packet, PacketBuilder};

/// The field descriptor of an ack/nack, in every command set.
pub const ACK_DESCRIPTOR: u8 = 0xF1;

/// Response field descriptors.
pub mod response {
    /// Base set: device info.
    pub const DEVICE_INFO: u8 = 0x81;
    /// 3DM set: IMU message format.
    pub const IMU_MESSAGE_FORMAT: u8 = 0x80;
    /// 3DM set: IMU base rate.
    pub const IMU_BASE_RATE: u8 = 0x83;
    /// 3DM set: data stream enabled.
    pub const DATA_STREAM: u8 = 0x85;
    /// 3DM set: base rate of a data set.
    pub const BASE_RATE: u8 = 0x8E;
    /// 3DM set: message format of a data set.
    pub const MESSAGE_FORMAT: u8 = 0x8F;
}

/// The ack/nack code (mip_sdk `mip_result.h`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum AckCode {
    /// 0x00: done.
    Ok,
    /// 0x01: the command is not supported.
    UnknownCommand,
    /// 0x02: invalid checksum (reserved).
    InvalidChecksum,
    /// 0x03: a parameter is not a supported value.
    InvalidParameter,
    /// 0x04: the device could not complete the command.
    CommandFailed,
    /// 0x05: internal device timeout.
    DeviceTimeout,
    /// Any other code.
    Other(u8),
}

impl AckCode {
    /// The code byte.
    pub fn code(self) -> u8 {
        match self {
            AckCode::Ok => 0,
            AckCode::UnknownCommand => 1,
            AckCode::InvalidChecksum => 2,
            AckCode::InvalidParameter => 3,
            AckCode::CommandFailed => 4,
            AckCode::DeviceTimeout => 5,
            AckCode::Other(c) => c,
        }
    }

    /// The code of a byte.
    pub fn from_code(code: u8) -> Self {
        match code {
            0 => AckCode::Ok,
            1 => AckCode::UnknownCommand,
            2 => AckCode::InvalidChecksum,
            3 => AckCode::InvalidParameter,
            4 => AckCode::CommandFailed,
            5 => AckCode::DeviceTimeout,
            c => AckCode::Other(c),
        }
    }
}

/// What `Get Device Information` reports. Strings are at most 16 ASCII characters each; the
/// device pads them with spaces, which decoding trims.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct DeviceInfo {
    /// Firmware version as a number (e.g. 1141 for 1.1.41).
    pub firmware_version: u16,
    /// Model name, e.g. "3DM-GX5-25".
    pub model_name: String,
    /// Model number.
    pub model_number: String,
    /// Serial number.
    pub serial_number: String,
    /// Lot number.
    pub lot_number: String,
    /// Device options, e.g. the sensor ranges.
    pub device_options: String,
}

const INFO_STR_LEN: usize = 16;

fn put_str(w: &mut Writer, s: &str) {
    let mut field = [b' '; INFO_STR_LEN];
    for (dst, src) in field.iter_mut().zip(s.bytes()) {
        *dst = if src.is_ascii() { src } else { b'?' };
    }
    w.data.extend_from_slice(&field);
}

fn get_str(r: &mut Reader<'_>) -> Result<String, MipError> {
    let bytes: [u8; INFO_STR_LEN] = r.bytes()?;
    let text: String = bytes
        .iter()
        .map(|&b| if b.is_ascii() { char::from(b) } else { '?' })
        .collect();
    Ok(text.trim_matches([' ', '\0']).to_string())
}

impl DeviceInfo {
    fn encode(&self, w: &mut Writer) {
        w.u16(self.firmware_version);
        for s in [
            &self.model_name,
            &self.model_number,
            &self.serial_number,
            &self.lot_number,
            &self.device_options,
        ] {
            put_str(w, s);
        }
    }

    fn decode(r: &mut Reader<'_>) -> Result<Self, MipError> {
        Ok(Self {
            firmware_version: r.u16()?,
            model_name: get_str(r)?,
            model_number: get_str(r)?,
            serial_number: get_str(r)?,
            lot_number: get_str(r)?,
            device_options: get_str(r)?,
        })
    }
}

/// A response field that follows an ack.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Response {
    /// Base 0x81.
    DeviceInfo(DeviceInfo),
    /// 3DM 0x83: the IMU data's base rate.
    ImuBaseRate {
        /// Base rate, Hz.
        rate_hz: u16,
    },
    /// 3DM 0x80: the IMU message format in force.
    ImuMessageFormat(MessageFormat),
    /// 3DM 0x8E: the base rate of a data set.
    BaseRate {
        /// The data set.
        descriptor_set: u8,
        /// Base rate, Hz.
        rate_hz: u16,
    },
    /// 3DM 0x8F: the message format of a data set.
    MessageFormat {
        /// The data set.
        descriptor_set: u8,
        /// Its format.
        format: MessageFormat,
    },
    /// 3DM 0x85: whether a data set streams.
    DataStream {
        /// The data set.
        descriptor_set: u8,
        /// Streaming or not.
        enabled: bool,
    },
}

impl Response {
    /// The descriptor set and field descriptor.
    pub fn descriptor(&self) -> (u8, u8) {
        match self {
            Response::DeviceInfo(_) => (BASE_COMMAND, response::DEVICE_INFO),
            Response::ImuBaseRate { .. } => (COMMAND_3DM, response::IMU_BASE_RATE),
            Response::ImuMessageFormat(_) => (COMMAND_3DM, response::IMU_MESSAGE_FORMAT),
            Response::DataStream { .. } => (COMMAND_3DM, response::DATA_STREAM),
            Response::BaseRate { .. } => (COMMAND_3DM, response::BASE_RATE),
            Response::MessageFormat { .. } => (COMMAND_3DM, response::MESSAGE_FORMAT),
        }
    }

    fn encode(&self) -> Vec<u8> {
        let mut w = Writer::default();
        match self {
            Response::DeviceInfo(info) => info.encode(&mut w),
            Response::ImuBaseRate { rate_hz } => {
                w.u16(*rate_hz);
            }
            Response::ImuMessageFormat(format) => format.encode(&mut w),
            Response::BaseRate {
                descriptor_set,
                rate_hz,
            } => {
                w.u8(*descriptor_set).u16(*rate_hz);
            }
            Response::MessageFormat {
                descriptor_set,
                format,
            } => {
                w.u8(*descriptor_set);
                format.encode(&mut w);
            }
            Response::DataStream {
                descriptor_set,
                enabled,
            } => {
                w.u8(*descriptor_set).u8(u8::from(*enabled));
            }
        }
        w.data
    }

    /// Decodes a response field; `Ok(None)` for a descriptor this codec does not know.
    fn decode(set: u8, field: Field<'_>) -> Result<Option<Self>, MipError> {
        let mut r = Reader::new(set, field);
        let out = match (set, field.descriptor) {
            (BASE_COMMAND, response::DEVICE_INFO) => {
                Response::DeviceInfo(DeviceInfo::decode(&mut r)?)
            }
            (COMMAND_3DM, response::IMU_BASE_RATE) => Response::ImuBaseRate { rate_hz: r.u16()? },
            (COMMAND_3DM, response::IMU_MESSAGE_FORMAT) => {
                Response::ImuMessageFormat(MessageFormat::decode(&mut r)?)
            }
            (COMMAND_3DM, response::BASE_RATE) => Response::BaseRate {
                descriptor_set: r.u8()?,
                rate_hz: r.u16()?,
            },
            (COMMAND_3DM, response::MESSAGE_FORMAT) => Response::MessageFormat {
                descriptor_set: r.u8()?,
                format: MessageFormat::decode(&mut r)?,
            },
            (COMMAND_3DM, response::DATA_STREAM) => Response::DataStream {
                descriptor_set: r.u8()?,
                enabled: match r.u8()? {
                    0 => false,
                    1 => true,
                    _ => return Err(r.error("enabled flag is not 0 or 1")),
                },
            },
            _ => return Ok(None),
        };
        r.end()?;
        Ok(Some(out))
    }
}

/// The device's answer to one command: the ack/nack and the response field, if any.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MipReply {
    /// Descriptor set of the command (and of the reply packet).
    pub descriptor_set: u8,
    /// The command's field descriptor, echoed.
    pub command: u8,
    /// Ack or why not.
    pub code: AckCode,
    /// The response field (only with [`AckCode::Ok`], for commands that read something).
    pub response: Option<Response>,
    /// Fields after the ack this codec does not know, skipped.
    pub unknown_fields: u8,
}

impl MipReply {
    /// A plain ack of `command` (set, descriptor) without a response.
    pub fn ack(command: (u8, u8), code: AckCode) -> Self {
        Self {
            descriptor_set: command.0,
            command: command.1,
            code,
            response: None,
            unknown_fields: 0,
        }
    }

    /// The reply in one packet (device side). `unknown_fields` is not encoded.
    pub fn to_packet(&self) -> Packet {
        let mut b = PacketBuilder::new(self.descriptor_set);
        // Cannot fail: an ack is 4 bytes, the longest response 2 + 248 (a data set's message
        // format of `MessageFormat::MAX_FIELDS`; device info is 2 + 82).
        let _ = b.field(ACK_DESCRIPTOR, &[self.command, self.code.code()]);
        if let Some(r) = &self.response {
            let _ = b.field(r.descriptor().1, &r.encode());
        }
        b.build()
    }

    /// Every reply in a packet (host side): each ack field starts one, the response fields
    /// after it belong to it. A packet whose first field is not an ack is not a reply.
    pub fn decode_packet(packet: &Packet) -> Result<Vec<Self>, MipError> {
        let set = packet.descriptor_set();
        let mut out: Vec<Self> = Vec::new();
        for field in packet.fields() {
            if field.descriptor == ACK_DESCRIPTOR {
                let mut r = Reader::new(set, field);
                let command = r.u8()?;
                let code = AckCode::from_code(r.u8()?);
                r.end()?;
                out.push(Self::ack((set, command), code));
                continue;
            }
            let Some(reply) = out.last_mut() else {
                return Err(MipError::MissingAck(field.descriptor));
            };
            match Response::decode(set, field)? {
                Some(r) if reply.response.is_none() => reply.response = Some(r),
                _ => reply.unknown_fields = reply.unknown_fields.saturating_add(1),
            }
        }
        Ok(out)
    }
}
