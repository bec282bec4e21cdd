//! The ASCII register protocol: `$` + header and comma-separated values + `*` + check +
//! `\r\n`. The check is the 8-bit XOR of the bytes between `$` and `*` as two hex digits, the
//! CRC-16-CCITT of the same bytes as four, or `XX`, the wildcard a unit accepts for "no check".
//!
//! [`Sentence`] is the framing (what the streaming decoder checks); [`VnCommand`] (host to
//! unit) and [`VnReply`] (unit to host) are the typed meanings of the sentences this codec
//! speaks: reads and writes of the [`Register`]s that identify and configure a unit, the unit's
//! `$VNERR` and its ASCII asynchronous outputs.

use smallvec::SmallVec;

use super::VnError;
use super::binary::{OutputFields, group};
use super::checksum::{checksum8, crc16};

/// Longest sentence the decoder waits for, `$` to `\n`; VectorNav's longest ASCII outputs are
/// well under it, and a start that has not ended by then is not a sentence.
pub const MAX_SENTENCE_LEN: usize = 256;

/// Which check a sentence carries.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub enum Check {
    /// Two hex digits: XOR of the body bytes.
    #[default]
    Checksum8,
    /// Four hex digits: CRC-16-CCITT of the body bytes.
    Crc16,
    /// `XX`: no check.
    Wildcard,
}

/// Longest sentence held inline, `$` to `\n`: register replies and the `$VNYPR` output are
/// well under it, so only a long ASCII output's bytes go to the heap.
pub const MAX_INLINE_SENTENCE_LEN: usize = 128;

/// One good sentence: its bytes (`$` to `\n`, inline up to [`MAX_INLINE_SENTENCE_LEN`], so
/// framing one allocates nothing) and the check it carried.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Sentence {
    bytes: SmallVec<[u8; MAX_INLINE_SENTENCE_LEN]>,
    check: Check,
}

impl Sentence {
    /// Frames `body` (header and values, without `$` and `*`) with `check`.
    pub fn new(body: &str, check: Check) -> Sentence {
        let tail = match check {
            Check::Checksum8 => format!("{:02X}", checksum8(body.as_bytes())),
            Check::Crc16 => format!("{:04X}", crc16(body.as_bytes())),
            Check::Wildcard => "XX".to_string(),
        };
        Sentence {
            bytes: SmallVec::from_vec(format!("${body}*{tail}\r\n").into_bytes()),
            check,
        }
    }

    /// Checks one whole sentence, `$` to `\n`.
    pub fn parse(bytes: &[u8]) -> Result<Sentence, VnError> {
        if bytes.len() > MAX_SENTENCE_LEN {
            return Err(VnError::BadSentence("longer than a sentence can be"));
        }
        let Some(inner) = bytes
            .strip_prefix(b"$")
            .and_then(|b| b.strip_suffix(b"\r\n"))
        else {
            return Err(VnError::BadSentence("not framed by '$' and CR LF"));
        };
        let Some(star) = inner.iter().rposition(|&b| b == b'*') else {
            return Err(VnError::BadSentence("no '*' before the check"));
        };
        let (body, tail) = (&inner[..star], &inner[star + 1..]);
        if !body
            .iter()
            .all(|b| (0x20..0x7F).contains(b) && *b != b'$' && *b != b'*')
        {
            return Err(VnError::BadSentence("body is not printable ASCII"));
        }
        if body.len() < 5 || !body.starts_with(b"VN") || body.get(5).is_some_and(|&b| b != b',') {
            return Err(VnError::BadSentence(
                "header is not \"VN\" and three letters",
            ));
        }
        let check = match tail {
            b"XX" => Check::Wildcard,
            [_, _] => Check::Checksum8,
            [_, _, _, _] => Check::Crc16,
            _ => return Err(VnError::BadSentence("check is not 2 or 4 hex digits")),
        };
        let tail_str = std::str::from_utf8(tail).unwrap_or("");
        let found = u16::from_str_radix(tail_str, 16);
        let computed = match check {
            Check::Wildcard => None,
            Check::Checksum8 => Some(u16::from(checksum8(body))),
            Check::Crc16 => Some(crc16(body)),
        };
        if let Some(computed) = computed {
            let Ok(found) = found else {
                return Err(VnError::BadSentence("check is not hex"));
            };
            if found != computed {
                return Err(VnError::BadChecksum { computed, found });
            }
        }
        Ok(Sentence {
            bytes: SmallVec::from_slice(bytes),
            check,
        })
    }

    /// The sentence's bytes, `$` to `\n`.
    pub fn as_bytes(&self) -> &[u8] {
        &self.bytes
    }

    /// The check it carried.
    pub fn check(&self) -> Check {
        self.check
    }

    /// Header and values, between `$` and `*`.
    pub fn body(&self) -> &str {
        let star = self.bytes.iter().rposition(|&b| b == b'*').unwrap_or(1);
        // Checked printable ASCII in `parse`/`new`.
        std::str::from_utf8(&self.bytes[1..star]).unwrap_or("")
    }

    /// The header, e.g. `VNRRG`.
    pub fn header(&self) -> &str {
        self.body().split(',').next().unwrap_or("")
    }

    /// The comma-separated values after the header.
    pub fn values(&self) -> impl Iterator<Item = &str> {
        self.body().split(',').skip(1)
    }
}

/// Register ids this codec reads and writes.
pub mod reg {
    /// Model number (string), read-only.
    pub const MODEL: u8 = 1;
    /// Hardware revision (u32), read-only.
    pub const HARDWARE_REVISION: u8 = 2;
    /// Serial number (u32), read-only.
    pub const SERIAL_NUMBER: u8 = 3;
    /// Firmware version (`major.minor.feature.hotfix`), read-only.
    pub const FIRMWARE: u8 = 4;
    /// Asynchronous ASCII data output type; 0 = off.
    pub const ASYNC_OUTPUT_TYPE: u8 = 6;
    /// Asynchronous ASCII data output frequency, Hz.
    pub const ASYNC_OUTPUT_FREQUENCY: u8 = 7;
    /// Binary output register 1; 76 and 77 are outputs 2 and 3.
    pub const BINARY_OUTPUT_1: u8 = 75;
}

/// Asynchronous ASCII output type of the yaw, pitch and roll sentence `$VNYPR` (register 6).
pub const ASYNC_YPR: u32 = 1;

/// A binary output register's contents (registers 75-77).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct BinaryOutputConfig {
    /// Which serial ports output it: 0 none, 1 port 1, 2 port 2, 3 both.
    pub async_mode: u16,
    /// Output at the IMU rate (800 Hz) divided by this.
    pub rate_divisor: u16,
    /// The fields of each message.
    pub fields: OutputFields,
}

/// A register and its value.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum Register {
    /// Register 1, e.g. `VN-100T-CR`.
    Model(String),
    /// Register 2.
    HardwareRevision(u32),
    /// Register 3.
    SerialNumber(u32),
    /// Register 4, e.g. `2.1.0.0`.
    Firmware(String),
    /// Register 6 (0 = off).
    AsyncOutputType(u32),
    /// Register 7, Hz.
    AsyncOutputFrequency(u32),
    /// Registers 75 (`index` 1) to 77 (`index` 3).
    BinaryOutput {
        /// 1..=3.
        index: u8,
        /// Its contents.
        config: BinaryOutputConfig,
    },
}

fn dec<T: std::str::FromStr>(id: u8, s: Option<&str>) -> Result<T, VnError> {
    s.and_then(|s| s.trim().parse().ok())
        .ok_or(VnError::BadRegister {
            id,
            problem: "value is not a decimal number",
        })
}

fn hex16(id: u8, s: Option<&str>) -> Result<u16, VnError> {
    s.and_then(|s| u16::from_str_radix(s.trim(), 16).ok())
        .ok_or(VnError::BadRegister {
            id,
            problem: "group or field word is not a hex u16",
        })
}

fn text(id: u8, s: Option<&str>) -> Result<String, VnError> {
    match s {
        Some(s) if !s.is_empty() => Ok(s.to_string()),
        _ => Err(VnError::BadRegister {
            id,
            problem: "empty text value",
        }),
    }
}

impl Register {
    /// The register's id.
    pub fn id(&self) -> u8 {
        match self {
            Register::Model(_) => reg::MODEL,
            Register::HardwareRevision(_) => reg::HARDWARE_REVISION,
            Register::SerialNumber(_) => reg::SERIAL_NUMBER,
            Register::Firmware(_) => reg::FIRMWARE,
            Register::AsyncOutputType(_) => reg::ASYNC_OUTPUT_TYPE,
            Register::AsyncOutputFrequency(_) => reg::ASYNC_OUTPUT_FREQUENCY,
            Register::BinaryOutput { index, .. } => reg::BINARY_OUTPUT_1 + index - 1,
        }
    }

    /// The values as sent after the register id (without a leading comma). Binary output
    /// registers write the group byte and field words in hex, as ArduPilot's and VectorNav's
    /// own library do (`$VNWRG,75,3,8,34,072E,0106,0612`).
    pub fn values(&self) -> String {
        match self {
            Register::Model(s) | Register::Firmware(s) => s.clone(),
            Register::HardwareRevision(v) | Register::SerialNumber(v) => v.to_string(),
            Register::AsyncOutputType(v) | Register::AsyncOutputFrequency(v) => v.to_string(),
            Register::BinaryOutput { config, .. } => {
                let mut s = format!(
                    "{},{},{:02X}",
                    config.async_mode,
                    config.rate_divisor,
                    config.fields.groups_byte()
                );
                for w in config.fields.words.iter().filter(|w| **w != 0) {
                    s.push_str(&format!(",{w:04X}"));
                }
                s
            }
        }
    }

    /// Parses register `id`'s values (what follows the id in a read reply or a write).
    pub fn parse<'a>(
        id: u8,
        values: impl IntoIterator<Item = &'a str>,
    ) -> Result<Register, VnError> {
        let mut it = values.into_iter();
        let first = it.next();
        let r = match id {
            reg::MODEL => Register::Model(text(id, first)?),
            reg::HARDWARE_REVISION => Register::HardwareRevision(dec(id, first)?),
            reg::SERIAL_NUMBER => Register::SerialNumber(dec(id, first)?),
            reg::FIRMWARE => Register::Firmware(text(id, first)?),
            // Newer firmware takes an optional serial port after the value; it is accepted
            // and not kept (this codec configures the port it talks on).
            reg::ASYNC_OUTPUT_TYPE => {
                let _port = it.next();
                Register::AsyncOutputType(dec(id, first)?)
            }
            reg::ASYNC_OUTPUT_FREQUENCY => {
                let _port = it.next();
                Register::AsyncOutputFrequency(dec(id, first)?)
            }
            75..=77 => {
                let async_mode = dec(id, first)?;
                let rate_divisor = dec(id, it.next())?;
                let groups = hex16(id, it.next())?;
                let groups = u8::try_from(groups).map_err(|_| VnError::BadGroups(0xFF))?;
                // One word per group bit, at most eight: a fixed array, no allocation.
                let n = groups.count_ones() as usize;
                let mut words = [0u16; 8];
                for w in &mut words[..n] {
                    *w = hex16(id, it.next())?;
                }
                let fields = OutputFields::from_header(groups, &words[..n])?;
                Register::BinaryOutput {
                    index: id - 74,
                    config: BinaryOutputConfig {
                        async_mode,
                        rate_divisor,
                        fields,
                    },
                }
            }
            _ => return Err(VnError::UnknownRegister(id)),
        };
        if it.next().is_some() {
            return Err(VnError::BadRegister {
                id,
                problem: "more values than the register has",
            });
        }
        Ok(r)
    }
}

fn register_id(s: Option<&str>) -> Result<u8, VnError> {
    s.and_then(|s| s.parse().ok())
        .ok_or(VnError::BadSentence("register id is not a number"))
}

/// What a host sends a unit.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum VnCommand {
    /// `$VNRRG,id`: read a register.
    Read(u8),
    /// `$VNWRG,id,values`: write a register.
    Write(Register),
}

impl VnCommand {
    /// The sentence, with `check`.
    pub fn to_sentence(&self, check: Check) -> Sentence {
        match self {
            VnCommand::Read(id) => Sentence::new(&format!("VNRRG,{id:02}"), check),
            VnCommand::Write(r) => {
                Sentence::new(&format!("VNWRG,{:02},{}", r.id(), r.values()), check)
            }
        }
    }

    /// The command a sentence carries (device side).
    pub fn decode(s: &Sentence) -> Result<VnCommand, VnError> {
        let mut values = s.values();
        match s.header() {
            "VNRRG" => match (values.next(), values.next()) {
                (Some(id), None) => Ok(VnCommand::Read(register_id(Some(id))?)),
                _ => Err(VnError::BadSentence("a read names one register")),
            },
            "VNWRG" => {
                let id = register_id(values.next())?;
                Ok(VnCommand::Write(Register::parse(id, values)?))
            }
            other => Err(VnError::unknown_header(other)),
        }
    }
}

/// Error codes of `$VNERR` (VectorNav's `SensorError`).
pub mod err {
    /// The check did not match.
    pub const INVALID_CHECKSUM: u8 = 3;
    /// Unknown command.
    pub const INVALID_COMMAND: u8 = 4;
    /// Too few values.
    pub const NOT_ENOUGH_PARAMETERS: u8 = 5;
    /// Too many values.
    pub const TOO_MANY_PARAMETERS: u8 = 6;
    /// A value out of range.
    pub const INVALID_PARAMETER: u8 = 7;
    /// No such register.
    pub const INVALID_REGISTER: u8 = 8;
    /// A read-only register written.
    pub const UNAUTHORIZED_ACCESS: u8 = 9;
}

/// What a unit sends a host in ASCII.
#[derive(Debug, Clone, PartialEq)]
pub enum VnReply {
    /// `$VNRRG,id,values`: the answer to a read.
    Read(Register),
    /// `$VNWRG,id,values`: the answer to a write, echoing the value written.
    Written(Register),
    /// `$VNERR,code` (hex).
    Error(u8),
    /// `$VNYPR,yaw,pitch,roll`: the yaw, pitch, roll asynchronous output, degrees.
    Ypr([f32; 3]),
}

impl VnReply {
    /// The sentence, with `check`.
    pub fn to_sentence(&self, check: Check) -> Sentence {
        let body = match self {
            VnReply::Read(r) => format!("VNRRG,{:02},{}", r.id(), r.values()),
            VnReply::Written(r) => format!("VNWRG,{:02},{}", r.id(), r.values()),
            VnReply::Error(code) => format!("VNERR,{code:02X}"),
            VnReply::Ypr([y, p, r]) => format!("VNYPR,{y:+08.3},{p:+08.3},{r:+08.3}"),
        };
        Sentence::new(&body, check)
    }

    /// The reply a sentence carries (host side).
    pub fn decode(s: &Sentence) -> Result<VnReply, VnError> {
        // The values are parsed from the sentence's bytes as they are split: nothing is
        // collected, so decoding a reply or an ASCII output allocates nothing.
        let mut values = s.values();
        match s.header() {
            h @ ("VNRRG" | "VNWRG") => {
                let id = register_id(values.next())?;
                let r = Register::parse(id, values)?;
                Ok(if h == "VNRRG" {
                    VnReply::Read(r)
                } else {
                    VnReply::Written(r)
                })
            }
            "VNERR" => match (values.next(), values.next()) {
                (Some(code), None) => u8::from_str_radix(code, 16)
                    .map(VnReply::Error)
                    .map_err(|_| VnError::BadSentence("error code is not hex")),
                _ => Err(VnError::BadSentence("an error carries one code")),
            },
            "VNYPR" => {
                let mut ypr = [0f32; 3];
                let (mut n, mut parsed) = (0, 0);
                for v in values {
                    if let (Some(slot), Ok(x)) = (ypr.get_mut(n), v.parse()) {
                        *slot = x;
                        parsed += 1;
                    }
                    n += 1;
                }
                if n == 3 && parsed == 3 {
                    Ok(VnReply::Ypr(ypr))
                } else {
                    Err(VnError::BadSentence("YPR carries three numbers"))
                }
            }
            other => Err(VnError::unknown_header(other)),
        }
    }
}

/// Group numbers are 1-based on the wire and in the documentation.
pub fn group_name(g: usize) -> &'static str {
    match g {
        group::COMMON => "common",
        group::TIME => "time",
        group::IMU => "imu",
        group::GPS => "gnss1",
        group::ATTITUDE => "attitude",
        group::INS => "ins",
        group::GPS2 => "gnss2",
        _ => "?",
    }
}
