//! Sans-IO codec for VectorNav's VN-100/200/300 serial protocol: ASCII register sentences and
//! binary output messages on one port, bytes <-> typed values, both ways, like the GX1 and MIP
//! codecs beside it.
//!
//! The host encodes [`VnCommand`]s and decodes [`VnReply`]s and [`BinaryMessage`]s from the
//! stream with [`VnDecoder`]; the device side (the simulator) decodes commands from the same
//! decoder's sentences and encodes replies and messages with the same types. Nothing here does
//! I/O.
//!
//! # Protocol facts
//! Read from public sources; the code is our own:
//! VectorNav's programming library vnproglib 1.2 (shipped in the ROS driver
//! github:dawonn/vectornav: `cpp/src/packet.cpp` for the sentence checks, register formats and
//! `BinaryGroupLengths`, `cpp/src/error_detection.cpp` for both checks, `cpp/include/vn/types.h`
//! for the group bits and `SensorError` codes), ArduPilot's
//! `libraries/AP_ExternalAHRS/AP_ExternalAHRS_VectorNav.cpp` (register writes with their
//! checksums, the binary layouts it reads, CRC over the message being 0), PX4's
//! `src/drivers/ins/vectornav` (built on VectorNav's libvnc) and the VN-100/200/300 interface
//! documentation (units of each field; time status bits).
//! - ASCII ([`ascii`]): `$` + header (`VNRRG` read register, `VNWRG` write register, `VNERR`
//!   error, `VNYPR` and the other asynchronous outputs) + `,`-separated values + `*` + check +
//!   `\r\n`. The check is the XOR of the bytes between `$` and `*` as two hex digits
//!   (`$VNRRG,11*73`), their CRC-16-CCITT as four, or `XX` for none.
//! - Registers: 1 model, 2 hardware revision, 3 serial number, 4 firmware version, 6 async
//!   ASCII output type (0 = off; a unit powers up with YPR, 1, unless saved otherwise), 7 async
//!   output frequency (Hz, 40 at power-up), 75-77 binary outputs 1-3: async mode (which ports),
//!   rate divisor of the 800 Hz IMU rate ([`IMU_RATE_HZ`]), group byte and one field word per
//!   group, the last two in hex (`$VNWRG,76,3,80,4E,0002,0010,20B8,0018*63`).
//! - Binary ([`binary`]): 0xFA, the group byte (bit g = group g+1: common, time, IMU, GNSS1,
//!   attitude, INS, GNSS2), a little-endian u16 field word per group present, the fields in
//!   group then bit order, little-endian (f32, u64 ns), then the CRC-16-CCITT (init 0, poly
//!   0x1021) of everything after the sync byte, big-endian, so the CRC over the message after
//!   the sync byte is 0. Nothing but the field words gives the length: every enabled field's
//!   size must be known ([`binary::FIELD_LEN`]).
//! - Units: accelerations m/s², rates rad/s, magnetic field gauss, temperature °C, pressure
//!   kPa, delta theta degrees, startup and GPS time u64 ns (GPS time since 1980-01-06). Time
//!   status bit 0 time of week valid, bit 1 week (date) valid, bit 2 UTC valid.
//!
//! # Disputed or undocumented points
//! - Not every checksum in the sources is right: two of the three register writes in
//!   ArduPilot's comments carry checksums that do not match their bodies (`*0C`, `*66`); the
//!   golden vectors here are the ones that do.
//! - vnproglib writes the binary output register's groups and fields in hex but parses a
//!   read's answer with `atoi` (decimal); we read them as hex, the form the unit is written in.
//! - Newer firmware sets bit 15 of a field word to announce an extension word; its fields'
//!   sizes are not in the public tables, so such messages are rejected (and counted).
//!
//! # Streams never fail
//! [`BinaryMessage::parse`], [`Sentence::parse`] and the typed decoders return [`VnError`];
//! [`VnDecoder`] never fails: it separates the ASCII and binary streams, skips, resynchronises,
//! counts (the same [`DecoderStats`] and [`RejectReason`]s as the other decoders) and reports
//! every byte exactly once.
//!
//! ```
//! use imu_proto::vectornav::{Check, VnCommand, VnDecoder, VnEvent};
//! let read_model = VnCommand::Read(1).to_sentence(Check::Checksum8);
//! assert_eq!(read_model.as_bytes(), b"$VNRRG,01*72\r\n");
//! let mut d = VnDecoder::new();
//! d.push(b"\x00");
//! d.push(read_model.as_bytes());
//! let events: Vec<_> = std::iter::from_fn(|| d.next_event()).collect();
//! assert!(matches!(&events[1], VnEvent::Ascii { sentence, offset: 1 } if *sentence == read_model));
//! ```
//!
//! [`DecoderStats`]: crate::decoder::DecoderStats
//! [`RejectReason`]: crate::decoder::RejectReason

pub mod ascii;
pub mod binary;
pub mod checksum;
pub mod decoder;
pub mod error;

pub use ascii::{
    BinaryOutputConfig, Check, Register, Sentence, VnCommand, VnReply, err as error_code, reg,
};
pub use binary::{BinaryData, BinaryMessage, DeltaTheta, OutputFields, TimeStatus, TimeUtc};
pub use decoder::{VnDecoder, VnEvent};
pub use error::VnError;

/// Sync byte of every binary message.
pub const SYNC: u8 = 0xFA;

/// The rate the binary outputs' rate divisor divides, Hz (VN-100/200; the VN-300's IMU rate is
/// 400 Hz, which its units report by the same divisor).
pub const IMU_RATE_HZ: u32 = 800;

#[cfg(test)]
mod tests;

/// A model with a GNSS receiver (VN-200, VN-300 and their variants) sends GPS time.
pub fn model_has_gnss(model: &str) -> bool {
    model.starts_with("VN-2") || model.starts_with("VN-3")
}

/// The binary output fields a calibration needs: startup time (the sample clock), GPS time and
/// its status on a unit with GNSS, uncompensated accel, gyro and mag (the raw reading a
/// calibration corrects), temperature, and the unit's compensated accel, rate and mag. What
/// imud's start-up writes, and what the simulated unit has saved.
pub fn calibration_fields(has_gnss: bool) -> OutputFields {
    use binary::{common, group, imu, time};
    let mut f = OutputFields::default();
    f.words[group::COMMON] = common::TIME_STARTUP;
    if has_gnss {
        f.words[group::TIME] = time::TIME_GPS | time::TIME_STATUS;
    }
    f.words[group::IMU] = imu::UNCOMP_MAG
        | imu::UNCOMP_ACCEL
        | imu::UNCOMP_GYRO
        | imu::TEMP
        | imu::MAG
        | imu::ACCEL
        | imu::ANGULAR_RATE;
    f
}
