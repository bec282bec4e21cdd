//! The streaming VectorNav decoder, used on both sides: push bytes, pull binary messages, ASCII
//! sentences and rejected runs; never fails, never panics, and accounts for every input byte
//! exactly once.
//!
//! A unit interleaves the two streams on one port (a `$VNWRG` reply between binary messages),
//! so one decoder separates them: a binary message starts with 0xFA and a valid group byte, a
//! sentence with `$VN`. It shares the GX1 and MIP decoders' byte buffer, reject reasons and
//! counters ([`DecoderStats`]), so the conservation law is the same:
//! `bytes_in == frame_bytes + rejected_bytes + pending_len()`, with both kinds counted as
//! frames, and the events' bytes, in order, are exactly the input stream.

use crate::decoder::stream::StreamBuf;
use crate::decoder::{DecoderStats, MAX_GARBAGE_RUN, RejectReason};

use super::ascii::{MAX_SENTENCE_LEN, Sentence};
use super::binary::{self, BinaryMessage};
use super::{SYNC, VnError};

/// One thing the [`VnDecoder`] found in the stream.
// The decoded values are held inline (as in `MipEvent`): they move once, into the event.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
pub enum VnEvent {
    /// A binary message with a good CRC and a known layout.
    Binary {
        /// The message.
        message: BinaryMessage,
        /// Stream byte offset of its sync byte.
        offset: u64,
    },
    /// An ASCII sentence with a good check (or the `XX` wildcard).
    Ascii {
        /// The sentence.
        sentence: Sentence,
        /// Stream byte offset of its `$`.
        offset: u64,
    },
    /// Bytes that are not (part of) a good message or sentence.
    Rejected {
        /// The rejected bytes.
        bytes: Vec<u8>,
        /// Stream byte offset of the first rejected byte.
        offset: u64,
        /// Why they were rejected.
        reason: RejectReason,
    },
}

impl VnEvent {
    /// Stream byte offset of the event's first byte.
    pub fn offset(&self) -> u64 {
        match self {
            VnEvent::Binary { offset, .. }
            | VnEvent::Ascii { offset, .. }
            | VnEvent::Rejected { offset, .. } => *offset,
        }
    }

    /// The event's bytes.
    pub fn bytes(&self) -> &[u8] {
        match self {
            VnEvent::Binary { message, .. } => message.as_bytes(),
            VnEvent::Ascii { sentence, .. } => sentence.as_bytes(),
            VnEvent::Rejected { bytes, .. } => bytes,
        }
    }
}

/// A good message or sentence.
#[allow(clippy::large_enum_variant)]
enum Good {
    Binary(BinaryMessage),
    Ascii(Sentence),
}

#[allow(clippy::large_enum_variant)]
enum Verdict {
    NeedMore,
    Good(Good),
    Truncated(usize),
    BadChecksum(usize),
    Malformed(usize),
}

enum Inner {
    NeedMore,
    Found(usize),
    None,
}

/// The extent of the candidate at the head of `avail`.
enum Extent {
    /// Not decidable yet.
    NeedMore,
    /// A candidate of this many bytes.
    Len(usize),
    /// A start that cannot be framed (unknown field size, bad group byte, a sentence start
    /// without an end in reach): these many bytes are its known part.
    Unframeable(usize),
}

/// Streaming decoder of VectorNav binary messages and ASCII sentences.
///
/// At the head of the stream, a byte that cannot start either is garbage. A start waits for
/// its extent (a binary header's field words, a sentence's `\n`), then:
/// - good CRC or check: a `Binary` or `Ascii` event;
/// - otherwise, if a good message or sentence starts inside the candidate: `Rejected {
///   Truncated }` up to that start, and decoding resumes there;
/// - otherwise `Rejected { BadChecksum }` with the candidate's bytes, or `Malformed` (a
///   sentence that is not `$VN...*CS\r\n`, a binary header whose length is unknown: its
///   header bytes).
///
/// A host waiting for one reply calls [`flush`](Self::flush) on a read timeout, so a message
/// cut off at the end of the stream is reported instead of held.
#[derive(Debug, Clone, Default)]
pub struct VnDecoder {
    sb: StreamBuf,
    lost_sync: bool,
    stats: DecoderStats,
    sentences: u64,
}

impl VnDecoder {
    /// A decoder at the start of a stream.
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends received bytes; the work happens in [`next_event`](Self::next_event).
    pub fn push(&mut self, bytes: &[u8]) {
        self.stats.bytes_in += bytes.len() as u64;
        self.sb.push(bytes);
    }

    /// Marks the end of the stream so far: pending bytes are reported instead of waited on.
    pub fn flush(&mut self) {
        self.sb.flush();
    }

    /// Bytes pushed but not yet reported in any event.
    pub fn pending_len(&self) -> usize {
        self.sb.pending_len()
    }

    /// The counters so far (`frames` counts binary messages and sentences).
    pub fn stats(&self) -> DecoderStats {
        self.stats
    }

    /// Of the frames, how many were ASCII sentences.
    pub fn sentences(&self) -> u64 {
        self.sentences
    }

    fn emit_garbage(&mut self) -> VnEvent {
        let (offset, bytes) = self.sb.take_garbage();
        self.stats.garbage_bytes += bytes.len() as u64;
        self.stats.rejected_bytes += bytes.len() as u64;
        self.lost_sync = true;
        VnEvent::Rejected {
            bytes,
            offset,
            reason: RejectReason::Garbage,
        }
    }

    fn emit_rejected(&mut self, n: usize, reason: RejectReason) -> VnEvent {
        let (offset, bytes) = self.sb.consume(n, |offset, b| (offset, b.to_vec()));
        self.stats.rejected_bytes += bytes.len() as u64;
        match reason {
            RejectReason::BadChecksum => self.stats.checksum_failures += 1,
            RejectReason::Malformed => self.stats.malformed_frames += 1,
            RejectReason::Truncated => self.stats.truncated_frames += 1,
            RejectReason::Garbage => self.stats.garbage_bytes += bytes.len() as u64,
        }
        self.lost_sync = true;
        VnEvent::Rejected {
            bytes,
            offset,
            reason,
        }
    }

    fn emit_good(&mut self, good: Good) -> VnEvent {
        let len = match &good {
            Good::Binary(m) => m.as_bytes().len(),
            Good::Ascii(s) => s.as_bytes().len(),
        };
        let offset = self.sb.consume(len, |offset, _| offset);
        self.stats.frames += 1;
        self.stats.frame_bytes += len as u64;
        if self.lost_sync {
            self.stats.resyncs += 1;
            self.lost_sync = false;
        }
        match good {
            Good::Binary(message) => VnEvent::Binary { message, offset },
            Good::Ascii(sentence) => {
                self.sentences += 1;
                VnEvent::Ascii { sentence, offset }
            }
        }
    }

    /// The next event, or `None` when more bytes are needed (or everything is reported).
    pub fn next_event(&mut self) -> Option<VnEvent> {
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
                self.sb.flush_end = None;
                if self.sb.unprocessed().is_empty() {
                    return None;
                }
                continue;
            }
            if garbage_len >= MAX_GARBAGE_RUN {
                return Some(self.emit_garbage());
            }
            let room = MAX_GARBAGE_RUN - garbage_len;
            let skip = (0..avail.len().min(room))
                .find(|&p| may_start(&avail[p..], eos))
                .unwrap_or(room.min(avail.len()));
            if skip > 0 {
                self.sb.garbage_len += skip;
                continue;
            }
            if garbage_len > 0 {
                return Some(self.emit_garbage());
            }
            return match classify(avail, eos) {
                Verdict::NeedMore => None,
                Verdict::Good(g) => Some(self.emit_good(g)),
                Verdict::Truncated(n) => Some(self.emit_rejected(n, RejectReason::Truncated)),
                Verdict::BadChecksum(n) => Some(self.emit_rejected(n, RejectReason::BadChecksum)),
                Verdict::Malformed(n) => Some(self.emit_rejected(n, RejectReason::Malformed)),
            };
        }
    }
}

/// `rest` starts with 0xFA and a possible group byte, or with `$VN` (as far as it goes; a
/// start cut by the end of what is buffered may still become one unless the stream ended).
fn may_start(rest: &[u8], eos: bool) -> bool {
    match rest[0] {
        SYNC => match rest.get(1) {
            Some(&g) => g != 0 && g & 0x80 == 0,
            None => !eos,
        },
        b'$' => {
            let n = rest.len().min(3);
            rest[..n] == b"$VN"[..n] && (n == 3 || !eos)
        }
        _ => false,
    }
}

/// Where the candidate at the head of `rest` ends (`may_start(rest)` holds).
fn extent(rest: &[u8]) -> Extent {
    if rest[0] == SYNC {
        return match binary::header(rest) {
            Ok(None) => Extent::NeedMore,
            Ok(Some((_, len))) => Extent::Len(len),
            Err(VnError::BadGroups(g)) if g == 0 || g & 0x80 != 0 => Extent::Unframeable(2),
            Err(_) => Extent::Unframeable(2 + 2 * rest[1].count_ones() as usize),
        };
    }
    let n = rest.len().min(3);
    if rest[..n] != b"$VN"[..n] {
        return Extent::Unframeable(1);
    }
    let reach = rest.len().min(MAX_SENTENCE_LEN);
    match rest[..reach].iter().position(|&b| b == b'\n') {
        Some(i) => Extent::Len(i + 1),
        None if rest.len() >= MAX_SENTENCE_LEN => Extent::Unframeable(MAX_SENTENCE_LEN),
        None => Extent::NeedMore,
    }
}

fn check(candidate: &[u8]) -> Result<Good, VnError> {
    if candidate[0] == SYNC {
        BinaryMessage::parse(candidate).map(Good::Binary)
    } else {
        Sentence::parse(candidate).map(Good::Ascii)
    }
}

/// The candidate at the head of `avail` (which may start one).
fn classify(avail: &[u8], eos: bool) -> Verdict {
    let salvage = |avail: &[u8]| match find_inner(avail, avail.len(), true) {
        Inner::Found(q) => Verdict::Truncated(q),
        _ => Verdict::Truncated(avail.len()),
    };
    let len = match extent(avail) {
        Extent::NeedMore if eos => return salvage(avail),
        Extent::NeedMore => return Verdict::NeedMore,
        Extent::Unframeable(n) => {
            return match find_inner(avail, n, eos) {
                Inner::NeedMore => Verdict::NeedMore,
                Inner::Found(q) => Verdict::Truncated(q),
                Inner::None => Verdict::Malformed(n.min(avail.len())),
            };
        }
        Extent::Len(len) => len,
    };
    let Some(candidate) = avail.get(..len) else {
        return if eos {
            salvage(avail)
        } else {
            Verdict::NeedMore
        };
    };
    let error = match check(candidate) {
        Ok(good) => return Verdict::Good(good),
        Err(e) => e,
    };
    match find_inner(avail, len, eos) {
        Inner::NeedMore => Verdict::NeedMore,
        Inner::Found(q) => Verdict::Truncated(q),
        Inner::None => match error {
            VnError::BadCrc(_) | VnError::BadChecksum { .. } => Verdict::BadChecksum(len),
            _ => Verdict::Malformed(len),
        },
    }
}

/// The first good message or sentence starting at 1..span. Without `eos`, a start whose extent
/// is not fully buffered yet means waiting (it may be the good one).
fn find_inner(avail: &[u8], span: usize, eos: bool) -> Inner {
    for q in 1..span.min(avail.len()) {
        let rest = &avail[q..];
        if !may_start(rest, eos) {
            continue;
        }
        let len = match extent(rest) {
            Extent::NeedMore if eos => continue,
            Extent::NeedMore => return Inner::NeedMore,
            Extent::Unframeable(_) => continue,
            Extent::Len(len) => len,
        };
        match rest.get(..len) {
            Some(candidate) => {
                if check(candidate).is_ok() {
                    return Inner::Found(q);
                }
            }
            None if eos => {}
            None => return Inner::NeedMore,
        }
    }
    Inner::None
}
