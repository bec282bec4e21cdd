//! The byte buffer both decoders share (reported prefix, pending garbage, the frame being
//! assembled) and the classification of a candidate frame by its length table and checksum.

use super::*;

/// Byte buffer shared by both decoders: reported prefix, pending garbage run, unprocessed rest.
///
/// Layout of `buf`: `[..start]` already reported (dropped on compaction), `[start..start +
/// garbage_len]` classified as garbage but not yet reported, `[start + garbage_len..]` not yet
/// classified.
#[derive(Debug, Clone, Default)]
pub(crate) struct StreamBuf {
    pub(crate) buf: Vec<u8>,
    pub(crate) start: usize,
    pub(crate) garbage_len: usize,
    /// Stream offset of `buf[0]`.
    pub(crate) base_offset: u64,
    /// While flushing: stream offset where the flushed stream "ends".
    pub(crate) flush_end: Option<u64>,
}

impl StreamBuf {
    pub(crate) fn push(&mut self, bytes: &[u8]) {
        // Drop the reported prefix once it is at least half the buffer: amortised O(1) per byte.
        if self.start > 0 && self.start >= self.buf.len() - self.start {
            self.buf.drain(..self.start);
            self.base_offset += self.start as u64;
            self.start = 0;
        }
        self.buf.extend_from_slice(bytes);
    }

    pub(crate) fn eos(&self) -> bool {
        self.flush_end.is_some()
    }

    pub(crate) fn end(&self) -> usize {
        match self.flush_end {
            Some(end) => usize::try_from(end.saturating_sub(self.base_offset))
                .unwrap_or(usize::MAX)
                .min(self.buf.len()),
            None => self.buf.len(),
        }
    }

    /// Bytes not yet classified (up to the flush point while flushing).
    pub(crate) fn unprocessed(&self) -> &[u8] {
        let from = self.start + self.garbage_len;
        self.buf.get(from..self.end()).unwrap_or(&[])
    }

    pub(crate) fn offset(&self) -> u64 {
        self.base_offset + self.start as u64
    }

    pub(crate) fn pending_len(&self) -> usize {
        self.buf.len() - self.start
    }

    pub(crate) fn after_consume(&mut self) {
        if self.start == self.buf.len() {
            self.base_offset += self.start as u64;
            self.buf.clear();
            self.start = 0;
        }
    }

    /// Takes the pending garbage run out. Returns its offset and bytes.
    pub(crate) fn take_garbage(&mut self) -> (u64, Vec<u8>) {
        let offset = self.offset();
        let bytes = self.buf[self.start..self.start + self.garbage_len].to_vec();
        self.start += self.garbage_len;
        self.garbage_len = 0;
        self.after_consume();
        (offset, bytes)
    }

    /// Consumes `n` unprocessed bytes (only valid with no pending garbage) and hands them to `f`.
    pub(crate) fn consume<T>(&mut self, n: usize, f: impl FnOnce(u64, &[u8]) -> T) -> T {
        debug_assert_eq!(self.garbage_len, 0);
        let offset = self.offset();
        let n = n.min(self.buf.len() - self.start);
        let out = f(offset, &self.buf[self.start..self.start + n]);
        self.start += n;
        self.after_consume();
        out
    }

    pub(crate) fn flush(&mut self) {
        self.flush_end = Some(self.base_offset + self.buf.len() as u64);
    }
}

/// Result of looking at the candidate frame at the head of the unprocessed bytes.
pub(super) enum Verdict {
    NeedMore,
    Frame(Reply),
    Truncated(usize),
    BadChecksum(usize),
    Malformed(usize),
}

/// Result of looking for a valid frame inside a failed candidate.
pub(super) enum Inner {
    NeedMore,
    Found(usize),
    None,
}

/// Reply length for each accepted header byte; 0 = not accepted.
pub(super) type LenTable = [u8; 256];

pub(super) fn len_table(codes: &[u8]) -> LenTable {
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
pub(super) fn find_inner(table: &LenTable, avail: &[u8], span: usize, eos: bool) -> Inner {
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

pub(super) fn classify(table: &LenTable, avail: &[u8], len: usize, eos: bool) -> Verdict {
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
