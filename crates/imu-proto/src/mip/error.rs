//! Errors of the whole-packet and typed MIP decode calls (the streaming decoder never fails).

use thiserror::Error;

/// Why a complete packet, or a field in it, could not be decoded.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum MipError {
    /// Fewer bytes than a header and a checksum.
    #[error("packet of {0} bytes: a MIP packet has at least 6")]
    TooShort(usize),
    /// The packet does not start with `0x75 0x65`.
    #[error("packet starts 0x{0:02X} 0x{1:02X}, not the sync bytes 0x75 0x65")]
    BadSync(u8, u8),
    /// The slice length disagrees with the payload length byte.
    #[error("payload length byte says {expected} bytes of packet, found {found}")]
    WrongLength {
        /// Length the header implies, header and checksum included.
        expected: usize,
        /// Length that was given.
        found: usize,
    },
    /// The Fletcher-16 checksum does not match.
    #[error("bad checksum: computed 0x{expected:04X}, packet carries 0x{found:04X}")]
    BadChecksum {
        /// Checksum computed over the packet.
        expected: u16,
        /// Checksum carried in the packet's last two bytes.
        found: u16,
    },
    /// Descriptor set 0x00 is invalid.
    #[error("descriptor set 0x00 is invalid")]
    ZeroDescriptorSet,
    /// The field lengths do not tile the payload.
    #[error("field at payload byte {offset} has length {len}, which does not fit the payload")]
    BadFieldLength {
        /// Offset of the field's length byte inside the payload.
        offset: usize,
        /// The field's length byte.
        len: u8,
    },
    /// A field's data has the wrong size or an invalid value for its descriptor.
    #[error("field 0x{set:02X}/0x{descriptor:02X}: {problem}")]
    BadField {
        /// Descriptor set of the packet.
        set: u8,
        /// Field descriptor.
        descriptor: u8,
        /// What is wrong.
        problem: &'static str,
    },
    /// The packet is not of the descriptor set the caller asked for.
    #[error("descriptor set 0x{found:02X} where 0x{expected:02X} was expected")]
    WrongDescriptorSet {
        /// The set the caller decodes.
        expected: u8,
        /// The packet's set.
        found: u8,
    },
    /// A command this codec does not know.
    #[error("unknown command 0x{set:02X}/0x{descriptor:02X}")]
    UnknownCommand {
        /// Descriptor set.
        set: u8,
        /// Field descriptor.
        descriptor: u8,
    },
    /// A reply packet whose first field is not an ack/nack.
    #[error("reply packet without an ack/nack (0xF1) field before field 0x{0:02X}")]
    MissingAck(u8),
    /// More fields than one packet's payload holds.
    #[error("fields of {0} bytes do not fit a packet's 255-byte payload")]
    PayloadFull(usize),
}
