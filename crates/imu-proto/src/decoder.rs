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

/// Byte buffer shared by both decoders: reported prefix, pending garbage run, unprocessed rest.
///
/// Layout of `buf`: `[..start]` already reported (dropped on compaction), `[start..start +
/// garbage_len]` classified as garbage but not yet reported, `[start + garbage_len..]` not yet
/// classified.
#[derive(Debug, Clone, Default)]
struct StreamBuf {
    buf: Vec<u8>,
    start: usize,
    garbage_len: usize,
    /// Stream offset of `buf[0]`.
    base_offset: u64,
    /// While flushing: stream offset where the flushed stream "ends".
    flush_end: Option<u64>,
}

impl StreamBuf {
    fn push(&mut self, bytes: &[u8]) {
        // Drop the reported prefix once it is at least half the buffer: amortised O(1) per byte.
        if self.start > 0 && self.start >= self.buf.len() - self.start {
            self.buf.drain(..self.start);
            self.base_offset += self.start as u64;
            self.start = 0;
        }
        self.buf.extend_from_slice(bytes);
    }

    fn eos(&self) -> bool {
        self.flush_end.is_some()
    }

    fn end(&self) -> usize {
        match self.flush_end {
            Some(end) => usize::try_from(end.saturating_sub(self.base_offset))
                .unwrap_or(usize::MAX)
                .min(self.buf.len()),
            None => self.buf.len(),
        }
    }

    /// Bytes not yet classified (up to the flush point while flushing).
    fn unprocessed(&self) -> &[u8] {
        let from = self.start + self.garbage_len;
        self.buf.get(from..self.end()).unwrap_or(&[])
    }

    fn offset(&self) -> u64 {
        self.base_offset + self.start as u64
    }

    fn pending_len(&self) -> usize {
        self.buf.len() - self.start
    }

    fn after_consume(&mut self) {
        if self.start == self.buf.len() {
            self.base_offset += self.start as u64;
            self.buf.clear();
            self.start = 0;
        }
    }

    /// Takes the pending garbage run out. Returns its offset and bytes.
    fn take_garbage(&mut self) -> (u64, Vec<u8>) {
        let offset = self.offset();
        let bytes = self.buf[self.start..self.start + self.garbage_len].to_vec();
        self.start += self.garbage_len;
        self.garbage_len = 0;
        self.after_consume();
        (offset, bytes)
    }

    /// Consumes `n` unprocessed bytes (only valid with no pending garbage) and hands them to `f`.
    fn consume<T>(&mut self, n: usize, f: impl FnOnce(u64, &[u8]) -> T) -> T {
        debug_assert_eq!(self.garbage_len, 0);
        let offset = self.offset();
        let n = n.min(self.buf.len() - self.start);
        let out = f(offset, &self.buf[self.start..self.start + n]);
        self.start += n;
        self.after_consume();
        out
    }

    fn flush(&mut self) {
        self.flush_end = Some(self.base_offset + self.buf.len() as u64);
    }
}

/// Result of looking at the candidate frame at the head of the unprocessed bytes.
enum Verdict {
    NeedMore,
    Frame(Reply),
    Truncated(usize),
    BadChecksum(usize),
    Malformed(usize),
}

/// Result of looking for a valid frame inside a failed candidate.
enum Inner {
    NeedMore,
    Found(usize),
    None,
}

/// Reply length for each accepted header byte; 0 = not accepted.
type LenTable = [u8; 256];

fn len_table(codes: &[u8]) -> LenTable {
    let mut table = [0u8; 256];
    let codes = if codes.is_empty() {
        &KNOWN_REPLY_CODES[..]
    } else {
        codes
    };
    for &code in codes {
        if let Some(len) = reply_len_for_code(code) {
            table[usize::from(code)] = len as u8;
        }
    }
    table
}

/// Looks for the first valid frame starting at 1..span. Without `eos`, a candidate that is not
/// fully buffered yet means we must wait (it might be the valid one).
fn find_inner(table: &LenTable, avail: &[u8], span: usize, eos: bool) -> Inner {
    for q in 1..span.min(avail.len()) {
        let len = usize::from(table[usize::from(avail[q])]);
        if len == 0 {
            continue;
        }
        match avail.get(q..q + len) {
            Some(candidate) => {
                if crate::reply::check_frame(candidate).is_ok() {
                    return Inner::Found(q);
                }
            }
            None if eos => {}
            None => return Inner::NeedMore,
        }
    }
    Inner::None
}

fn classify(table: &LenTable, avail: &[u8], len: usize, eos: bool) -> Verdict {
    let Some(candidate) = avail.get(..len) else {
        if !eos {
            return Verdict::NeedMore;
        }
        // End of stream inside the candidate: it can never complete. Salvage a valid frame
        // inside it if there is one, else the whole rest is one truncated frame.
        return match find_inner(table, avail, avail.len(), true) {
            Inner::Found(q) => Verdict::Truncated(q),
            _ => Verdict::Truncated(avail.len()),
        };
    };
    let error = match Reply::decode(candidate) {
        Ok(reply) => return Verdict::Frame(reply),
        Err(e) => e,
    };
    // The candidate failed. If a valid frame starts inside it, the candidate was cut short
    // (bytes lost on the line) and the valid frame is where the stream really continues.
    // Otherwise no valid frame starts anywhere in the candidate's span, so rejecting the whole
    // span loses nothing that skipping byte by byte would have recovered.
    match find_inner(table, avail, len, eos) {
        Inner::NeedMore => Verdict::NeedMore,
        Inner::Found(q) => Verdict::Truncated(q),
        Inner::None => match error {
            FrameError::BadChecksum { .. } => Verdict::BadChecksum(len),
            _ => Verdict::Malformed(len),
        },
    }
}

/// Host-side streaming decoder of device replies.
///
/// At the head of the stream: a byte that is not an accepted header is garbage. An accepted
/// header with reply length L waits for L bytes, then:
/// - good checksum (and fixed bytes): a `Frame`, L bytes consumed;
/// - otherwise, if a valid frame starts inside the candidate (offsets 1..L): `Rejected {
///   Truncated }` with the bytes up to that start, and decoding resumes there;
/// - otherwise `Rejected { BadChecksum }` (or `Malformed`) with the L bytes. This is equivalent
///   to skipping one byte at a time, because every start inside the span was just checked.
///
/// The checksum is the only arbiter: once in sync, header-like bytes inside good frames are
/// never looked at, and a 0x10 continuous-mode confirmation is just another 7-byte frame.
/// While out of sync, a 16-bit checksum lets a false frame through with probability about
/// 2^-16 per header-like byte, which is the protocol's limit, not the decoder's.
///
/// A polling host that waits for one reply should call [`flush`](Self::flush) on a read
/// timeout: a cut-off frame at the end of the stream is otherwise held until more bytes come.
///
/// ```
/// use imu_proto::decoder::{DecodeEvent, ReplyDecoder, RejectReason};
/// use imu_proto::reply::Reply;
/// let mut d = ReplyDecoder::new();
/// d.push(&[0xAA, 0x07, 0x12, 0x34, 0x00, 0x42, 0x12, 0x7D]);
/// assert!(matches!(d.next_event(), Some(DecodeEvent::Rejected { reason: RejectReason::Garbage, .. })));
/// match d.next_event() {
///     Some(DecodeEvent::Frame { reply, offset, .. }) => {
///         assert_eq!(reply, Reply::Temperature { raw: 0x1234, ticks: 0x42 });
///         assert_eq!(offset, 1);
///     }
///     other => panic!("{other:?}"),
/// }
/// assert_eq!(d.next_event(), None);
/// assert_eq!(d.stats().resyncs, 1);
/// ```
#[derive(Debug, Clone)]
pub struct ReplyDecoder {
    sb: StreamBuf,
    table: LenTable,
    lost_sync: bool,
    stats: DecoderStats,
}

impl Default for ReplyDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl ReplyDecoder {
    /// A decoder that accepts every known reply code as a frame start.
    pub fn new() -> Self {
        Self {
            sb: StreamBuf::default(),
            table: len_table(&[]),
            lost_sync: false,
            stats: DecoderStats::default(),
        }
    }

    /// Restricts which header codes may start a frame (the host knows what it asked for).
    /// An empty slice means every known code. Unknown codes in `codes` are ignored, so a list of
    /// only unknown codes accepts nothing. Applies to bytes not yet classified.
    pub fn set_expected(&mut self, codes: &[u8]) {
        self.table = len_table(codes);
    }

    /// Appends bytes received from the device. Cheap: the work happens in
    /// [`next_event`](Self::next_event).
    pub fn push(&mut self, bytes: &[u8]) {
        self.stats.bytes_in += bytes.len() as u64;
        self.sb.push(bytes);
    }

    /// Marks the end of the stream so far: the next calls to [`next_event`](Self::next_event)
    /// report every pending byte (incomplete frames as `Truncated`, garbage as `Garbage`)
    /// instead of waiting for more. Decoding goes on normally for bytes pushed afterwards.
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

    fn emit_garbage(&mut self) -> DecodeEvent {
        let (offset, bytes) = self.sb.take_garbage();
        self.stats.garbage_bytes += bytes.len() as u64;
        self.stats.rejected_bytes += bytes.len() as u64;
        self.lost_sync = true;
        DecodeEvent::Rejected {
            bytes,
            offset,
            reason: RejectReason::Garbage,
        }
    }

    fn emit_rejected(&mut self, n: usize, reason: RejectReason) -> DecodeEvent {
        let (offset, bytes) = self.sb.consume(n, |offset, b| (offset, b.to_vec()));
        self.stats.rejected_bytes += bytes.len() as u64;
        match reason {
            RejectReason::BadChecksum => self.stats.checksum_failures += 1,
            RejectReason::Malformed => self.stats.malformed_frames += 1,
            RejectReason::Truncated => self.stats.truncated_frames += 1,
            RejectReason::Garbage => self.stats.garbage_bytes += bytes.len() as u64,
        }
        self.lost_sync = true;
        DecodeEvent::Rejected {
            bytes,
            offset,
            reason,
        }
    }

    /// The next event, or `None` when more bytes are needed (or everything is reported).
    pub fn next_event(&mut self) -> Option<DecodeEvent> {
        loop {
            let eos = self.sb.eos();
            let garbage_len = self.sb.garbage_len;
            let avail = self.sb.unprocessed();
            let Some(&header) = avail.first() else {
                if eos {
                    if garbage_len > 0 {
                        return Some(self.emit_garbage());
                    }
                    // Flush complete; bytes pushed after the flush are decoded normally.
                    self.sb.flush_end = None;
                    if self.sb.unprocessed().is_empty() {
                        return None;
                    }
                    continue;
                }
                return None;
            };
            if garbage_len >= MAX_GARBAGE_RUN {
                return Some(self.emit_garbage());
            }
            let len = usize::from(self.table[usize::from(header)]);
            if len == 0 {
                // Hot path over garbage: jump to the next accepted header in one scan.
                let room = MAX_GARBAGE_RUN - garbage_len;
                let table = &self.table;
                let skip = avail
                    .iter()
                    .take(room)
                    .position(|&b| table[usize::from(b)] != 0)
                    .unwrap_or(room.min(avail.len()));
                self.sb.garbage_len += skip;
                continue;
            }
            // An accepted header ends any garbage run, whatever the candidate turns out to be.
            if garbage_len > 0 {
                return Some(self.emit_garbage());
            }
            return match classify(&self.table, avail, len, eos) {
                Verdict::NeedMore => None,
                Verdict::Frame(reply) => {
                    let (offset, bytes) = self.sb.consume(len, |o, b| (o, FrameBytes::new(b)));
                    self.stats.frames += 1;
                    self.stats.frame_bytes += bytes.len() as u64;
                    if self.lost_sync {
                        self.stats.resyncs += 1;
                        self.lost_sync = false;
                    }
                    Some(DecodeEvent::Frame {
                        reply,
                        bytes,
                        offset,
                    })
                }
                Verdict::Truncated(n) => Some(self.emit_rejected(n, RejectReason::Truncated)),
                Verdict::BadChecksum(n) => Some(self.emit_rejected(n, RejectReason::BadChecksum)),
                Verdict::Malformed(n) => Some(self.emit_rejected(n, RejectReason::Malformed)),
            };
        }
    }
}

/// Why bytes were rejected by the [`CommandDecoder`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CommandRejectReason {
    /// Bytes that are not a known command code (one event per contiguous run, at most
    /// [`MAX_GARBAGE_RUN`] bytes each).
    UnknownCode,
    /// A known code followed by a wrong fixed byte; only the code byte is rejected and decoding
    /// resumes right after it.
    BadArgument,
    /// A command cut short by the end of the stream ([`CommandDecoder::flush`]).
    Truncated,
}

/// One thing the [`CommandDecoder`] found in the stream.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CommandEvent {
    /// A well-formed command.
    Command(Command),
    /// Bytes that are not (part of) a well-formed command.
    Rejected {
        /// The rejected bytes.
        bytes: Vec<u8>,
        /// Stream byte offset of the first rejected byte.
        offset: u64,
        /// Why they were rejected.
        reason: CommandRejectReason,
    },
}

/// Counters of a [`CommandDecoder`]. Byte counters are updated when the event is emitted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CommandDecoderStats {
    /// Well-formed commands emitted.
    pub commands: u64,
    /// Bytes pushed.
    pub bytes_in: u64,
    /// Bytes of emitted commands.
    pub command_bytes: u64,
    /// Bytes emitted in `Rejected` events of any reason.
    pub rejected_bytes: u64,
    /// Bytes rejected as unknown codes.
    pub unknown_bytes: u64,
    /// Code bytes rejected because a fixed argument byte was wrong.
    pub bad_arguments: u64,
    /// Commands cut short by the end of the stream.
    pub truncated_commands: u64,
}

/// Device-side streaming decoder of host commands (used by the simulator).
///
/// Knows each command's length and checks the fixed argument bytes as soon as they arrive
/// (`10 00`, `0F/11 C1 C3 C5`, `29 71 .. .. .. .. AA`); a wrong one rejects the code byte alone
/// and decoding rescans from the next byte. Commands carry no checksum, so a garbage byte that
/// happens to be a command code is decoded as a command: that is the protocol.
///
/// ```
/// use imu_proto::command::Command;
/// use imu_proto::decoder::{CommandDecoder, CommandEvent};
/// let mut d = CommandDecoder::new();
/// d.push(&[0x10, 0x00, 0x02, 0x07]);
/// assert_eq!(d.next_event(), Some(CommandEvent::Command(Command::SetContinuous { command: 2 })));
/// assert_eq!(d.next_event(), Some(CommandEvent::Command(Command::Temperature)));
/// assert_eq!(d.next_event(), None);
/// ```
#[derive(Debug, Clone, Default)]
pub struct CommandDecoder {
    sb: StreamBuf,
    stats: CommandDecoderStats,
}

impl CommandDecoder {
    /// A fresh decoder.
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends bytes received from the host.
    pub fn push(&mut self, bytes: &[u8]) {
        self.stats.bytes_in += bytes.len() as u64;
        self.sb.push(bytes);
    }

    /// Marks the end of the stream so far; see [`ReplyDecoder::flush`].
    pub fn flush(&mut self) {
        self.sb.flush();
    }

    /// Bytes pushed but not yet reported in any event.
    pub fn pending_len(&self) -> usize {
        self.sb.pending_len()
    }

    /// The counters so far.
    pub fn stats(&self) -> CommandDecoderStats {
        self.stats
    }

    fn emit_unknown(&mut self) -> CommandEvent {
        let (offset, bytes) = self.sb.take_garbage();
        self.stats.unknown_bytes += bytes.len() as u64;
        self.stats.rejected_bytes += bytes.len() as u64;
        CommandEvent::Rejected {
            bytes,
            offset,
            reason: CommandRejectReason::UnknownCode,
        }
    }

    fn emit_rejected(&mut self, n: usize, reason: CommandRejectReason) -> CommandEvent {
        let (offset, bytes) = self.sb.consume(n, |offset, b| (offset, b.to_vec()));
        self.stats.rejected_bytes += bytes.len() as u64;
        match reason {
            CommandRejectReason::BadArgument => self.stats.bad_arguments += 1,
            CommandRejectReason::Truncated => self.stats.truncated_commands += 1,
            CommandRejectReason::UnknownCode => self.stats.unknown_bytes += bytes.len() as u64,
        }
        CommandEvent::Rejected {
            bytes,
            offset,
            reason,
        }
    }

    /// The host went quiet in the middle of a command: rejects the incomplete command's code byte
    /// (as [`CommandRejectReason::Truncated`]) so that the bytes after it are decoded afresh.
    ///
    /// Commands carry no checksum, so a stray byte that looks like the start of a long command
    /// (`0x29` takes 7 bytes) would otherwise swallow the next real command while the host waits
    /// for its reply. A device times such partial input out; call this after a quiet period.
    /// Returns `None` when no partial command is pending.
    pub fn expire_partial(&mut self) -> Option<CommandEvent> {
        if self.sb.garbage_len > 0 {
            return None;
        }
        let avail = self.sb.unprocessed();
        let len = command_len_for_code(*avail.first()?)?;
        if avail.len() >= len {
            return None;
        }
        Some(self.emit_rejected(1, CommandRejectReason::Truncated))
    }

    /// The next event, or `None` when more bytes are needed (or everything is reported).
    pub fn next_event(&mut self) -> Option<CommandEvent> {
        loop {
            let eos = self.sb.eos();
            let garbage_len = self.sb.garbage_len;
            let avail = self.sb.unprocessed();
            let Some(&code) = avail.first() else {
                if eos {
                    if garbage_len > 0 {
                        return Some(self.emit_unknown());
                    }
                    self.sb.flush_end = None;
                    if self.sb.unprocessed().is_empty() {
                        return None;
                    }
                    continue;
                }
                return None;
            };
            if garbage_len >= MAX_GARBAGE_RUN {
                return Some(self.emit_unknown());
            }
            let Some(len) = command_len_for_code(code) else {
                let room = MAX_GARBAGE_RUN - garbage_len;
                let skip = avail
                    .iter()
                    .take(room)
                    .position(|&b| command_len_for_code(b).is_some())
                    .unwrap_or(room.min(avail.len()));
                self.sb.garbage_len += skip;
                continue;
            };
            if garbage_len > 0 {
                return Some(self.emit_unknown());
            }
            // Check the fixed bytes we already have, so a bad one is rejected without waiting.
            let have = len.min(avail.len());
            let bad_fixed_byte =
                (1..have).any(|i| fixed_command_byte(code, i).is_some_and(|want| avail[i] != want));
            if bad_fixed_byte {
                return Some(self.emit_rejected(1, CommandRejectReason::BadArgument));
            }
            if avail.len() < len {
                if eos {
                    let n = avail.len();
                    return Some(self.emit_rejected(n, CommandRejectReason::Truncated));
                }
                return None;
            }
            return match Command::decode(&avail[..len]) {
                Ok(command) => {
                    self.sb.consume(len, |_, _| ());
                    self.stats.commands += 1;
                    self.stats.command_bytes += len as u64;
                    Some(CommandEvent::Command(command))
                }
                // Unreachable (length and fixed bytes were checked), but never panic.
                Err(_) => Some(self.emit_rejected(1, CommandRejectReason::BadArgument)),
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reply::Filter;

    #[test]
    fn expired_partial_command_releases_the_command_inside_it() {
        let mut d = CommandDecoder::new();
        // A stray 0x29 (write EEPROM, 7 bytes) followed by a real poll 0x01.
        d.push(&[0x29, 0x71, 0x00, 0x01]);
        assert_eq!(
            d.next_event(),
            None,
            "waits for the rest of the 0x29 command"
        );
        assert!(matches!(
            d.expire_partial(),
            Some(CommandEvent::Rejected { reason: CommandRejectReason::Truncated, ref bytes, .. }) if bytes == &[0x29]
        ));
        // 0x71 and 0x00 are unknown codes, then the poll is decoded.
        let events: Vec<_> = std::iter::from_fn(|| d.next_event()).collect();
        assert_eq!(
            events.last(),
            Some(&CommandEvent::Command(Command::RawSensorBits))
        );
        assert_eq!(d.expire_partial(), None);
        assert_eq!(d.stats().truncated_commands, 1);
    }

    fn drain(d: &mut ReplyDecoder) -> Vec<DecodeEvent> {
        std::iter::from_fn(|| d.next_event()).collect()
    }

    fn temp(raw: u16, ticks: u16) -> Reply {
        Reply::Temperature { raw, ticks }
    }

    fn euler(ticks: u16) -> Reply {
        Reply::Euler {
            kind: Filter::Stabilized,
            rpy: [0x0E0E, 0x0D0D, 0x0101],
            ticks,
        }
    }

    fn kinds(events: &[DecodeEvent]) -> Vec<(u64, usize, Option<RejectReason>)> {
        events
            .iter()
            .map(|e| match e {
                DecodeEvent::Frame { offset, bytes, .. } => (*offset, bytes.len(), None),
                DecodeEvent::Rejected {
                    offset,
                    bytes,
                    reason,
                } => (*offset, bytes.len(), Some(*reason)),
            })
            .collect()
    }

    #[test]
    fn clean_stream_byte_by_byte() {
        let replies = [temp(1, 2), euler(3), temp(0xFFFF, 0x0707)];
        let stream: Vec<u8> = replies.iter().flat_map(Reply::to_bytes).collect();
        let mut d = ReplyDecoder::new();
        let mut got = Vec::new();
        for b in &stream {
            d.push(std::slice::from_ref(b));
            got.extend(drain(&mut d));
        }
        let decoded: Vec<Reply> = got
            .iter()
            .map(|e| match e {
                DecodeEvent::Frame { reply, .. } => *reply,
                other => panic!("unexpected {other:?}"),
            })
            .collect();
        assert_eq!(decoded, replies);
        let s = d.stats();
        assert_eq!((s.frames, s.resyncs, s.rejected_bytes), (3, 0, 0));
        assert_eq!(s.bytes_in, stream.len() as u64);
        assert_eq!(d.pending_len(), 0);
    }

    #[test]
    fn garbage_then_frame_is_one_run_and_one_resync() {
        let mut d = ReplyDecoder::new();
        d.push(&[0x00, 0x55, 0xAA]);
        d.push(&temp(5, 6).to_bytes());
        let ev = drain(&mut d);
        assert_eq!(
            kinds(&ev),
            vec![(0, 3, Some(RejectReason::Garbage)), (3, 7, None)]
        );
        assert_eq!(d.stats().garbage_bytes, 3);
        assert_eq!(d.stats().resyncs, 1);
    }

    #[test]
    fn garbage_is_held_until_sync_or_flush() {
        let mut d = ReplyDecoder::new();
        d.push(&[0x00, 0x55]);
        assert_eq!(d.next_event(), None);
        assert_eq!(d.pending_len(), 2);
        d.push(&[0xAA]);
        assert_eq!(d.next_event(), None);
        d.flush();
        assert_eq!(
            d.next_event(),
            Some(DecodeEvent::Rejected {
                bytes: vec![0x00, 0x55, 0xAA],
                offset: 0,
                reason: RejectReason::Garbage
            })
        );
        assert_eq!(d.next_event(), None);
        assert_eq!(d.pending_len(), 0);
    }

    #[test]
    fn truncated_frame_before_good_frame() {
        // An euler frame (11 bytes) loses its last 4 bytes on the line; the next frame is intact.
        let mut stream = euler(1).to_bytes();
        stream.truncate(7);
        let good = temp(0x1234, 0x42).to_bytes();
        stream.extend_from_slice(&good);
        let mut d = ReplyDecoder::new();
        d.push(&stream);
        // Header-like bytes inside the cut frame start candidates longer than what follows,
        // so without an end of stream the decoder waits for more bytes instead of guessing.
        assert_eq!(d.next_event(), None);
        d.flush();
        let ev = drain(&mut d);
        assert_eq!(
            kinds(&ev),
            vec![(0, 7, Some(RejectReason::Truncated)), (7, 7, None)]
        );
        assert_eq!(d.stats().truncated_frames, 1);
        assert_eq!(d.stats().checksum_failures, 0);
        assert_eq!(d.stats().resyncs, 1);
    }

    #[test]
    fn corrupted_frame_is_bad_checksum_and_next_frame_survives() {
        let mut stream = euler(1).to_bytes();
        stream[4] ^= 0x40;
        stream.extend_from_slice(&euler(2).to_bytes());
        let mut d = ReplyDecoder::new();
        d.push(&stream);
        d.flush();
        let ev = drain(&mut d);
        assert_eq!(
            kinds(&ev),
            vec![(0, 11, Some(RejectReason::BadChecksum)), (11, 11, None)]
        );
        assert_eq!(d.stats().checksum_failures, 1);
    }

    #[test]
    fn waits_for_lookahead_before_calling_truncation() {
        // A failed candidate with a header-like byte inside whose own frame is not complete yet:
        // the decoder must wait rather than guess.
        let mut stream = euler(1).to_bytes();
        stream[10] ^= 1; // bad checksum
        stream[8] = 0x06; // a 5-byte candidate starting at 8 needs 13 bytes buffered
        let mut d = ReplyDecoder::new();
        d.push(&stream);
        assert_eq!(d.next_event(), None);
        d.flush();
        let ev = drain(&mut d);
        assert_eq!(kinds(&ev), vec![(0, 11, Some(RejectReason::BadChecksum))]);
    }

    #[test]
    fn flush_reports_partial_frame_as_truncated() {
        let bytes = euler(9).to_bytes();
        let mut d = ReplyDecoder::new();
        d.push(&bytes[..6]);
        assert_eq!(d.next_event(), None);
        d.flush();
        let ev = drain(&mut d);
        assert_eq!(kinds(&ev), vec![(0, 6, Some(RejectReason::Truncated))]);
        // decoding continues after a flush
        d.push(&bytes);
        let ev = drain(&mut d);
        assert_eq!(kinds(&ev), vec![(6, 11, None)]);
    }

    #[test]
    fn expected_codes_restrict_frame_starts() {
        let mut d = ReplyDecoder::new();
        d.set_expected(&[0x07]);
        let mut stream = euler(1).to_bytes();
        stream.extend_from_slice(&temp(1, 1).to_bytes());
        d.push(&stream);
        let ev = drain(&mut d);
        assert_eq!(
            kinds(&ev),
            vec![(0, 11, Some(RejectReason::Garbage)), (11, 7, None)]
        );
    }

    #[test]
    fn malformed_continuous_reply() {
        // 10 01 02 00 00 | checksum 0x10 + 0x0102 + 0x0000 = 0x0112
        let mut d = ReplyDecoder::new();
        d.push(&[0x10, 0x01, 0x02, 0x00, 0x00, 0x01, 0x12]);
        d.flush();
        let ev = drain(&mut d);
        assert_eq!(kinds(&ev), vec![(0, 7, Some(RejectReason::Malformed))]);
        assert_eq!(d.stats().malformed_frames, 1);
    }

    #[test]
    fn long_garbage_is_split_and_memory_stays_bounded() {
        let mut d = ReplyDecoder::new();
        let junk = vec![0x00u8; 10 * MAX_GARBAGE_RUN + 5];
        for chunk in junk.chunks(333) {
            d.push(chunk);
            for ev in drain(&mut d) {
                assert!(ev.bytes().len() <= MAX_GARBAGE_RUN);
            }
            assert!(d.pending_len() <= MAX_GARBAGE_RUN + 333);
            assert!(d.sb.buf.capacity() <= 4 * (MAX_GARBAGE_RUN + 333));
        }
        d.flush();
        drain(&mut d);
        assert_eq!(d.stats().garbage_bytes, junk.len() as u64);
    }

    fn drain_cmd(d: &mut CommandDecoder) -> Vec<CommandEvent> {
        std::iter::from_fn(|| d.next_event()).collect()
    }

    #[test]
    fn command_bad_key_rejects_only_the_code() {
        let mut d = CommandDecoder::new();
        // 0F C1 01: bad tare key; 01 is then a raw-sensor-bits command.
        d.push(&[0x0F, 0xC1, 0x01]);
        let ev = drain_cmd(&mut d);
        assert_eq!(
            ev,
            vec![
                CommandEvent::Rejected {
                    bytes: vec![0x0F],
                    offset: 0,
                    reason: CommandRejectReason::BadArgument
                },
                CommandEvent::Rejected {
                    bytes: vec![0xC1],
                    offset: 1,
                    reason: CommandRejectReason::UnknownCode
                },
                CommandEvent::Command(Command::RawSensorBits),
            ]
        );
        assert_eq!(d.stats().bad_arguments, 1);
        assert_eq!(d.stats().unknown_bytes, 1);
    }

    #[test]
    fn command_partial_waits_then_truncates_on_flush() {
        let mut d = CommandDecoder::new();
        d.push(&[0x29, 0x71, 0x00]);
        assert_eq!(d.next_event(), None);
        d.push(&[0x82, 0x27, 0x10, 0xAA]);
        assert_eq!(
            d.next_event(),
            Some(CommandEvent::Command(Command::WriteEeprom {
                address: 130,
                value: 10_000
            }))
        );
        d.push(&[0x28, 0x00]);
        d.flush();
        assert_eq!(
            d.next_event(),
            Some(CommandEvent::Rejected {
                bytes: vec![0x28, 0x00],
                offset: 7,
                reason: CommandRejectReason::Truncated
            })
        );
        assert_eq!(d.next_event(), None);
        assert_eq!(d.stats().truncated_commands, 1);
        assert_eq!(d.stats().command_bytes, 7);
    }
}
