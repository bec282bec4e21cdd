//! The byte stream of imud's ROS 2 input (a live ROS 2 IMU taken as the device): each message
//! the DDS subscription takes becomes one frame,
//! `"R2" | length (u32, little-endian) | the message's CDR bytes` (encapsulation header
//! included), so the session reads a topic like a serial line, the log keeps every message as a
//! raw frame and `imud replay` feeds the recorded frames back through the same decoder.
//!
//! The subscription writes only whole frames, so on a live link nothing is ever rejected; a
//! replayed capture may be cut or damaged, which is why the decoder still resynchronises on
//! the magic, rejects (and counts) what is not a frame, and keeps the byte accounting of every
//! decoder (`bytes_in = frame bytes + rejected bytes + pending`).

use crate::decoder::{DecoderStats, RejectReason};

/// The two bytes that open every frame.
pub const MAGIC: [u8; 2] = *b"R2";
/// Magic and length.
pub const HEADER_LEN: usize = 6;
/// The longest message a frame may carry, bytes (a `sensor_msgs/Imu` is about 320; a larger
/// length is a damaged header, not a message).
pub const MAX_MESSAGE_LEN: usize = 64 * 1024;
/// The shortest: a CDR encapsulation header.
const MIN_MESSAGE_LEN: usize = 4;

/// Appends the frame of one CDR message to `out`.
pub fn encode(cdr: &[u8], out: &mut Vec<u8>) {
    out.extend_from_slice(&MAGIC);
    // A message longer than u32 cannot come from DDS (its sample size is bounded far below).
    out.extend_from_slice(&u32::try_from(cdr.len()).unwrap_or(u32::MAX).to_le_bytes());
    out.extend_from_slice(cdr);
}

/// The CDR message of a whole frame (what [`FrameDecoder`] returned).
pub fn message(frame: &[u8]) -> &[u8] {
    frame.get(HEADER_LEN..).unwrap_or(&[])
}

/// What the decoder found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum FrameEvent {
    /// A whole frame (header and message).
    Frame {
        /// Stream offset of its first byte.
        offset: u64,
        /// Its bytes.
        bytes: Vec<u8>,
    },
    /// Bytes that are not (part of) a frame.
    Rejected {
        /// Stream offset of the first.
        offset: u64,
        /// The bytes.
        bytes: Vec<u8>,
        /// Why.
        reason: RejectReason,
    },
}

/// Push bytes, pull frames (see the module docs).
#[derive(Debug, Default)]
pub struct FrameDecoder {
    buf: Vec<u8>,
    /// Stream offset of `buf[0]`.
    base_offset: u64,
    /// The line ended: what is left is rejected as truncated.
    flushing: bool,
    stats: DecoderStats,
}

impl FrameDecoder {
    /// Bytes read from the stream.
    pub fn push(&mut self, bytes: &[u8]) {
        self.stats.bytes_in += bytes.len() as u64;
        self.buf.extend_from_slice(bytes);
    }

    /// The line closed: a partial frame is rejected as truncated by the next calls.
    pub fn flush(&mut self) {
        self.flushing = true;
    }

    /// The counters so far.
    pub fn stats(&self) -> DecoderStats {
        self.stats
    }

    /// Takes the first `n` bytes of the buffer.
    fn take(&mut self, n: usize) -> (u64, Vec<u8>) {
        let offset = self.base_offset;
        let bytes: Vec<u8> = self.buf.drain(..n).collect();
        self.base_offset += n as u64;
        (offset, bytes)
    }

    fn reject(&mut self, n: usize, reason: RejectReason) -> FrameEvent {
        let (offset, bytes) = self.take(n);
        self.stats.rejected_bytes += n as u64;
        match reason {
            RejectReason::Garbage => {
                self.stats.garbage_bytes += n as u64;
                self.stats.resyncs += 1;
            }
            RejectReason::Truncated => self.stats.truncated_frames += 1,
            RejectReason::Malformed => self.stats.malformed_frames += 1,
            RejectReason::BadChecksum => self.stats.checksum_failures += 1,
        }
        FrameEvent::Rejected {
            offset,
            bytes,
            reason,
        }
    }

    /// The next frame or rejected run, if the buffer holds one.
    pub fn next_event(&mut self) -> Option<FrameEvent> {
        if self.buf.is_empty() {
            self.flushing = false;
            return None;
        }
        let magic_at = self.buf.windows(2).position(|w| w == MAGIC);
        match magic_at {
            Some(0) => {}
            Some(p) => return Some(self.reject(p, RejectReason::Garbage)),
            None => {
                // A last byte that may open the next magic waits for it (unless the line ended).
                let keep = usize::from(!self.flushing && self.buf.last() == Some(&MAGIC[0]));
                let n = self.buf.len() - keep;
                if n == 0 {
                    return None;
                }
                return Some(self.reject(n, RejectReason::Garbage));
            }
        }
        let Some(len_bytes) = self.buf.get(2..HEADER_LEN) else {
            return self
                .flushing
                .then(|| self.reject(self.buf.len(), RejectReason::Truncated));
        };
        let len = u32::from_le_bytes([len_bytes[0], len_bytes[1], len_bytes[2], len_bytes[3]]);
        let len = usize::try_from(len).unwrap_or(usize::MAX);
        if !(MIN_MESSAGE_LEN..=MAX_MESSAGE_LEN).contains(&len) {
            // No frame starts here: the magic is rejected and the search goes on after it.
            return Some(self.reject(MAGIC.len(), RejectReason::Malformed));
        }
        let total = HEADER_LEN + len;
        if self.buf.len() < total {
            return self
                .flushing
                .then(|| self.reject(self.buf.len(), RejectReason::Truncated));
        }
        let (offset, bytes) = self.take(total);
        self.stats.frames += 1;
        self.stats.frame_bytes += total as u64;
        Some(FrameEvent::Frame { offset, bytes })
    }

    /// Bytes held and not yet reported (`bytes_in = frame + rejected + pending`).
    pub fn pending_len(&self) -> usize {
        self.buf.len()
    }
}
