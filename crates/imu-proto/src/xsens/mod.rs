//! Sans-IO codec for Xsens's Xbus protocol (MTi-1/-2/-3/-7, MTi-10/-20/-30, MTi-100/-200/-300,
//! MTi-600 series): bytes <-> typed messages, both ways, like the MIP codec beside it.
//!
//! The host encodes [`XsensCommand`]s and decodes [`XsensReply`]s and [`MtData2`] from the
//! stream with [`XsensDecoder`]; the device side (the simulator) decodes commands from the same
//! decoder's messages and encodes replies and data with the same types. Nothing here does I/O.
//!
//! # Protocol facts
//! Taken from the Xsens "MT Low Level Communication Protocol" documentation as quoted by the
//! public drivers: ETH ASL's `ethzasl_xsens_driver` (`src/xsens_driver/mtdef.py` for the
//! message and data identifiers, `mtdevice.py` for framing, `parse_MTData2` and the formats),
//! Xsens's own `xspublic` (`xsmessage.c`: `XsMessage_getDataFP1632`, `XS_MAXDATALEN`) and
//! Scott Rapson's `xsens-mti` (its tests and `docs/mtmanager_packets.md`, bytes sniffed from an
//! MTi-300 talking to MT Manager, which are our golden vectors); the code is our own.
//! - A message is `0xFA` (preamble), a bus id (`0xFF`, the master, for a unit on a serial
//!   port), a message id ([`mid`]), a length byte, the data, and a checksum byte chosen so that
//!   every byte after the preamble sums to 0 mod 256 ([`message`]). A length byte of `0xFF`
//!   means a big-endian u16 length follows (the extended form, data up to [`MAX_DATA_LEN`]).
//!   Multi-byte values are big-endian; floats IEEE-754.
//! - A request is the message id with no data; the answer is the next (odd) id: `ReqDID` 0x00
//!   -> `DeviceID` 0x01, `GoToConfig` 0x30 -> 0x31, `SetOutputConfiguration` 0xC0 with data
//!   sets it, without data asks for it, and 0xC1 carries it back either way ([`command`]).
//!   An `Error` message (0x42) carries an error code byte.
//! - `MTData2` (0x36) is a sequence of items: a u16 data identifier, a size byte, the data
//!   ([`data`]). The identifier's bits are the group (`0xF800`), the type in the group
//!   (`0x00F0`), the coordinate frame (`0x000C`: ENU 0, NED 4, NWU 8) and the number format
//!   (`0x0003`: float32 0, fixed-point 12.20 1, fixed-point 16.32 2, float64 3). Fixed 12.20
//!   is an i32 / 2^20; fixed 16.32 is 6 bytes, the u32 fraction first, then the i16 integer
//!   part (`XsMessage_getDataFP1632`).
//! - A unit powers up in measurement mode streaming its configured outputs; `GoToConfig`
//!   stops the stream (its ack may arrive after data already in flight), `GoToMeasurement`
//!   starts it again. `WakeUp` (0x3E) is sent at power-up; a host answering with `WakeUpAck`
//!   (0x3F) keeps the unit in config mode.
//!
//! # Disputed or undocumented points
//! - `RawAccGyrMagTemp` (0xA010: nine u16 ADC counts and an i16 temperature) exists only on
//!   the MTi-10/100 series and has no published scale, so it is decoded but is not the reading
//!   imud calibrates; the "raw reading the calibration corrects" is the HR outputs
//!   (`AccelerationHR` 0x4040, `RateOfTurnHR` 0x8040): the factory calibration applied, before
//!   the unit's strapdown integration and filtering, at the sensors' rate. `Acceleration`,
//!   `RateOfTurn` and `MagneticField` are the unit's compensated outputs.
//! - `SampleTimeFine` (0x1060) counts at 10 kHz in a u32; `DeviceID` is 4 bytes on most units
//!   and 8 on some newer ones; `FirmwareRev` is 3 bytes (major, minor, revision) or 11 (plus
//!   build number and SVN revision). All forms are accepted.
//!
//! # Streams never fail
//! [`Message::parse`] and the typed decoders return [`XsensError`]; [`XsensDecoder`] never
//! fails: it is the shared [`FramedDecoder`](crate::decoder::framed::FramedDecoder), which
//! skips, resynchronises on `0xFA 0xFF`, counts and reports every byte exactly once.
//!
//! ```
//! use imu_proto::xsens::{XsensCommand, XsensDecoder, XsensEvent};
//! // GoToConfig as MT Manager sends it (xsens-mti docs/mtmanager_packets.md).
//! let wire = XsensCommand::GoToConfig.to_message();
//! assert_eq!(wire.as_bytes(), [0xFA, 0xFF, 0x30, 0x00, 0xD1]);
//! let mut d = XsensDecoder::new();
//! d.push(&[0x00]);
//! d.push(wire.as_bytes());
//! let events: Vec<_> = std::iter::from_fn(|| d.next_event()).collect();
//! assert!(matches!(&events[1], XsensEvent::Packet { packet, offset: 1 } if *packet == wire));
//! ```

pub mod command;
pub mod data;
pub mod error;
pub mod message;

pub use command::{FirmwareRev, OutputConfiguration, OutputSetting, XsensCommand, XsensReply};
pub use data::{DataId, Format, MtData2, RawAccGyrMagTemp, UtcTime};
pub use error::XsensError;
pub use message::{Message, XbusFraming, XsensDecoder, XsensEvent};

/// First byte of every message.
pub const PREAMBLE: u8 = 0xFA;
/// Bus id of the master: what a unit on a serial port sends and expects.
pub const BUS_ID: u8 = 0xFF;
/// Length byte announcing the extended (u16) length.
pub const EXTENDED_LEN: u8 = 0xFF;
/// Longest data of a message in the standard form.
pub const MAX_SHORT_DATA_LEN: usize = 254;
/// Longest data of any message (`XS_MAXDATALEN` of Xsens's `xspublic`: 8192 minus the
/// extended header and checksum).
pub const MAX_DATA_LEN: usize = 8192 - 7;
/// Preamble, bus id, message id and length byte.
pub const HEADER_LEN: usize = 4;
/// The header of the extended form (two more length bytes).
pub const EXTENDED_HEADER_LEN: usize = 6;
/// The longest standard-form message.
pub const MAX_SHORT_MESSAGE_LEN: usize = HEADER_LEN + MAX_SHORT_DATA_LEN + 1;
/// `SampleTimeFine` counts per second.
pub const SAMPLE_TIME_FINE_HZ: u32 = 10_000;

/// Message identifiers (`mtdef.py` `MID`).
pub mod mid {
    /// Request the device id.
    pub const REQ_DID: u8 = 0x00;
    /// The device id (u32, or u64 on some newer units).
    pub const DEVICE_ID: u8 = 0x01;
    /// Switch to measurement mode.
    pub const GO_TO_MEASUREMENT: u8 = 0x10;
    /// Its acknowledgement.
    pub const GO_TO_MEASUREMENT_ACK: u8 = 0x11;
    /// Request the firmware revision.
    pub const REQ_FW_REV: u8 = 0x12;
    /// The firmware revision.
    pub const FIRMWARE_REV: u8 = 0x13;
    /// Request the product code.
    pub const REQ_PRODUCT_CODE: u8 = 0x1C;
    /// The product code, ASCII.
    pub const PRODUCT_CODE: u8 = 0x1D;
    /// Switch to config mode.
    pub const GO_TO_CONFIG: u8 = 0x30;
    /// Its acknowledgement.
    pub const GO_TO_CONFIG_ACK: u8 = 0x31;
    /// Data message of the MTi-1/10/100/600 series.
    pub const MT_DATA2: u8 = 0x36;
    /// Sent by a unit at power-up.
    pub const WAKE_UP: u8 = 0x3E;
    /// The host's answer to `WakeUp`: stay in config mode.
    pub const WAKE_UP_ACK: u8 = 0x3F;
    /// Reset the unit.
    pub const RESET: u8 = 0x40;
    /// Its acknowledgement.
    pub const RESET_ACK: u8 = 0x41;
    /// An error, one code byte.
    pub const ERROR: u8 = 0x42;
    /// Set (with data) or request (without) the output configuration.
    pub const SET_OUTPUT_CONFIGURATION: u8 = 0xC0;
    /// The output configuration in force.
    pub const OUTPUT_CONFIGURATION: u8 = 0xC1;
}

#[cfg(test)]
mod tests;
