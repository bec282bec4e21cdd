//! The streaming MIP decoder, used on both sides: push bytes, pull packets and rejected runs;
//! never fails, never panics, and accounts for every input byte exactly once.
//!
//! It shares the GX1 decoders' byte buffer, reject reasons and counters
//! ([`DecoderStats`]), so the conservation law is the same:
//! `bytes_in == frame_bytes + rejected_bytes + pending_len()`, and the events' bytes, in
//! order, are exactly the input stream.

use crate::decoder::stream::StreamBuf;
use crate::decoder::{DecoderStats, MAX_GARBAGE_RUN, RejectReason};

use super::{CHECKSUM_LEN, HEADER_LEN, MipError, Packet, SYNC1, SYNC2};

/// One thing the [`MipDecoder`] found in the stream.
// The packet is held inline (up to 261 bytes) so that decoding one allocates nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
pub enum MipEvent {
    /// A packet with good sync, checksum and field layout.
    Packet {
        /// The packet.
        packet: Packet,
        /// Stream byte offset of its first sync byte.
        offset: u64,
    },
    /// Bytes that are not (part of) a good packet.
    Rejected {
        /// The rejected bytes.
        bytes: Vec<u8>,
        /// Stream byte offset of the first rejected byte.
        offset: u64,
        /// Why they were rejected.
        reason: RejectReason,
    },
}

impl MipEvent {
    /// Stream byte offset of the event's first byte.
    pub fn offset(&self) -> u64 {
        match self {
            MipEvent::Packet { offset, .. } | MipEvent::Rejected { offset, .. } => *offset,
        }
    }

    /// The event's bytes.
    pub fn bytes(&self) -> &[u8] {
        match self {
            MipEvent::Packet { packet, .. } => packet.as_bytes(),
            MipEvent::Rejected { bytes, .. } => bytes,
        }
    }
}

/// Result of looking at the candidate packet at the head of the unprocessed bytes.
// The packet is held inline, as in `MipEvent`: it moves once, into the event.
#[allow(clippy::large_enum_variant)]
enum Verdict {
    NeedMore,
    Packet(Packet),
    Truncated(usize),
    BadChecksum(usize),
    Malformed(usize),
}

/// Result of looking for a good packet starting inside a failed candidate.
enum Inner {
    NeedMore,
    Found(usize),
    None,
}

/// Streaming decoder of MIP packets (host side: replies and data; device side: commands).
///
/// At the head of the stream, a byte that cannot start `0x75 0x65` is garbage. A packet start
/// waits for its header, then for the length the header announces, then:
/// - good checksum and field layout: a `Packet`;
/// - otherwise, if a good packet starts inside the candidate: `Rejected { Truncated }` with the
///   bytes up to that start, and decoding resumes there;
/// - otherwise `Rejected { BadChecksum }` (or `Malformed`: good checksum, bad fields or
///   descriptor set 0) with the candidate's bytes, which is what skipping one byte at a time
///   would give, because every start inside it was just checked.
///
/// A host waiting for one reply calls [`flush`](Self::flush) on a read timeout, so a packet cut
/// off at the end of the stream is reported instead of held.
#[derive(Debug, Clone, Default)]
pub struct MipDecoder {
    sb: StreamBuf,
    lost_sync: bool,
    stats: DecoderStats,
}

impl MipDecoder {
    /// A decoder at the start of a stream.
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends received bytes; the work happens in [`next_event`](Self::next_event).
    pub fn push(&mut self, bytes: &[u8]) {
        self.stats.bytes_in += bytes.len() as u64;
        self.sb.push(bytes);
    }

    /// Marks the end of the stream so far: pending bytes are reported (an incomplete packet
    /// as `Truncated`) instead of waited on. Bytes pushed afterwards decode normally.
    pub fn flush(&mut self) {
        self.sb.flush();
    }

    /// Bytes pushed but not yet reported in any event.
    pub fn pending_len(&self) -> usize {
        self.sb.pending_len()
    }

    /// The counters so far.
    pub fn stats(&self) -> DecoderStats {
        self.stats
    }

    fn emit_garbage(&mut self) -> MipEvent {
        let (offset, bytes) = self.sb.take_garbage();
        self.stats.garbage_bytes += bytes.len() as u64;
        self.stats.rejected_bytes += bytes.len() as u64;
        self.lost_sync = true;
        MipEvent::Rejected {
            bytes,
            offset,
            reason: RejectReason::Garbage,
        }
    }

    fn emit_rejected(&mut self, n: usize, reason: RejectReason) -> MipEvent {
        let (offset, bytes) = self.sb.consume(n, |offset, b| (offset, b.to_vec()));
        self.stats.rejected_bytes += bytes.len() as u64;
        match reason {
            RejectReason::BadChecksum => self.stats.checksum_failures += 1,
            RejectReason::Malformed => self.stats.malformed_frames += 1,
            RejectReason::Truncated => self.stats.truncated_frames += 1,
            RejectReason::Garbage => self.stats.garbage_bytes += bytes.len() as u64,
        }
        self.lost_sync = true;
        MipEvent::Rejected {
            bytes,
            offset,
            reason,
        }
    }

    fn emit_packet(&mut self, packet: Packet) -> MipEvent {
        let len = packet.as_bytes().len();
        let offset = self.sb.consume(len, |offset, _| offset);
        self.stats.frames += 1;
        self.stats.frame_bytes += len as u64;
        if self.lost_sync {
            self.stats.resyncs += 1;
            self.lost_sync = false;
        }
        MipEvent::Packet { packet, offset }
    }

    /// The next event, or `None` when more bytes are needed (or everything is reported).
    pub fn next_event(&mut self) -> Option<MipEvent> {
        loop {
            let eos = self.sb.eos();
            let garbage_len = self.sb.garbage_len;
            let avail = self.sb.unprocessed();
            if avail.is_empty() {
                if !eos {
                    return None;
                }
                if garbage_len > 0 {
                    return Some(self.emit_garbage());
                }
                // Flush complete; bytes pushed after the flush decode normally.
                self.sb.flush_end = None;
                if self.sb.unprocessed().is_empty() {
                    return None;
                }
                continue;
            }
            if garbage_len >= MAX_GARBAGE_RUN {
                return Some(self.emit_garbage());
            }
            // Hot path over garbage: jump to the next possible packet start in one scan.
            let room = MAX_GARBAGE_RUN - garbage_len;
            let skip = (0..avail.len().min(room))
                .find(|&p| may_start(avail, p, eos))
                .unwrap_or(room.min(avail.len()));
            if skip > 0 {
                self.sb.garbage_len += skip;
                continue;
            }
            // A possible start ends any garbage run, whatever the candidate turns out to be.
            if garbage_len > 0 {
                return Some(self.emit_garbage());
            }
            return match classify(avail, eos) {
                Verdict::NeedMore => None,
                Verdict::Packet(p) => Some(self.emit_packet(p)),
                Verdict::Truncated(n) => Some(self.emit_rejected(n, RejectReason::Truncated)),
                Verdict::BadChecksum(n) => Some(self.emit_rejected(n, RejectReason::BadChecksum)),
                Verdict::Malformed(n) => Some(self.emit_rejected(n, RejectReason::Malformed)),
            };
        }
    }
}

/// `avail[p]` is `0x75` followed by `0x65`, or by nothing yet (and more may come).
fn may_start(avail: &[u8], p: usize, eos: bool) -> bool {
    avail[p] == SYNC1
        && match avail.get(p + 1) {
            Some(&b) => b == SYNC2,
            None => !eos,
        }
}

/// The packet at the head of `avail` (which may start one).
fn classify(avail: &[u8], eos: bool) -> Verdict {
    let Some(header) = avail.get(..HEADER_LEN) else {
        return if eos {
            Verdict::Truncated(avail.len())
        } else {
            Verdict::NeedMore
        };
    };
    let len = HEADER_LEN + usize::from(header[3]) + CHECKSUM_LEN;
    let Some(candidate) = avail.get(..len) else {
        if !eos {
            return Verdict::NeedMore;
        }
        // The stream ends inside the candidate: salvage a good packet inside it if there is
        // one, else the whole rest is one truncated packet.
        return match find_inner(avail, avail.len(), true) {
            Inner::Found(q) => Verdict::Truncated(q),
            _ => Verdict::Truncated(avail.len()),
        };
    };
    let error = match Packet::parse(candidate) {
        Ok(p) => return Verdict::Packet(p),
        Err(e) => e,
    };
    match find_inner(avail, len, eos) {
        Inner::NeedMore => Verdict::NeedMore,
        Inner::Found(q) => Verdict::Truncated(q),
        Inner::None => match error {
            MipError::BadChecksum { .. } => Verdict::BadChecksum(len),
            _ => Verdict::Malformed(len),
        },
    }
}

/// The first good packet starting at 1..span. Without `eos`, a start whose packet is not fully
/// buffered yet means waiting (it may be the good one).
fn find_inner(avail: &[u8], span: usize, eos: bool) -> Inner {
    for q in 1..span.min(avail.len()) {
        if avail[q] != SYNC1 {
            continue;
        }
        let rest = &avail[q..];
        let Some(header) = rest.get(..HEADER_LEN) else {
            if eos || rest.get(1).is_some_and(|&b| b != SYNC2) {
                continue;
            }
            return Inner::NeedMore;
        };
        if header[1] != SYNC2 {
            continue;
        }
        let len = HEADER_LEN + usize::from(header[3]) + CHECKSUM_LEN;
        match rest.get(..len) {
            Some(candidate) => {
                if Packet::parse(candidate).is_ok() {
                    return Inner::Found(q);
                }
            }
            None if eos => {}
            None => return Inner::NeedMore,
        }
    }
    Inner::None
}
