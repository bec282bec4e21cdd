//! Streaming decoders: push bytes as they arrive, pull typed events; never fail, never panic,
//! and account for every input byte exactly once.
//!
//! [`ReplyDecoder`] runs on the host (bytes from the device), [`CommandDecoder`] on the device
//! side (bytes from the host, e.g. in the simulator). Both are lazy: [`push`](ReplyDecoder::push)
//! only buffers, [`next_event`](ReplyDecoder::next_event) does the work. Memory is the bytes
//! pushed but not yet consumed by `next_event`, plus a constant: a caller that drains events
//! after each push keeps the buffer at one push plus at most a few frames of look-ahead, whatever
//! the bytes are. Garbage runs are reported in pieces of at most [`MAX_GARBAGE_RUN`] bytes so
//! they never have to be held whole.
//!
//! The conservation law, checked by the property tests and the fuzz targets:
//! `bytes_in == bytes in Frame/Command events + bytes in Rejected events + pending_len()`,
//! and the events' bytes, in order, are exactly the input stream.

use std::fmt;
use std::ops::Deref;

use crate::command::{Command, command_len_for_code, fixed_command_byte};
use crate::error::FrameError;
use crate::reply::{KNOWN_REPLY_CODES, MAX_REPLY_LEN, Reply, reply_len_for_code};

mod command;
pub mod framed;
mod reply;
pub(crate) mod stream;

pub use command::*;
pub use reply::*;
use stream::*;

/// Longest garbage run reported as one event; longer runs are split so memory stays bounded.
pub const MAX_GARBAGE_RUN: usize = 1024;

/// The exact bytes of one reply frame, held inline.
///
/// Frames are at most [`MAX_REPLY_LEN`] (31) bytes, so they are stored in a fixed array instead
/// of a `Vec`: decoding a frame allocates nothing. Dereferences to `&[u8]`.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct FrameBytes {
    len: u8,
    data: [u8; MAX_REPLY_LEN],
}

impl FrameBytes {
    /// Copies `bytes` (at most [`MAX_REPLY_LEN`]; anything longer is cut, which the decoder
    /// never asks for).
    fn new(bytes: &[u8]) -> Self {
        let n = bytes.len().min(MAX_REPLY_LEN);
        let mut data = [0u8; MAX_REPLY_LEN];
        data[..n].copy_from_slice(&bytes[..n]);
        Self { len: n as u8, data }
    }

    /// The frame bytes.
    pub fn as_slice(&self) -> &[u8] {
        &self.data[..usize::from(self.len)]
    }
}

impl Deref for FrameBytes {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        self.as_slice()
    }
}

impl AsRef<[u8]> for FrameBytes {
    fn as_ref(&self) -> &[u8] {
        self.as_slice()
    }
}

impl fmt::Debug for FrameBytes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "FrameBytes({:02X?})", self.as_slice())
    }
}

impl PartialEq<[u8]> for FrameBytes {
    fn eq(&self, other: &[u8]) -> bool {
        self.as_slice() == other
    }
}

impl PartialEq<Vec<u8>> for FrameBytes {
    fn eq(&self, other: &Vec<u8>) -> bool {
        self.as_slice() == other.as_slice()
    }
}

impl PartialEq<FrameBytes> for Vec<u8> {
    fn eq(&self, other: &FrameBytes) -> bool {
        self.as_slice() == other.as_slice()
    }
}

impl PartialEq<FrameBytes> for [u8] {
    fn eq(&self, other: &FrameBytes) -> bool {
        self == other.as_slice()
    }
}

/// Why bytes were rejected by the [`ReplyDecoder`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RejectReason {
    /// A full-length candidate whose checksum failed, with no valid frame starting inside it.
    BadChecksum,
    /// A candidate with a good checksum but a wrong fixed byte (0x10 reply whose byte 1 is not 0).
    Malformed,
    /// A frame cut short: a valid frame starts inside it, or the stream ended (flush) inside it.
    Truncated,
    /// Bytes that do not start an accepted frame (one event per contiguous run, at most
    /// [`MAX_GARBAGE_RUN`] bytes each).
    Garbage,
}

/// One thing the [`ReplyDecoder`] found in the stream.
#[derive(Debug, Clone, PartialEq)]
pub enum DecodeEvent {
    /// A frame with a good checksum.
    Frame {
        /// The decoded reply.
        reply: Reply,
        /// The exact frame bytes, header to checksum.
        bytes: FrameBytes,
        /// Stream byte offset of the frame's header (bytes counted since the decoder was created).
        offset: u64,
    },
    /// Bytes that are not (part of) a good frame.
    Rejected {
        /// The rejected bytes.
        bytes: Vec<u8>,
        /// Stream byte offset of the first rejected byte.
        offset: u64,
        /// Why they were rejected.
        reason: RejectReason,
    },
}

impl DecodeEvent {
    /// Stream byte offset of the event's first byte.
    pub fn offset(&self) -> u64 {
        match self {
            DecodeEvent::Frame { offset, .. } | DecodeEvent::Rejected { offset, .. } => *offset,
        }
    }

    /// The event's bytes.
    pub fn bytes(&self) -> &[u8] {
        match self {
            DecodeEvent::Frame { bytes, .. } => bytes,
            DecodeEvent::Rejected { bytes, .. } => bytes,
        }
    }
}

/// Counters of a [`ReplyDecoder`]. Byte counters are updated when the event is emitted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DecoderStats {
    /// Good frames emitted.
    pub frames: u64,
    /// Bytes pushed.
    pub bytes_in: u64,
    /// Bytes emitted in `Frame` events.
    pub frame_bytes: u64,
    /// Bytes emitted in `Rejected` events of any reason.
    pub rejected_bytes: u64,
    /// Bytes emitted as `Rejected { reason: Garbage }`.
    pub garbage_bytes: u64,
    /// `Rejected { reason: BadChecksum }` events.
    pub checksum_failures: u64,
    /// `Rejected { reason: Malformed }` events.
    pub malformed_frames: u64,
    /// `Rejected { reason: Truncated }` events.
    pub truncated_frames: u64,
    /// Times a good frame followed rejected bytes (the decoder regained sync).
    pub resyncs: u64,
}

#[cfg(test)]
mod tests;
