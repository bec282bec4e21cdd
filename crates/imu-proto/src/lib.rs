//! Sans-IO codec for the MicroStrain 3DM-GX1 serial protocol: bytes <-> typed frames, both ways.
//! Its successor, the MIP protocol of today's MicroStrain devices, is in [`mip`]; Xsens's Xbus
//! protocol (MTi units) is in [`xsens`]; the framing of imud's ROS 2 input (a ROS 2 IMU topic
//! read as a device's byte stream) in [`ros2_frame`].
//!
//! The same code serves the host (encode [`Command`]s, decode [`Reply`]s from a byte stream with
//! [`ReplyDecoder`]) and the device side used by the simulator (decode commands with
//! [`CommandDecoder`], encode replies). Nothing here reads or writes a port, sleeps or
//! allocates per byte; the daemon, the simulator, the fuzz targets and replay tests all run the
//! same decoders.
//!
//! # Protocol facts (from `shared/reference/3dm-gx1-protocol.md`)
//! - RS-232 8N1. The host sends a command: a code byte, sometimes followed by arguments; commands
//!   carry no checksum ([`command`]).
//! - Every reply echoes the code, then fixed big-endian 16-bit fields, then a checksum
//!   ([`reply`]): the header byte as an **unsigned** u8 plus every big-endian word, modulo 2^16
//!   ([`checksum`]). One driver reads the header as a signed char, which is wrong for 0xF0/0xF1.
//! - Data replies carry a u16 timer-tick counter before the checksum; it wraps and is unwrapped
//!   with +65536 per wrap ([`ticks`]; one driver's +65535 is an off-by-one).
//! - Scaled vectors are `counts × GainScale / 32 768 000` (g, rad/s, gauss); quaternion and
//!   matrix elements `counts / 8192`; Euler angles `counts × 360 / 65536` degrees; temperature
//!   `((raw × 5 / 65536) − 0.5) × 100` °C ([`scale`]). GainScales are EEPROM words 130 (gyro),
//!   230 (accel), 232 (mag), read with 0x28 ([`device`]).
//!
//! # Disputed points, kept configurable ([`device::DeviceParams`])
//! - **Tick period**: 6.5536 ms in most drivers, 10 ms in one (after reprogramming EEPROM).
//!   [`ticks::DEFAULT_TICK_PERIOD_S`] is only the default; the daemon should estimate it against
//!   the host clock.
//! - **Fallback GainScales** when the EEPROM read fails: accel 7000 or 8500, gyro 8500 or 10000,
//!   mag 2000. Our default is accel 7000, gyro 10000, mag 2000
//!   ([`device::GainScales::DEFAULT_FALLBACK`]); a fallback must never be used silently.
//! - **Baud rate**: 38400 in most drivers, 115200 in one ([`device::DEFAULT_BAUD`]).
//! - Raw ADC bits (0x01) have no documented scale; [`scale::raw_bits_to_units`] uses a nominal
//!   `(raw − 32768) × GainScale / 32 768 000`, our own assumption, and calibration replaces it.
//! - Legacy EEPROM commands 0x08/0x09 have disputed reply lengths and are not supported.
//!
//! # Streams never fail
//! Whole-frame calls ([`Reply::decode`], [`Command::decode`]) return [`FrameError`]. The
//! streaming decoders never return errors: they skip, resync, count and report every byte
//! exactly once (see [`decoder`]).
//!
//! ```
//! use imu_proto::{Command, DecodeEvent, Reply, ReplyDecoder};
//! let cmd = Command::Temperature;
//! assert_eq!(cmd.to_bytes(), [0x07]);
//!
//! // what the device would answer (the simulator encodes it the same way)
//! let reply = Reply::Temperature { raw: 0x1234, ticks: 0x0042 };
//! let wire = reply.to_bytes();
//! assert_eq!(wire.len(), cmd.reply_len());
//!
//! let mut decoder = ReplyDecoder::new();
//! decoder.push(&wire);
//! match decoder.next_event() {
//!     Some(DecodeEvent::Frame { reply: r, .. }) => assert_eq!(r, reply),
//!     other => panic!("unexpected {other:?}"),
//! }
//! ```

pub mod checksum;
pub mod command;
pub mod decoder;
pub mod device;
pub mod error;
pub mod gnss_time;
pub mod mip;
pub mod protocol;
pub mod reply;
pub mod ros2_frame;
pub mod scale;
pub mod ticks;
pub mod vectornav;
pub mod xsens;

pub use command::Command;
pub use decoder::{
    CommandDecoder, CommandDecoderStats, CommandEvent, CommandRejectReason, DecodeEvent,
    DecoderStats, FrameBytes, RejectReason, ReplyDecoder,
};
pub use device::{DeviceParams, GainScales};
pub use error::FrameError;
pub use protocol::DeviceProtocol;
pub use reply::{Filter, Reply, reply_len_for_code};
pub use scale::Quantized;
pub use ticks::TickUnwrapper;
