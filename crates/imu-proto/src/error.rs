//! Errors of the whole-frame decode calls (the streaming decoders never fail, they count).

use thiserror::Error;

/// Why a complete, exact-length frame (reply or command) could not be decoded.
///
/// Returned by [`Reply::decode`](crate::reply::Reply::decode) and
/// [`Command::decode`](crate::command::Command::decode). The streaming decoders never return it:
/// they turn the same conditions into counted, rejected byte runs.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum FrameError {
    /// No bytes at all were given.
    #[error("empty frame: expected at least a header byte")]
    Empty,
    /// The header byte is not a code this codec knows.
    #[error("unknown code 0x{0:02X}: not a 3DM-GX1 command this codec knows")]
    UnknownCode(u8),
    /// The slice length does not match the fixed length for its header code.
    #[error("code 0x{code:02X}: expected {expected} bytes, found {found}")]
    WrongLength {
        /// Header code of the frame.
        code: u8,
        /// Fixed length for this code, header and checksum included.
        expected: usize,
        /// Length that was given.
        found: usize,
    },
    /// The checksum stored in the frame does not match the one computed over it.
    #[error("bad checksum: computed 0x{expected:04X}, frame carries 0x{found:04X}")]
    BadChecksum {
        /// Checksum computed over header and words.
        expected: u16,
        /// Checksum carried in the frame's last two bytes.
        found: u16,
    },
    /// A byte that the protocol fixes (e.g. `00` after `10`, `C1 C3 C5` after tare) is wrong.
    #[error("code 0x{code:02X}: byte {offset} must be 0x{expected:02X}, found 0x{found:02X}")]
    BadArgument {
        /// Header code of the frame.
        code: u8,
        /// Byte offset of the wrong byte inside the frame.
        offset: usize,
        /// The value the protocol requires there.
        expected: u8,
        /// The value found.
        found: u8,
    },
}
