//! The host side: the streaming decoder of device replies.

use super::*;

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
    pub(super) sb: StreamBuf,
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

    pub(super) fn emit_garbage(&mut self) -> DecodeEvent {
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

    pub(super) fn emit_rejected(&mut self, n: usize, reason: RejectReason) -> DecodeEvent {
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
