//! Sans-IO codec for MicroStrain's MIP protocol (3DM-GX3/GX4/GX5, 3DM-CV5/CV7, GQ7): bytes <->
//! typed packets, both ways, like the 3DM-GX1 codec beside it.
//!
//! The host encodes [`MipCommand`]s and decodes [`MipReply`]s and [`ImuData`] from the stream
//! with [`MipDecoder`]; the device side (the simulator) decodes commands from the same decoder's
//! packets and encodes replies and data with the same types. Nothing here does I/O.
//!
//! # Protocol facts
//! Taken from the vendor's MIT-licensed `mip_sdk` (`src/c/mip/definitions/*.h`,
//! `mip_descriptors.h`, `mip_result.h`, its tests and examples) and the public DCP manuals; the
//! code is our own.
//! - A packet is `0x75 0x65`, a descriptor set byte, a payload length byte, the payload, and a
//!   Fletcher-16 checksum over everything before it, sent as the two running sums, sum1 first
//!   ([`checksum`]). The payload is a sequence of fields: a length byte (counting itself and the
//!   descriptor), a field descriptor, the field data ([`packet`]). Multi-byte values are
//!   big-endian; floats are IEEE-754.
//! - Descriptor set 0x01 holds the base commands (ping 0x01, set to idle 0x02, get device info
//!   0x03, resume 0x06), set 0x0C the 3DM commands (get IMU base rate 0x06, IMU message format
//!   0x08, and their generic forms for any data set, get base rate 0x0E and message format
//!   0x0F, which the 7-series use; enable data stream 0x11), set 0x80 the IMU ("sensor") data
//!   ([`data`]). Settings
//!   commands start with a function selector (write 1, read 2, save 3, load 4, reset 5).
//! - A device answers a command packet with a packet of the same descriptor set whose first
//!   field is 0xF1: the command's descriptor and an ack/nack code (0 ok, 1 unknown command, 2
//!   invalid checksum, 3 invalid parameter, 4 command failed, 5 device timeout), followed by the
//!   response field, if any ([`reply`]).
//! - Field descriptors 0xD0..=0xFF are "shared" and may appear in any data set: 0xD5 is the
//!   reference time, nanoseconds since the device started, which is the device's sample clock.
//!
//! # Disputed or undocumented points
//! - The deprecated internal timestamp (0x80, 0x0E) carries u32 counts whose rate the SDK does
//!   not state; the 3DM-GX3-25 manual gives 62.5 kHz ([`data::INTERNAL_TICK_HZ`]). New devices
//!   send the shared reference time (0xD5) instead, which is what a host should prefer.
//! - Raw fields (0x01..=0x03) are "native sensor counts" as floats with no published scale.
//!
//! # Streams never fail
//! [`Packet::parse`] and the typed decoders return [`MipError`]; [`MipDecoder`] never fails: it
//! skips, resynchronises on `0x75 0x65`, counts (the same [`DecoderStats`] and
//! [`RejectReason`]s as the GX1 decoder) and reports every byte exactly once.
//!
//! ```
//! use imu_proto::mip::{MipCommand, MipDecoder, MipEvent};
//! // The ping of the mip_sdk's test suite (test/c/mip/test_mip_format.c).
//! let wire = MipCommand::Ping.to_packet();
//! assert_eq!(wire.as_bytes(), [0x75, 0x65, 0x01, 0x02, 0x02, 0x01, 0xE0, 0xC6]);
//! let mut d = MipDecoder::new();
//! d.push(&[0x00]);
//! d.push(wire.as_bytes());
//! let events: Vec<_> = std::iter::from_fn(|| d.next_event()).collect();
//! assert!(matches!(&events[1], MipEvent::Packet { packet, offset: 1 } if *packet == wire));
//! ```
//!
//! [`DecoderStats`]: crate::decoder::DecoderStats
//! [`RejectReason`]: crate::decoder::RejectReason

pub mod checksum;
pub mod command;
pub mod data;
pub mod decoder;
pub mod error;
pub mod packet;
pub mod reply;

pub use command::{DescriptorRate, MessageFormat, MipCommand, Setting};
pub use data::{GpsTime, ImuData, TemperatureStats};
pub use decoder::{MipDecoder, MipEvent};
pub use error::MipError;
pub use packet::{Field, Packet, PacketBuilder};
pub use reply::{AckCode, DeviceInfo, MipReply, Response};

/// First sync byte of every packet.
pub const SYNC1: u8 = 0x75;
/// Second sync byte of every packet.
pub const SYNC2: u8 = 0x65;
/// Sync bytes, descriptor set and payload length.
pub const HEADER_LEN: usize = 4;
/// The Fletcher-16 checksum's two bytes.
pub const CHECKSUM_LEN: usize = 2;
/// The payload length is one byte.
pub const MAX_PAYLOAD_LEN: usize = 255;
/// Header, the longest payload and the checksum.
pub const MAX_PACKET_LEN: usize = HEADER_LEN + MAX_PAYLOAD_LEN + CHECKSUM_LEN;

/// Descriptor sets this codec speaks.
pub mod descriptor_set {
    /// Base commands (ping, idle, device info, resume).
    pub const BASE_COMMAND: u8 = 0x01;
    /// 3DM commands (message format, base rate, data stream).
    pub const COMMAND_3DM: u8 = 0x0C;
    /// IMU ("sensor") data.
    pub const IMU_DATA: u8 = 0x80;
}

#[cfg(test)]
mod tests;
