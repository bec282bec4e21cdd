//! Errors of the whole-message VectorNav decode calls (the streaming decoder never fails).

use thiserror::Error;

/// Bytes of a sentence header: `VN` and three letters.
pub const HEADER_LEN: usize = 5;

/// Why a complete ASCII sentence or binary message, or a value in it, could not be decoded.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum VnError {
    /// The bytes do not start with the binary sync byte 0xFA.
    #[error("binary message starts 0x{0:02X}, not the sync byte 0xFA")]
    BadSync(u8),
    /// Fewer bytes than the header says the message has.
    #[error("message of {found} bytes: its header says {expected}")]
    WrongLength {
        /// Length computed from the header.
        expected: usize,
        /// Length that was given.
        found: usize,
    },
    /// No group, a group with an empty field word, or group 8 (which does not exist).
    #[error("group byte 0x{0:02X} or its field words name no valid group")]
    BadGroups(u8),
    /// A field bit whose size this codec does not know: the message's length is unknown.
    #[error("group {group} field bit {bit} has no known size")]
    UnknownField {
        /// Group number, 1 (common) to 7 (GNSS2).
        group: u8,
        /// Bit in the group's field word.
        bit: u8,
    },
    /// The CRC over the message after its sync byte is not zero.
    #[error("bad CRC: 0x{0:04X} over the message instead of 0")]
    BadCrc(u16),
    /// The ASCII sentence's checksum or CRC does not match its body (numbers, not text, so
    /// that a corrupt sentence met while resynchronising allocates nothing).
    #[error("bad ASCII check: computed 0x{computed:X}, sentence carries 0x{found:X}")]
    BadChecksum {
        /// The check computed over the body.
        computed: u16,
        /// The check the sentence carries.
        found: u16,
    },
    /// The ASCII sentence is not `$VNxxx,...*CS\r\n` of printable characters.
    #[error("malformed ASCII sentence: {0}")]
    BadSentence(&'static str),
    /// A register this codec does not know.
    #[error("register {0} is not one this codec decodes")]
    UnknownRegister(u8),
    /// A register's values do not parse.
    #[error("register {id}: {problem}")]
    BadRegister {
        /// Register id.
        id: u8,
        /// What is wrong.
        problem: &'static str,
    },
    /// The sentence is not a command or reply this codec decodes: its header's first
    /// [`HEADER_LEN`] bytes (a good sentence's header is `VN` and three letters), padded with
    /// spaces (held inline: an unknown ASCII output is met at its rate).
    #[error("unknown sentence header {:?}", String::from_utf8_lossy(.0).trim_end())]
    UnknownHeader([u8; HEADER_LEN]),
    /// Encoding asked for a field the data does not hold.
    #[error("group {group} field bit {bit} is enabled but the data has no value for it")]
    MissingValue {
        /// Group number, 1 to 7.
        group: u8,
        /// Bit in the group's field word.
        bit: u8,
    },
}

impl VnError {
    /// [`VnError::UnknownHeader`] of `header`.
    pub(crate) fn unknown_header(header: &str) -> VnError {
        let mut h = [b' '; HEADER_LEN];
        for (d, s) in h.iter_mut().zip(header.bytes()) {
            *d = s;
        }
        VnError::UnknownHeader(h)
    }
}
