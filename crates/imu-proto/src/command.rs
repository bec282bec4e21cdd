//! Host-to-device commands: typed values, their byte encodings and their reply lengths.
//!
//! Commands carry no checksum. Most are one byte; a few carry arguments, some of which are fixed
//! "key" bytes that the device checks (and that [`CommandDecoder`](crate::decoder::CommandDecoder)
//! checks on the simulator side).

use crate::error::FrameError;
use crate::reply::reply_len_for_code;

/// The argument bytes that must follow the tare (0x0F) and remove-tare (0x11) codes.
pub const TARE_KEY: [u8; 3] = [0xC1, 0xC3, 0xC5];
/// The byte that must follow 0x29 (write EEPROM).
pub const WRITE_EEPROM_KEY: u8 = 0x71;
/// The byte that must end a 0x29 (write EEPROM) command.
pub const WRITE_EEPROM_TRAILER: u8 = 0xAA;
/// Longest command on the wire (0x29 write EEPROM), in bytes.
pub const MAX_COMMAND_LEN: usize = 7;

/// One command the host can send to a 3DM-GX1.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Command {
    /// 0x01: raw ADC bits of the nine sensors.
    RawSensorBits,
    /// 0x02: gyro-stabilized mag and accel vectors and compensated angular rate.
    StabilizedVectors,
    /// 0x03: instantaneous mag, accel and angular-rate vectors.
    InstantaneousVectors,
    /// 0x04: instantaneous orientation quaternion.
    InstantaneousQuaternion,
    /// 0x05: gyro-stabilized orientation quaternion.
    StabilizedQuaternion,
    /// 0x06: capture gyro bias (the device may take many seconds to answer).
    CaptureGyroBias,
    /// 0x07: temperature.
    Temperature,
    /// 0x0A: instantaneous orientation matrix.
    InstantaneousOrientationMatrix,
    /// 0x0B: gyro-stabilized orientation matrix.
    StabilizedOrientationMatrix,
    /// 0x0C: gyro-stabilized quaternion plus stabilized vectors.
    StabilizedQuaternionVectors,
    /// 0x12: instantaneous quaternion plus instantaneous vectors.
    InstantaneousQuaternionVectors,
    /// 0x0D: instantaneous Euler angles.
    InstantaneousEuler,
    /// 0x0E: gyro-stabilized Euler angles.
    StabilizedEuler,
    /// 0x31: gyro-stabilized Euler angles plus accel and angular-rate vectors.
    StabilizedEulerVectors,
    /// 0x10: `10 00 <command>`: stream `command` replies back to back; `command` 0 stops.
    SetContinuous {
        /// The command code to stream, or 0 to stop continuous mode.
        command: u8,
    },
    /// 0x0F: `0F C1 C3 C5`: tare the orientation.
    Tare,
    /// 0x11: `11 C1 C3 C5`: remove the tare.
    RemoveTare,
    /// 0x28: `28 aH aL`: read one EEPROM word.
    ReadEeprom {
        /// EEPROM word address.
        address: u16,
    },
    /// 0x29: `29 71 aH aL vH vL AA`: write one EEPROM word.
    WriteEeprom {
        /// EEPROM word address.
        address: u16,
        /// Value to store.
        value: u16,
    },
    /// 0xF0: firmware version.
    FirmwareVersion,
    /// 0xF1: serial number.
    SerialNumber,
}

/// Every command code this codec knows, in table order.
pub const KNOWN_COMMAND_CODES: [u8; 21] = [
    0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x07, 0x0A, 0x0B, 0x0C, 0x12, 0x0D, 0x0E, 0x31, 0x10, 0x0F,
    0x11, 0x28, 0x29, 0xF0, 0xF1,
];

/// Number of bytes the host sends for command `code`, or `None` for an unknown code.
pub const fn command_len_for_code(code: u8) -> Option<usize> {
    match code {
        0x01..=0x07 | 0x0A..=0x0E | 0x12 | 0x31 | 0xF0 | 0xF1 => Some(1),
        0x10 | 0x28 => Some(3),
        0x0F | 0x11 => Some(4),
        0x29 => Some(7),
        _ => None,
    }
}

/// The byte that the protocol fixes at `offset` of command `code`, if that position is fixed.
///
/// Used to reject malformed commands as early as possible: the device side does not have to
/// wait for the full length to know `0F 12` is not a tare.
pub const fn fixed_command_byte(code: u8, offset: usize) -> Option<u8> {
    match (code, offset) {
        (0x10, 1) => Some(0x00),
        (0x0F | 0x11, 1..=3) => Some(TARE_KEY[offset - 1]),
        (0x29, 1) => Some(WRITE_EEPROM_KEY),
        (0x29, 6) => Some(WRITE_EEPROM_TRAILER),
        _ => None,
    }
}

impl Command {
    /// The command code (first byte on the wire, echoed as the reply header).
    pub const fn code(&self) -> u8 {
        match self {
            Command::RawSensorBits => 0x01,
            Command::StabilizedVectors => 0x02,
            Command::InstantaneousVectors => 0x03,
            Command::InstantaneousQuaternion => 0x04,
            Command::StabilizedQuaternion => 0x05,
            Command::CaptureGyroBias => 0x06,
            Command::Temperature => 0x07,
            Command::InstantaneousOrientationMatrix => 0x0A,
            Command::StabilizedOrientationMatrix => 0x0B,
            Command::StabilizedQuaternionVectors => 0x0C,
            Command::InstantaneousQuaternionVectors => 0x12,
            Command::InstantaneousEuler => 0x0D,
            Command::StabilizedEuler => 0x0E,
            Command::StabilizedEulerVectors => 0x31,
            Command::SetContinuous { .. } => 0x10,
            Command::Tare => 0x0F,
            Command::RemoveTare => 0x11,
            Command::ReadEeprom { .. } => 0x28,
            Command::WriteEeprom { .. } => 0x29,
            Command::FirmwareVersion => 0xF0,
            Command::SerialNumber => 0xF1,
        }
    }

    /// The command that is fully determined by its code (no free argument bytes).
    ///
    /// Returns `None` for unknown codes and for 0x10, 0x28 and 0x29, which need arguments
    /// (use the variants directly or [`Command::decode`]).
    pub const fn from_code(code: u8) -> Option<Command> {
        Some(match code {
            0x01 => Command::RawSensorBits,
            0x02 => Command::StabilizedVectors,
            0x03 => Command::InstantaneousVectors,
            0x04 => Command::InstantaneousQuaternion,
            0x05 => Command::StabilizedQuaternion,
            0x06 => Command::CaptureGyroBias,
            0x07 => Command::Temperature,
            0x0A => Command::InstantaneousOrientationMatrix,
            0x0B => Command::StabilizedOrientationMatrix,
            0x0C => Command::StabilizedQuaternionVectors,
            0x12 => Command::InstantaneousQuaternionVectors,
            0x0D => Command::InstantaneousEuler,
            0x0E => Command::StabilizedEuler,
            0x31 => Command::StabilizedEulerVectors,
            0x0F => Command::Tare,
            0x11 => Command::RemoveTare,
            0xF0 => Command::FirmwareVersion,
            0xF1 => Command::SerialNumber,
            _ => return None,
        })
    }

    /// Number of bytes this command occupies on the wire.
    pub const fn encoded_len(&self) -> usize {
        match command_len_for_code(self.code()) {
            Some(n) => n,
            None => 1, // unreachable: every variant has a known code
        }
    }

    /// Length in bytes of the device's reply to this command, header and checksum included.
    ///
    /// For [`Command::SetContinuous`] this is the 7-byte confirmation, not the streamed replies.
    pub const fn reply_len(&self) -> usize {
        match reply_len_for_code(self.code()) {
            Some(n) => n,
            None => 0, // unreachable: every command has a reply layout
        }
    }

    /// True for the commands whose reply is an inertial sample carrying timer ticks: the ones
    /// that make sense as the argument of [`Command::SetContinuous`].
    ///
    /// Temperature (0x07) also carries ticks but is not an inertial sample; the spec says it is
    /// read by polling, so it is `false` here.
    pub const fn is_data(&self) -> bool {
        matches!(
            self,
            Command::RawSensorBits
                | Command::StabilizedVectors
                | Command::InstantaneousVectors
                | Command::InstantaneousQuaternion
                | Command::StabilizedQuaternion
                | Command::InstantaneousOrientationMatrix
                | Command::StabilizedOrientationMatrix
                | Command::StabilizedQuaternionVectors
                | Command::InstantaneousQuaternionVectors
                | Command::InstantaneousEuler
                | Command::StabilizedEuler
                | Command::StabilizedEulerVectors
        )
    }

    /// Appends the command's bytes to `out`.
    pub fn encode(&self, out: &mut Vec<u8>) {
        out.push(self.code());
        match *self {
            Command::SetContinuous { command } => out.extend_from_slice(&[0x00, command]),
            Command::Tare | Command::RemoveTare => out.extend_from_slice(&TARE_KEY),
            Command::ReadEeprom { address } => out.extend_from_slice(&address.to_be_bytes()),
            Command::WriteEeprom { address, value } => {
                let [a_hi, a_lo] = address.to_be_bytes();
                let [v_hi, v_lo] = value.to_be_bytes();
                out.extend_from_slice(&[
                    WRITE_EEPROM_KEY,
                    a_hi,
                    a_lo,
                    v_hi,
                    v_lo,
                    WRITE_EEPROM_TRAILER,
                ]);
            }
            _ => {}
        }
    }

    /// The command's bytes as a new vector.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.encoded_len());
        self.encode(&mut out);
        out
    }

    /// Decodes exactly one command from `bytes` (whose length must be the command's length).
    pub fn decode(bytes: &[u8]) -> Result<Command, FrameError> {
        let (&code, _) = bytes.split_first().ok_or(FrameError::Empty)?;
        let expected = command_len_for_code(code).ok_or(FrameError::UnknownCode(code))?;
        if bytes.len() != expected {
            return Err(FrameError::WrongLength {
                code,
                expected,
                found: bytes.len(),
            });
        }
        for (offset, &found) in bytes.iter().enumerate().skip(1) {
            if let Some(want) = fixed_command_byte(code, offset)
                && found != want
            {
                return Err(FrameError::BadArgument {
                    code,
                    offset,
                    expected: want,
                    found,
                });
            }
        }
        let word = |at: usize| u16::from_be_bytes([bytes[at], bytes[at + 1]]);
        Ok(match code {
            0x10 => Command::SetContinuous { command: bytes[2] },
            0x28 => Command::ReadEeprom { address: word(1) },
            0x29 => Command::WriteEeprom {
                address: word(2),
                value: word(4),
            },
            // Every other known code is fully determined by the code itself.
            _ => Command::from_code(code).ok_or(FrameError::UnknownCode(code))?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_known_code_has_length_and_reply() {
        for code in KNOWN_COMMAND_CODES {
            assert!(command_len_for_code(code).is_some(), "0x{code:02X}");
            assert!(reply_len_for_code(code).is_some(), "0x{code:02X}");
        }
        let n_known = (0..=255u8)
            .filter(|&c| command_len_for_code(c).is_some())
            .count();
        assert_eq!(n_known, KNOWN_COMMAND_CODES.len());
    }

    #[test]
    fn from_code_round_trips_code() {
        for code in KNOWN_COMMAND_CODES {
            match Command::from_code(code) {
                Some(cmd) => {
                    assert_eq!(cmd.code(), code);
                    assert_eq!(Command::decode(&cmd.to_bytes()), Ok(cmd));
                }
                None => assert!(matches!(code, 0x10 | 0x28 | 0x29), "0x{code:02X}"),
            }
        }
    }

    #[test]
    fn decode_rejects_wrong_keys() {
        assert_eq!(
            Command::decode(&[0x10, 0x01, 0x02]),
            Err(FrameError::BadArgument {
                code: 0x10,
                offset: 1,
                expected: 0x00,
                found: 0x01
            })
        );
        assert!(matches!(
            Command::decode(&[0x0F, 0xC1, 0xC3, 0xC4]),
            Err(FrameError::BadArgument { offset: 3, .. })
        ));
        assert!(matches!(
            Command::decode(&[0x29, 0x71, 0, 1, 0, 2, 0xAB]),
            Err(FrameError::BadArgument { offset: 6, .. })
        ));
        assert_eq!(Command::decode(&[]), Err(FrameError::Empty));
        assert_eq!(Command::decode(&[0x08]), Err(FrameError::UnknownCode(0x08)));
        assert!(matches!(
            Command::decode(&[0x28, 0x00]),
            Err(FrameError::WrongLength {
                code: 0x28,
                expected: 3,
                found: 2
            })
        ));
    }

    #[test]
    fn data_commands() {
        assert!(Command::RawSensorBits.is_data());
        assert!(Command::StabilizedEulerVectors.is_data());
        assert!(!Command::Temperature.is_data());
        assert!(!Command::SetContinuous { command: 2 }.is_data());
        assert_eq!(Command::SetContinuous { command: 2 }.reply_len(), 7);
        assert_eq!(Command::StabilizedQuaternionVectors.reply_len(), 31);
    }
}
