//! Device-to-host replies: typed values with the exact wire layout of every reply in the spec table.
//!
//! A reply is the command byte echoed back, fixed big-endian 16-bit fields, then a checksum
//! (see [`crate::checksum`]). All fields are kept in device counts; [`crate::scale`] converts
//! them to physical units.

use crate::checksum::{checksum, stored_checksum};
use crate::error::FrameError;

/// Longest reply on the wire (0x0C / 0x12 quaternion + vectors), in bytes.
pub const MAX_REPLY_LEN: usize = 31;
/// Shortest reply on the wire (header + one word + checksum), in bytes.
pub const MIN_REPLY_LEN: usize = 5;

/// Which of the device's two estimates a reply carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Filter {
    /// Gyro-stabilized (filtered) estimate.
    Stabilized,
    /// Instantaneous (unfiltered) estimate.
    Instantaneous,
}

/// One decoded reply frame.
///
/// Vector fields are `[x, y, z]` in device counts. `ticks` is the device's free-running u16
/// timer (see [`crate::ticks`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Reply {
    /// 0x01: raw, unsigned ADC counts centred near 32768 (not orthogonalized).
    RawSensorBits {
        /// Magnetometer channels.
        mag: [u16; 3],
        /// Accelerometer channels.
        accel: [u16; 3],
        /// Angular-rate channels.
        rate: [u16; 3],
        /// Timer ticks.
        ticks: u16,
    },
    /// 0x02 (stabilized) / 0x03 (instantaneous): scaled vectors, value = counts × gain / 32 768 000.
    Vectors {
        /// Which estimate.
        kind: Filter,
        /// Magnetic field counts (gauss after scaling).
        mag: [i16; 3],
        /// Acceleration counts (g after scaling).
        accel: [i16; 3],
        /// Angular-rate counts (rad/s after scaling; compensated for 0x02).
        rate: [i16; 3],
        /// Timer ticks.
        ticks: u16,
    },
    /// 0x04 (instantaneous) / 0x05 (stabilized): quaternion q0..q3, counts / 8192.
    Quaternion {
        /// Which estimate.
        kind: Filter,
        /// q0..q3 in wire order.
        q: [i16; 4],
        /// Timer ticks.
        ticks: u16,
    },
    /// 0x06: gyro bias captured.
    CaptureGyroBias {
        /// Timer ticks.
        ticks: u16,
    },
    /// 0x07: temperature, see [`crate::scale::temp_raw_to_c`].
    Temperature {
        /// Raw temperature counts.
        raw: u16,
        /// Timer ticks.
        ticks: u16,
    },
    /// 0x0A (instantaneous) / 0x0B (stabilized): orientation matrix, counts / 8192.
    ///
    /// `m` holds the nine words in wire order. Drivers store it transposed (as the matrix that
    /// maps the other way); this type does not interpret it.
    OrientationMatrix {
        /// Which estimate.
        kind: Filter,
        /// The nine matrix words in wire order.
        m: [i16; 9],
        /// Timer ticks.
        ticks: u16,
    },
    /// 0x0C (stabilized) / 0x12 (instantaneous): quaternion plus scaled vectors.
    QuaternionVectors {
        /// Which estimate.
        kind: Filter,
        /// q0..q3 in wire order.
        q: [i16; 4],
        /// Magnetic field counts.
        mag: [i16; 3],
        /// Acceleration counts.
        accel: [i16; 3],
        /// Angular-rate counts.
        rate: [i16; 3],
        /// Timer ticks.
        ticks: u16,
    },
    /// 0x0D (instantaneous) / 0x0E (stabilized): Euler angles, counts × 360 / 65536 degrees.
    Euler {
        /// Which estimate.
        kind: Filter,
        /// Roll, pitch, yaw counts.
        rpy: [i16; 3],
        /// Timer ticks.
        ticks: u16,
    },
    /// 0x31: stabilized Euler angles plus accel and angular-rate vectors.
    EulerVectors {
        /// Roll, pitch, yaw counts.
        rpy: [i16; 3],
        /// Acceleration counts.
        accel: [i16; 3],
        /// Angular-rate counts.
        rate: [i16; 3],
        /// Timer ticks.
        ticks: u16,
    },
    /// 0x10: continuous-mode confirmation, `10 00 <command> tH tL cH cL`.
    Continuous {
        /// The command now streamed (0 = continuous mode stopped).
        command: u8,
        /// Timer ticks.
        ticks: u16,
    },
    /// 0x0F: tare done.
    Tare {
        /// Timer ticks.
        ticks: u16,
    },
    /// 0x11: tare removed.
    RemoveTare {
        /// Timer ticks.
        ticks: u16,
    },
    /// 0x28: EEPROM word read.
    EepromRead {
        /// The word read.
        value: u16,
        /// Timer ticks.
        ticks: u16,
    },
    /// 0x29: EEPROM word written (the device echoes the value).
    EepromWrite {
        /// The word written.
        value: u16,
        /// Timer ticks.
        ticks: u16,
    },
    /// 0xF0: firmware version number; see [`crate::scale::format_firmware_version`].
    FirmwareVersion {
        /// Version number N, read as N/1000 . (N%1000)/100 . N%100.
        version: u16,
    },
    /// 0xF1: serial number.
    SerialNumber {
        /// Serial number.
        serial: u16,
    },
}

/// Every reply header code this codec knows.
pub const KNOWN_REPLY_CODES: [u8; 21] = crate::command::KNOWN_COMMAND_CODES;

/// Length in bytes (header and checksum included) of the reply whose header is `code`, or
/// `None` for a code this codec does not know (including the legacy 0x08/0x09, whose lengths
/// are disputed).
pub const fn reply_len_for_code(code: u8) -> Option<usize> {
    match code {
        0x01 | 0x02 | 0x03 | 0x0A | 0x0B | 0x31 => Some(23),
        0x04 | 0x05 => Some(13),
        0x06 | 0x0F | 0x11 | 0xF0 | 0xF1 => Some(5),
        0x07 | 0x10 | 0x28 | 0x29 => Some(7),
        0x0C | 0x12 => Some(31),
        0x0D | 0x0E => Some(11),
        _ => None,
    }
}

/// Cheap validity test used by the streaming decoder: exact length for a known code, good
/// checksum, and the fixed `00` byte of the 0x10 reply.
pub(crate) fn check_frame(frame: &[u8]) -> Result<(), FrameError> {
    let (&code, _) = frame.split_first().ok_or(FrameError::Empty)?;
    let expected = reply_len_for_code(code).ok_or(FrameError::UnknownCode(code))?;
    if frame.len() != expected {
        return Err(FrameError::WrongLength {
            code,
            expected,
            found: frame.len(),
        });
    }
    let computed = checksum(&frame[..expected - 2]);
    let found = stored_checksum(frame).unwrap_or(0);
    if computed != found {
        return Err(FrameError::BadChecksum {
            expected: computed,
            found,
        });
    }
    if code == 0x10 && frame[1] != 0x00 {
        return Err(FrameError::BadArgument {
            code,
            offset: 1,
            expected: 0x00,
            found: frame[1],
        });
    }
    Ok(())
}

/// Reads big-endian words from a frame whose length has already been checked.
struct Words<'a> {
    frame: &'a [u8],
    at: usize,
}

impl Words<'_> {
    fn u16(&mut self) -> u16 {
        let w = u16::from_be_bytes([self.frame[self.at], self.frame[self.at + 1]]);
        self.at += 2;
        w
    }
    fn i16(&mut self) -> i16 {
        self.u16() as i16
    }
    fn u16s<const N: usize>(&mut self) -> [u16; N] {
        std::array::from_fn(|_| self.u16())
    }
    fn i16s<const N: usize>(&mut self) -> [i16; N] {
        std::array::from_fn(|_| self.i16())
    }
}

fn put_u16s(out: &mut Vec<u8>, words: &[u16]) {
    for w in words {
        out.extend_from_slice(&w.to_be_bytes());
    }
}

fn put_i16s(out: &mut Vec<u8>, words: &[i16]) {
    for w in words {
        out.extend_from_slice(&w.to_be_bytes());
    }
}

impl Reply {
    /// The reply's header code (the echoed command code).
    pub const fn code(&self) -> u8 {
        use Filter::{Instantaneous as I, Stabilized as S};
        match self {
            Reply::RawSensorBits { .. } => 0x01,
            Reply::Vectors { kind: S, .. } => 0x02,
            Reply::Vectors { kind: I, .. } => 0x03,
            Reply::Quaternion { kind: I, .. } => 0x04,
            Reply::Quaternion { kind: S, .. } => 0x05,
            Reply::CaptureGyroBias { .. } => 0x06,
            Reply::Temperature { .. } => 0x07,
            Reply::OrientationMatrix { kind: I, .. } => 0x0A,
            Reply::OrientationMatrix { kind: S, .. } => 0x0B,
            Reply::QuaternionVectors { kind: S, .. } => 0x0C,
            Reply::QuaternionVectors { kind: I, .. } => 0x12,
            Reply::Euler { kind: I, .. } => 0x0D,
            Reply::Euler { kind: S, .. } => 0x0E,
            Reply::EulerVectors { .. } => 0x31,
            Reply::Continuous { .. } => 0x10,
            Reply::Tare { .. } => 0x0F,
            Reply::RemoveTare { .. } => 0x11,
            Reply::EepromRead { .. } => 0x28,
            Reply::EepromWrite { .. } => 0x29,
            Reply::FirmwareVersion { .. } => 0xF0,
            Reply::SerialNumber { .. } => 0xF1,
        }
    }

    /// Length of this reply on the wire, header and checksum included.
    pub const fn encoded_len(&self) -> usize {
        match reply_len_for_code(self.code()) {
            Some(n) => n,
            None => 0, // unreachable: every variant has a known code
        }
    }

    /// The device timer ticks carried by the reply; `None` for 0xF0 and 0xF1, which carry none.
    pub const fn ticks(&self) -> Option<u16> {
        match *self {
            Reply::RawSensorBits { ticks, .. }
            | Reply::Vectors { ticks, .. }
            | Reply::Quaternion { ticks, .. }
            | Reply::CaptureGyroBias { ticks }
            | Reply::Temperature { ticks, .. }
            | Reply::OrientationMatrix { ticks, .. }
            | Reply::QuaternionVectors { ticks, .. }
            | Reply::Euler { ticks, .. }
            | Reply::EulerVectors { ticks, .. }
            | Reply::Continuous { ticks, .. }
            | Reply::Tare { ticks }
            | Reply::RemoveTare { ticks }
            | Reply::EepromRead { ticks, .. }
            | Reply::EepromWrite { ticks, .. } => Some(ticks),
            Reply::FirmwareVersion { .. } | Reply::SerialNumber { .. } => None,
        }
    }

    /// Appends the whole frame (header, fields, checksum) to `out`.
    pub fn encode(&self, out: &mut Vec<u8>) {
        let start = out.len();
        out.push(self.code());
        if !self.encode_data_words(out) {
            self.encode_short_words(out);
        }
        let sum = checksum(&out[start..]);
        out.extend_from_slice(&sum.to_be_bytes());
    }

    /// The words of a data reply (vectors, orientation, ticks); `false` for the other replies.
    fn encode_data_words(&self, out: &mut Vec<u8>) -> bool {
        match self {
            Reply::RawSensorBits {
                mag,
                accel,
                rate,
                ticks,
            } => {
                put_u16s(out, mag);
                put_u16s(out, accel);
                put_u16s(out, rate);
                put_u16s(out, &[*ticks]);
            }
            Reply::Vectors {
                mag,
                accel,
                rate,
                ticks,
                ..
            } => {
                put_i16s(out, mag);
                put_i16s(out, accel);
                put_i16s(out, rate);
                put_u16s(out, &[*ticks]);
            }
            Reply::Quaternion { q, ticks, .. } => {
                put_i16s(out, q);
                put_u16s(out, &[*ticks]);
            }
            Reply::OrientationMatrix { m, ticks, .. } => {
                put_i16s(out, m);
                put_u16s(out, &[*ticks]);
            }
            Reply::QuaternionVectors {
                q,
                mag,
                accel,
                rate,
                ticks,
                ..
            } => {
                put_i16s(out, q);
                put_i16s(out, mag);
                put_i16s(out, accel);
                put_i16s(out, rate);
                put_u16s(out, &[*ticks]);
            }
            Reply::Euler { rpy, ticks, .. } => {
                put_i16s(out, rpy);
                put_u16s(out, &[*ticks]);
            }
            Reply::EulerVectors {
                rpy,
                accel,
                rate,
                ticks,
            } => {
                put_i16s(out, rpy);
                put_i16s(out, accel);
                put_i16s(out, rate);
                put_u16s(out, &[*ticks]);
            }
            _ => return false,
        }
        true
    }

    /// The words of the replies that are not data (acknowledgements, EEPROM, identity).
    fn encode_short_words(&self, out: &mut Vec<u8>) {
        match self {
            Reply::Continuous { command, ticks } => {
                out.extend_from_slice(&[0x00, *command]);
                put_u16s(out, &[*ticks]);
            }
            Reply::CaptureGyroBias { ticks }
            | Reply::Tare { ticks }
            | Reply::RemoveTare { ticks } => {
                put_u16s(out, &[*ticks]);
            }
            Reply::Temperature { raw: value, ticks }
            | Reply::EepromRead { value, ticks }
            | Reply::EepromWrite { value, ticks } => put_u16s(out, &[*value, *ticks]),
            Reply::FirmwareVersion { version: value } | Reply::SerialNumber { serial: value } => {
                put_u16s(out, &[*value]);
            }
            // Data replies: written by `encode_data_words`.
            _ => {}
        }
    }

    /// The whole frame as a new vector.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.encoded_len());
        self.encode(&mut out);
        out
    }

    /// Decodes one exact-length frame, verifying its length and checksum.
    ///
    /// ```
    /// use imu_proto::reply::Reply;
    /// // 0x07 + 0x1234 + 0x0042 = 0x127D
    /// let r = Reply::decode(&[0x07, 0x12, 0x34, 0x00, 0x42, 0x12, 0x7D]).unwrap();
    /// assert_eq!(r, Reply::Temperature { raw: 0x1234, ticks: 0x42 });
    /// ```
    pub fn decode(frame: &[u8]) -> Result<Reply, FrameError> {
        check_frame(frame)?;
        let code = frame[0];
        let mut w = Words { frame, at: 1 };
        let kind = match code {
            0x02 | 0x05 | 0x0B | 0x0C | 0x0E => Filter::Stabilized,
            _ => Filter::Instantaneous,
        };
        Ok(match code {
            0x01 => Reply::RawSensorBits {
                mag: w.u16s(),
                accel: w.u16s(),
                rate: w.u16s(),
                ticks: w.u16(),
            },
            0x02 | 0x03 => Reply::Vectors {
                kind,
                mag: w.i16s(),
                accel: w.i16s(),
                rate: w.i16s(),
                ticks: w.u16(),
            },
            0x04 | 0x05 => Reply::Quaternion {
                kind,
                q: w.i16s(),
                ticks: w.u16(),
            },
            0x06 => Reply::CaptureGyroBias { ticks: w.u16() },
            0x07 => Reply::Temperature {
                raw: w.u16(),
                ticks: w.u16(),
            },
            0x0A | 0x0B => Reply::OrientationMatrix {
                kind,
                m: w.i16s(),
                ticks: w.u16(),
            },
            0x0C | 0x12 => Reply::QuaternionVectors {
                kind,
                q: w.i16s(),
                mag: w.i16s(),
                accel: w.i16s(),
                rate: w.i16s(),
                ticks: w.u16(),
            },
            0x0D | 0x0E => Reply::Euler {
                kind,
                rpy: w.i16s(),
                ticks: w.u16(),
            },
            0x31 => Reply::EulerVectors {
                rpy: w.i16s(),
                accel: w.i16s(),
                rate: w.i16s(),
                ticks: w.u16(),
            },
            // byte 1 is the fixed 0x00, already checked by check_frame
            0x10 => Reply::Continuous {
                command: frame[2],
                ticks: u16::from_be_bytes([frame[3], frame[4]]),
            },
            0x0F => Reply::Tare { ticks: w.u16() },
            0x11 => Reply::RemoveTare { ticks: w.u16() },
            0x28 => Reply::EepromRead {
                value: w.u16(),
                ticks: w.u16(),
            },
            0x29 => Reply::EepromWrite {
                value: w.u16(),
                ticks: w.u16(),
            },
            0xF0 => Reply::FirmwareVersion { version: w.u16() },
            0xF1 => Reply::SerialNumber { serial: w.u16() },
            _ => return Err(FrameError::UnknownCode(code)),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lengths_match_layouts() {
        // Encode a zeroed reply of every code and check the encoder writes exactly the
        // table length, so the length table and the layouts cannot drift apart.
        let samples = [
            Reply::RawSensorBits {
                mag: [0; 3],
                accel: [0; 3],
                rate: [0; 3],
                ticks: 0,
            },
            Reply::Quaternion {
                kind: Filter::Stabilized,
                q: [0; 4],
                ticks: 0,
            },
            Reply::QuaternionVectors {
                kind: Filter::Instantaneous,
                q: [0; 4],
                mag: [0; 3],
                accel: [0; 3],
                rate: [0; 3],
                ticks: 0,
            },
            Reply::Continuous {
                command: 0,
                ticks: 0,
            },
            Reply::SerialNumber { serial: 0 },
        ];
        let expected = [23, 13, 31, 7, 5];
        for (r, n) in samples.iter().zip(expected) {
            assert_eq!(r.to_bytes().len(), n, "{r:?}");
            assert_eq!(r.encoded_len(), n);
        }
    }

    #[test]
    fn decode_errors_carry_context() {
        assert_eq!(Reply::decode(&[]), Err(FrameError::Empty));
        assert_eq!(
            Reply::decode(&[0x08, 0, 0]),
            Err(FrameError::UnknownCode(0x08))
        );
        assert_eq!(
            Reply::decode(&[0x06, 0, 0, 0]),
            Err(FrameError::WrongLength {
                code: 0x06,
                expected: 5,
                found: 4
            })
        );
        assert_eq!(
            Reply::decode(&[0x06, 0x00, 0x01, 0x00, 0x06]),
            Err(FrameError::BadChecksum {
                expected: 0x0007,
                found: 0x0006
            })
        );
        // 0x10 with a non-zero fixed byte but a checksum that matches: 0x10 + 0x0102 + 0 = 0x0112
        assert_eq!(
            Reply::decode(&[0x10, 0x01, 0x02, 0x00, 0x00, 0x01, 0x12]),
            Err(FrameError::BadArgument {
                code: 0x10,
                offset: 1,
                expected: 0,
                found: 1
            })
        );
    }

    #[test]
    fn ticks_absent_only_for_identity_replies() {
        assert_eq!(Reply::FirmwareVersion { version: 1 }.ticks(), None);
        assert_eq!(Reply::SerialNumber { serial: 1 }.ticks(), None);
        assert_eq!(Reply::Tare { ticks: 9 }.ticks(), Some(9));
        assert_eq!(
            Reply::Continuous {
                command: 2,
                ticks: 7
            }
            .ticks(),
            Some(7)
        );
    }
}
