//! MCAP's record layer, read front to back and tolerant of damage: the records of the data
//! section (and the summary after it) one at a time, chunks expanded into the records they hold,
//! every length checked against what really is there.
//!
//! Why not the `mcap` crate's sans-IO `LinearReader`, which this replaced: fuzzing found that a
//! record claiming more bytes than its uncompressed chunk holds overflows its bookkeeping (a panic
//! in builds with overflow checks, a wrapped count that reads on past the chunk without them), and
//! a record cut off at the end of a file made it zero-fill the whole claimed length first. The
//! record framing is small (an opcode and a length before every record, the chunk header's six
//! fields); the records' bodies are still parsed by `mcap::parse_record`.
//!
//! Memory stays bounded by one chunk (its compressed bytes, and its records when they are
//! checked against the chunk's CRC before any is delivered): a length is never allocated before
//! its bytes have been read, so a damaged length field in a small file costs little. A chunk cut
//! by the end of the file (a killed writer's last) is decompressed as a stream and yields every
//! record before the cut.

use std::io::{self, Cursor, Read};

use mcap::McapError;
use mcap::records::{Record, op};

/// The longest record accepted: a length field above this is damage, not a record.
pub(crate) const RECORD_LENGTH_LIMIT: u64 = 1 << 30;

/// Bytes of a record's opcode and length.
const RECORD_PREFIX_LEN: usize = 9;

/// What the reader hands over next.
#[derive(Debug)]
pub(crate) enum Event<'a> {
    /// One record (inside a chunk or not), its body ready for `mcap::parse_record`.
    Record {
        /// The record's opcode.
        opcode: u8,
        /// The record's body.
        body: &'a [u8],
    },
    /// The end of the reading: nothing more will be handed over.
    End(End),
}

/// How a read ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum End {
    /// The footer and the closing magic were read.
    Complete,
    /// The read stopped before the footer: the file was cut (`at_eof`) or a record is damaged.
    Stopped {
        /// Why, in words.
        reason: String,
        /// True when the file's end came before what a record said it held.
        at_eof: bool,
    },
}

/// A chunk being expanded.
struct Chunk {
    /// The chunk's records, decompressed as they are read.
    content: Box<dyn Read>,
    /// Uncompressed bytes the chunk header says are still to come.
    remaining: u64,
    /// True when the file ended inside this chunk's record.
    cut: bool,
}

/// The record reader over a byte source (a file, usually buffered).
pub(crate) struct RecordStream<R> {
    src: R,
    read_bytes: u64,
    hit_eof: bool,
    started: bool,
    footer_read: bool,
    ended: Option<End>,
    /// The current top-level record's body.
    body: Vec<u8>,
    /// The current record inside a chunk.
    inner: Vec<u8>,
    chunk: Option<Chunk>,
}

impl<R: Read> RecordStream<R> {
    /// A reader at the start of a file (before its magic).
    pub(crate) fn new(src: R) -> Self {
        RecordStream {
            src,
            read_bytes: 0,
            hit_eof: false,
            started: false,
            footer_read: false,
            ended: None,
            body: Vec::new(),
            inner: Vec::new(),
            chunk: None,
        }
    }

    /// Bytes read from the source so far.
    pub(crate) fn read_bytes(&self) -> u64 {
        self.read_bytes
    }

    /// True once a read from the source returned nothing (its end).
    pub(crate) fn hit_eof(&self) -> bool {
        self.hit_eof
    }

    /// The next record, or how the read ended (returned again on every later call). Errors are
    /// the source's own (an I/O failure); damage in the bytes ends the read instead.
    pub(crate) fn next_event(&mut self) -> io::Result<Event<'_>> {
        if let Some(end) = &self.ended {
            return Ok(Event::End(end.clone()));
        }
        match self.advance()? {
            Step::Top(opcode) => Ok(Event::Record {
                opcode,
                body: &self.body,
            }),
            Step::Inner(opcode) => Ok(Event::Record {
                opcode,
                body: &self.inner,
            }),
            Step::ChunkOpened => unreachable!("advance goes on into an opened chunk"),
            Step::End(end) => {
                self.ended = Some(end.clone());
                self.chunk = None;
                Ok(Event::End(end))
            }
        }
    }

    /// Moves to the next record; says which buffer holds it.
    fn advance(&mut self) -> io::Result<Step> {
        if !self.started {
            self.started = true;
            let mut magic = [0u8; 8];
            let n = self.read_full(&mut magic)?;
            if n < magic.len() || magic != *mcap::MAGIC {
                return Ok(stop("it does not start with the MCAP magic", false));
            }
        }
        loop {
            if self.chunk.is_some() {
                match self.next_in_chunk() {
                    Some(step) => return Ok(step),
                    None => continue,
                }
            }
            if self.footer_read {
                let mut magic = [0u8; 8];
                let n = self.read_full(&mut magic)?;
                return Ok(if n == magic.len() && magic == *mcap::MAGIC {
                    Step::End(End::Complete)
                } else if n < magic.len() {
                    stop("file ends before its closing magic", true)
                } else {
                    stop("the footer is not followed by the MCAP magic", false)
                });
            }
            match self.next_top()? {
                Step::ChunkOpened => continue,
                step => return Ok(step),
            }
        }
    }

    /// The next top-level record; a chunk is opened and its first record read instead.
    fn next_top(&mut self) -> io::Result<Step> {
        let at = self.read_bytes;
        let mut prefix = [0u8; RECORD_PREFIX_LEN];
        let n = self.read_full(&mut prefix)?;
        if n == 0 {
            return Ok(stop(
                format!("file ends after {at} bytes without its footer; it was not closed cleanly"),
                true,
            ));
        }
        if n < prefix.len() {
            return Ok(stop(
                format!("file ends inside the record at byte {at}; it was not closed cleanly"),
                true,
            ));
        }
        let opcode = prefix[0];
        let len = u64::from_le_bytes(prefix[1..].try_into().expect("8 bytes"));
        if len > RECORD_LENGTH_LIMIT {
            return Ok(stop(
                format!(
                    "damaged record at byte {at}: opcode {opcode:#04x} claims {len} bytes (limit \
                     {RECORD_LENGTH_LIMIT})"
                ),
                false,
            ));
        }
        self.body.clear();
        // Grows as the bytes arrive: a damaged length costs at most what the file holds.
        let got = (&mut self.src).take(len).read_to_end(&mut self.body)?;
        self.count(got);
        let cut = (got as u64) < len;
        if cut {
            self.hit_eof = true;
        }
        if opcode == op::CHUNK {
            return self.open_chunk(at, cut);
        }
        if cut {
            return Ok(stop(
                format!(
                    "file ends inside the record at byte {at} ({got} of its {len} bytes); it was \
                     not closed cleanly"
                ),
                true,
            ));
        }
        if opcode == op::FOOTER {
            self.footer_read = true;
        }
        Ok(Step::Top(opcode))
    }

    /// Reads the chunk header in `self.body` and starts expanding its records.
    fn open_chunk(&mut self, at: u64, cut: bool) -> io::Result<Step> {
        let header = match ChunkHeader::parse(&self.body) {
            Some(h) => h,
            None if cut => {
                return Ok(stop(
                    format!(
                        "file ends inside the chunk header at byte {at}; it was not closed cleanly"
                    ),
                    true,
                ));
            }
            None => return Ok(stop(format!("damaged chunk header at byte {at}"), false)),
        };
        let available = (self.body.len() - header.records_offset) as u64;
        if !cut && header.compressed_size > available {
            return Ok(stop(
                format!(
                    "damaged chunk at byte {at}: its records claim {} bytes, the record holds {available}",
                    header.compressed_size
                ),
                false,
            ));
        }
        let mut records = Cursor::new(std::mem::take(&mut self.body));
        records.set_position(header.records_offset as u64);
        let records = records.take(header.compressed_size);
        let content: Box<dyn Read> = match header.compression.as_str() {
            "" => Box::new(records),
            "zstd" => Box::new(zstd::stream::read::Decoder::new(records)?),
            "lz4" => Box::new(lz4_flex::frame::FrameDecoder::new(records)),
            other => {
                return Ok(stop(
                    format!(
                        "chunk at byte {at} uses compression {other:?}, which is not supported"
                    ),
                    false,
                ));
            }
        };
        let remaining = header.uncompressed_size;
        if remaining > RECORD_LENGTH_LIMIT {
            // Decompression is bounded by this size: a damaged one must not let a small chunk
            // expand without limit.
            return Ok(stop(
                format!(
                    "damaged chunk at byte {at}: it claims {remaining} uncompressed bytes (limit \
                     {RECORD_LENGTH_LIMIT})"
                ),
                false,
            ));
        }
        let content = if cut || header.uncompressed_crc == 0 {
            // A chunk cut by the file's end (its CRC cannot be checked) or written without a CRC:
            // its records are streamed, every one before the cut delivered.
            content
        } else {
            // A whole chunk with a CRC is checked before any of its records is delivered, so
            // damaged compressed bytes never reach the caller as messages.
            let mut records = Vec::new();
            let got = match content.take(remaining).read_to_end(&mut records) {
                Ok(got) => got as u64,
                Err(e) => {
                    return Ok(stop(
                        format!("damaged chunk at byte {at}: cannot decompress: {e}"),
                        false,
                    ));
                }
            };
            if got != remaining {
                return Ok(stop(
                    format!(
                        "damaged chunk at byte {at}: its records hold {got} of the {remaining} bytes its header gives"
                    ),
                    false,
                ));
            }
            let calculated = crc32fast::hash(&records);
            if calculated != header.uncompressed_crc {
                return Ok(stop(
                    format!(
                        "damaged chunk at byte {at}: its CRC is {:#010x}, its records' {calculated:#010x}",
                        header.uncompressed_crc
                    ),
                    false,
                ));
            }
            Box::new(Cursor::new(records))
        };
        self.chunk = Some(Chunk {
            content,
            remaining,
            cut,
        });
        Ok(Step::ChunkOpened)
    }

    /// The next record of the open chunk; `None` when the chunk ended cleanly (it is closed).
    fn next_in_chunk(&mut self) -> Option<Step> {
        let chunk = self.chunk.as_mut()?;
        let damaged = |what: String, chunk: &Chunk| {
            if chunk.cut {
                stop(
                    format!("file ends inside a chunk ({what}); it was not closed cleanly"),
                    true,
                )
            } else {
                stop(format!("damaged chunk: {what}"), false)
            }
        };
        if chunk.remaining == 0 {
            self.chunk = None;
            return None;
        }
        if chunk.remaining < RECORD_PREFIX_LEN as u64 {
            return Some(damaged(
                format!("{} bytes left, too few for a record", chunk.remaining),
                chunk,
            ));
        }
        let mut prefix = [0u8; RECORD_PREFIX_LEN];
        if let Err(e) = read_exact_or_name(&mut chunk.content, &mut prefix) {
            return Some(damaged(e, chunk));
        }
        let opcode = prefix[0];
        let len = u64::from_le_bytes(prefix[1..].try_into().expect("8 bytes"));
        let room = chunk.remaining - RECORD_PREFIX_LEN as u64;
        if len > room {
            return Some(damaged(
                format!(
                    "a record (opcode {opcode:#04x}) claims {len} bytes, the chunk has {room} left"
                ),
                chunk,
            ));
        }
        self.inner.clear();
        match (&mut chunk.content).take(len).read_to_end(&mut self.inner) {
            Ok(got) if got as u64 == len => {}
            Ok(got) => {
                return Some(damaged(
                    format!("its records end {got} bytes into a record of {len}"),
                    chunk,
                ));
            }
            Err(e) => return Some(damaged(format!("cannot decompress: {e}"), chunk)),
        }
        chunk.remaining = room - len;
        Some(Step::Inner(opcode))
    }

    /// Reads until `buf` is full or the source ends; returns the bytes read.
    fn read_full(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let mut n = 0;
        while n < buf.len() {
            match self.src.read(&mut buf[n..]) {
                Ok(0) => {
                    self.hit_eof = true;
                    break;
                }
                Ok(k) => n += k,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        self.count(n);
        Ok(n)
    }

    fn count(&mut self, n: usize) {
        self.read_bytes += n as u64;
    }
}

/// Which buffer holds the record just read, or the end.
enum Step {
    Top(u8),
    Inner(u8),
    /// A chunk was opened: its records come next (it may hold none).
    ChunkOpened,
    End(End),
}

fn stop(reason: impl Into<String>, at_eof: bool) -> Step {
    Step::End(End::Stopped {
        reason: reason.into(),
        at_eof,
    })
}

/// `read_exact` on decompressed content, its failure in words (a cut stream or a decoder error).
fn read_exact_or_name(content: &mut dyn Read, buf: &mut [u8]) -> Result<(), String> {
    let mut n = 0;
    while n < buf.len() {
        match content.read(&mut buf[n..]) {
            Ok(0) => return Err(format!("its records end {n} bytes into a record's header")),
            Ok(k) => n += k,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(format!("cannot decompress: {e}")),
        }
    }
    Ok(())
}

/// The fixed part of a chunk record's body (MCAP spec, "Chunk (op=0x06)").
struct ChunkHeader {
    uncompressed_size: u64,
    uncompressed_crc: u32,
    compression: String,
    compressed_size: u64,
    /// Where the records start in the body.
    records_offset: usize,
}

impl ChunkHeader {
    /// `None` when the body is too short for the header or its compression name is not UTF-8.
    fn parse(body: &[u8]) -> Option<Self> {
        // message_start_time, message_end_time: not needed here.
        let uncompressed_size = u64::from_le_bytes(body.get(16..24)?.try_into().ok()?);
        let uncompressed_crc = u32::from_le_bytes(body.get(24..28)?.try_into().ok()?);
        let name_len = u32::from_le_bytes(body.get(28..32)?.try_into().ok()?) as usize;
        let name_end = 32usize.checked_add(name_len)?;
        let compression = std::str::from_utf8(body.get(32..name_end)?)
            .ok()?
            .to_owned();
        let size_end = name_end.checked_add(8)?;
        let compressed_size = u64::from_le_bytes(body.get(name_end..size_end)?.try_into().ok()?);
        Some(ChunkHeader {
            uncompressed_size,
            uncompressed_crc,
            compression,
            compressed_size,
            records_offset: size_end,
        })
    }
}

/// A record's body parsed by `mcap::parse_record`, refused first where that would panic: mcap
/// 0.26 takes an attachment's CRC from the last four bytes of its body without checking that
/// four are left after its header (found by the `mcap` fuzz target).
pub(crate) fn parse_record(opcode: u8, body: &[u8]) -> mcap::McapResult<Record<'_>> {
    if opcode == op::ATTACHMENT && !attachment_has_room(body) {
        return Err(McapError::UnexpectedEof);
    }
    mcap::parse_record(opcode, body)
}

/// True when an attachment's body holds its header (log time, create time, name, media type,
/// data length) and the four bytes of its CRC.
fn attachment_has_room(body: &[u8]) -> bool {
    let string_end = |at: usize| -> Option<usize> {
        let len = u32::from_le_bytes(body.get(at..at.checked_add(4)?)?.try_into().ok()?);
        at.checked_add(4)?.checked_add(len as usize)
    };
    let header_len = string_end(16)
        .and_then(string_end)
        .and_then(|end| end.checked_add(8));
    header_len
        .and_then(|h| h.checked_add(4))
        .is_some_and(|need| body.len() >= need)
}
