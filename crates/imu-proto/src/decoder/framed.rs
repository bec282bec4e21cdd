//! The streaming decoder of length-prefixed packet protocols (MIP, Xsens Xbus): one
//! implementation of the resync, salvage and byte-accounting rules, parameterised by a
//! [`Framing`] that says where a packet may start, how long its header says it is, and whether
//! a candidate is a good packet.
//!
//! It shares the GX1 decoders' byte buffer, reject reasons and counters ([`DecoderStats`]), so
//! the conservation law is the same:
//! `bytes_in == frame_bytes + rejected_bytes + pending_len()`, and the events' bytes, in
//! order, are exactly the input stream.

use std::marker::PhantomData;

use super::stream::StreamBuf;
use super::{DecoderStats, MAX_GARBAGE_RUN, RejectReason};

/// What a packet protocol tells the [`FramedDecoder`].
pub trait Framing {
    /// A checked packet.
    type Packet;

    /// `avail[p]` may start a packet: its sync bytes, or a prefix of them at the end of
    /// `avail` when more bytes may come (`!eos`).
    fn may_start(avail: &[u8], p: usize, eos: bool) -> bool;

    /// The whole packet length the header at the start of `head` announces, or `None` while
    /// fewer bytes than the header are there. `head` starts with the sync bytes.
    fn packet_len(head: &[u8]) -> Option<usize>;

    /// Checks a complete candidate: `Ok` a good packet, `Err(true)` a checksum failure,
    /// `Err(false)` any other fault (good checksum, bad layout).
    fn parse(candidate: &[u8]) -> Result<Self::Packet, bool>;

    /// The packet's bytes on the wire.
    fn bytes(packet: &Self::Packet) -> &[u8];
}

/// One thing a [`FramedDecoder`] found in the stream.
// The packet may be held inline (MIP's 261 bytes) so that decoding one allocates nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
pub enum PacketEvent<P> {
    /// A packet with good sync, checksum and layout.
    Packet {
        /// The packet.
        packet: P,
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

impl<P> PacketEvent<P> {
    /// Stream byte offset of the event's first byte.
    pub fn offset(&self) -> u64 {
        match self {
            PacketEvent::Packet { offset, .. } | PacketEvent::Rejected { offset, .. } => *offset,
        }
    }
}

impl<P: AsRef<[u8]>> PacketEvent<P> {
    /// The event's bytes.
    pub fn bytes(&self) -> &[u8] {
        match self {
            PacketEvent::Packet { packet, .. } => packet.as_ref(),
            PacketEvent::Rejected { bytes, .. } => bytes,
        }
    }
}

/// Result of looking at the candidate packet at the head of the unprocessed bytes.
enum Verdict<P> {
    NeedMore,
    Packet(P),
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

/// Streaming decoder of a [`Framing`]'s packets (host side: replies and data; device side:
/// commands).
///
/// At the head of the stream, a byte that cannot start a packet is garbage. A packet start
/// waits for its header, then for the length the header announces, then:
/// - a good packet: `Packet`;
/// - otherwise, if a good packet starts inside the candidate: `Rejected { Truncated }` with the
///   bytes up to that start, and decoding resumes there;
/// - otherwise `Rejected { BadChecksum }` (or `Malformed`: good checksum, bad layout) with the
///   candidate's bytes, which is what skipping one byte at a time would give, because every
///   start inside it was just checked.
///
/// A host waiting for one reply calls [`flush`](Self::flush) on a read timeout, so a packet cut
/// off at the end of the stream is reported instead of held.
#[derive(Debug, Clone)]
pub struct FramedDecoder<F> {
    sb: StreamBuf,
    lost_sync: bool,
    stats: DecoderStats,
    framing: PhantomData<F>,
}

impl<F> Default for FramedDecoder<F> {
    fn default() -> Self {
        Self {
            sb: StreamBuf::default(),
            lost_sync: false,
            stats: DecoderStats::default(),
            framing: PhantomData,
        }
    }
}

impl<F: Framing> FramedDecoder<F> {
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

    fn emit_garbage(&mut self) -> PacketEvent<F::Packet> {
        let (offset, bytes) = self.sb.take_garbage();
        self.stats.garbage_bytes += bytes.len() as u64;
        self.stats.rejected_bytes += bytes.len() as u64;
        self.lost_sync = true;
        PacketEvent::Rejected {
            bytes,
            offset,
            reason: RejectReason::Garbage,
        }
    }

    fn emit_rejected(&mut self, n: usize, reason: RejectReason) -> PacketEvent<F::Packet> {
        let (offset, bytes) = self.sb.consume(n, |offset, b| (offset, b.to_vec()));
        self.stats.rejected_bytes += bytes.len() as u64;
        match reason {
            RejectReason::BadChecksum => self.stats.checksum_failures += 1,
            RejectReason::Malformed => self.stats.malformed_frames += 1,
            RejectReason::Truncated => self.stats.truncated_frames += 1,
            RejectReason::Garbage => self.stats.garbage_bytes += bytes.len() as u64,
        }
        self.lost_sync = true;
        PacketEvent::Rejected {
            bytes,
            offset,
            reason,
        }
    }

    fn emit_packet(&mut self, packet: F::Packet) -> PacketEvent<F::Packet> {
        let len = F::bytes(&packet).len();
        let offset = self.sb.consume(len, |offset, _| offset);
        self.stats.frames += 1;
        self.stats.frame_bytes += len as u64;
        if self.lost_sync {
            self.stats.resyncs += 1;
            self.lost_sync = false;
        }
        PacketEvent::Packet { packet, offset }
    }

    /// The next event, or `None` when more bytes are needed (or everything is reported).
    pub fn next_event(&mut self) -> Option<PacketEvent<F::Packet>> {
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
                .find(|&p| F::may_start(avail, p, eos))
                .unwrap_or(room.min(avail.len()));
            if skip > 0 {
                self.sb.garbage_len += skip;
                continue;
            }
            // A possible start ends any garbage run, whatever the candidate turns out to be.
            if garbage_len > 0 {
                return Some(self.emit_garbage());
            }
            return match classify::<F>(avail, eos) {
                Verdict::NeedMore => None,
                Verdict::Packet(p) => Some(self.emit_packet(p)),
                Verdict::Truncated(n) => Some(self.emit_rejected(n, RejectReason::Truncated)),
                Verdict::BadChecksum(n) => Some(self.emit_rejected(n, RejectReason::BadChecksum)),
                Verdict::Malformed(n) => Some(self.emit_rejected(n, RejectReason::Malformed)),
            };
        }
    }
}

/// The packet at the head of `avail` (which may start one).
fn classify<F: Framing>(avail: &[u8], eos: bool) -> Verdict<F::Packet> {
    let Some(len) = F::packet_len(avail) else {
        if !eos {
            return Verdict::NeedMore;
        }
        // The stream ends inside the header: salvage a good packet inside it if there is one.
        return match find_inner::<F>(avail, avail.len(), true) {
            Inner::Found(q) => Verdict::Truncated(q),
            _ => Verdict::Truncated(avail.len()),
        };
    };
    let Some(candidate) = avail.get(..len) else {
        if !eos {
            return Verdict::NeedMore;
        }
        // The stream ends inside the candidate: salvage a good packet inside it if there is
        // one, else the whole rest is one truncated packet.
        return match find_inner::<F>(avail, avail.len(), true) {
            Inner::Found(q) => Verdict::Truncated(q),
            _ => Verdict::Truncated(avail.len()),
        };
    };
    let checksum_failed = match F::parse(candidate) {
        Ok(p) => return Verdict::Packet(p),
        Err(checksum) => checksum,
    };
    match find_inner::<F>(avail, len, eos) {
        Inner::NeedMore => Verdict::NeedMore,
        Inner::Found(q) => Verdict::Truncated(q),
        Inner::None if checksum_failed => Verdict::BadChecksum(len),
        Inner::None => Verdict::Malformed(len),
    }
}

/// The first good packet starting at 1..span. Without `eos`, a start whose packet is not fully
/// buffered yet means waiting (it may be the good one).
fn find_inner<F: Framing>(avail: &[u8], span: usize, eos: bool) -> Inner {
    for q in 1..span.min(avail.len()) {
        if !F::may_start(avail, q, eos) {
            continue;
        }
        let rest = &avail[q..];
        let Some(len) = F::packet_len(rest) else {
            if eos {
                continue;
            }
            return Inner::NeedMore;
        };
        match rest.get(..len) {
            Some(candidate) => {
                if F::parse(candidate).is_ok() {
                    return Inner::Found(q);
                }
            }
            None if eos => {}
            None => return Inner::NeedMore,
        }
    }
    Inner::None
}
