//! Errors of the whole-message and typed Xsens decode calls (the streaming decoder never fails).

use thiserror::Error;

/// Why a complete message, or an item in it, could not be decoded.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum XsensError {
    /// Fewer bytes than a header and a checksum.
    #[error("message of {0} bytes: an Xbus message has at least 5")]
    TooShort(usize),
    /// The message does not start with `0xFA 0xFF`.
    #[error("message starts 0x{0:02X} 0x{1:02X}, not the preamble 0xFA and bus id 0xFF")]
    BadPreamble(u8, u8),
    /// The slice length disagrees with the length field.
    #[error("length field says {expected} bytes of message, found {found}")]
    WrongLength {
        /// Length the header implies, header and checksum included.
        expected: usize,
        /// Length that was given.
        found: usize,
    },
    /// An extended length beyond the protocol's maximum.
    #[error("extended length {0} is beyond the maximum {max}", max = super::MAX_DATA_LEN)]
    BadExtendedLength(usize),
    /// The bytes after the preamble do not sum to 0 mod 256.
    #[error("bad checksum: the bytes after the preamble sum to 0x{0:02X}, not 0")]
    BadChecksum(u8),
    /// The MTData2 items do not tile the data.
    #[error("MTData2 item at data byte {offset} (id 0x{id:04X}) runs past the message's end")]
    BadItemLayout {
        /// Offset of the item's identifier in the data.
        offset: usize,
        /// The item's data identifier (0 if cut inside it).
        id: u16,
    },
    /// A message's data has the wrong size or an invalid value for its id.
    #[error("message 0x{mid:02X}: {problem}")]
    BadData {
        /// Message id.
        mid: u8,
        /// What is wrong.
        problem: &'static str,
    },
    /// A message id this codec does not decode in this direction.
    #[error("unknown message id 0x{0:02X}")]
    UnknownMessage(u8),
    /// More data than one message holds.
    #[error("{0} bytes of data do not fit one message ({max} at most)", max = super::MAX_DATA_LEN)]
    TooLong(usize),
}
