//! ROS 1 bag files (format 2.0), read front to back: chunks decompressed one at a time (none,
//! bz2, lz4), connections and messages handed over in file order, the index ignored. Memory is
//! bounded by one chunk whatever the file size.
//!
//! Not the `rosbag` crate (0.6): it memory-maps the file (`unsafe`, denied here), slices the
//! chunks up to the header's `index_pos` so an unindexed bag (`index_pos` 0, what a killed
//! recorder leaves) or one cut before its index panics instead of being read, and links the C
//! `lz4` library. The format is small (records of `name=value` header fields and data):
//! <http://wiki.ros.org/Bags/Format/2.0>.
//!
//! A bag whose recorder stopped without closing it is read up to its last complete record and
//! reported as [`Unfinished`] (`footer_missing`: no index), as an unfinished MCAP is: the
//! records of a cut chunk are recovered from its decompressed prefix, and the records a killed
//! `rosbag record` left after its last chunk header (whose sizes were never filled in) are read
//! too.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

use crate::mcap_read::Unfinished;

/// The first bytes of every ROS bag, whatever its version.
pub const ROSBAG_MAGIC_PREFIX: &[u8] = b"#ROSBAG V";
/// The version line of the bags read here.
pub const ROSBAG_V2: &[u8] = b"#ROSBAG V2.0\n";

/// A record header longer than this is damage, not a record (connection headers are a few KiB).
const MAX_HEADER_BYTES: u32 = 1 << 20;
/// A record (a chunk, compressed or not) longer than this is damage: asking for it would
/// allocate gigabytes from one corrupt length field.
const MAX_DATA_BYTES: u32 = 1 << 30;

const OP_MESSAGE: u8 = 0x02;
const OP_BAG_HEADER: u8 = 0x03;
const OP_CHUNK: u8 = 0x05;
const OP_CONNECTION: u8 = 0x07;

/// What went wrong opening a bag or handing over its messages (damage after the bag header is
/// reported in [`BagReport`] instead).
#[derive(Debug, thiserror::Error)]
pub enum Ros1BagError {
    /// The file could not be opened or read.
    #[error("{path}: cannot read")]
    Io {
        /// The bag.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// Not a ROS 1 bag of format 2.0.
    #[error("{path}: not a ROS 1 bag (format 2.0): {message}")]
    NotBag {
        /// The file.
        path: PathBuf,
        /// What was found.
        message: String,
    },
    /// A chunk is compressed in a way this reader does not know.
    #[error(
        "{path}: chunk at byte {offset}: compression `{compression}` (none, bz2 and lz4 are read)"
    )]
    Compression {
        /// The bag.
        path: PathBuf,
        /// The chunk record's offset in the file.
        offset: u64,
        /// Its `compression` field.
        compression: String,
    },
    /// The caller's message handler refused a message.
    #[error("{path}: topic {topic}, message at time {time_ns} ns: {message}")]
    Message {
        /// The bag.
        path: PathBuf,
        /// The connection's topic.
        topic: String,
        /// The message record's time.
        time_ns: u64,
        /// What the handler said.
        message: String,
    },
}

/// A connection: a topic with its message type, as its connection record says.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Connection {
    /// The connection id within the bag.
    pub id: u32,
    /// Topic name.
    pub topic: String,
    /// ROS 1 message type, e.g. `sensor_msgs/Imu`.
    pub msg_type: String,
    /// The type's MD5 sum as the publisher computed it.
    pub md5sum: String,
    /// The type's full definition text (may be empty).
    pub message_definition: String,
}

/// What a read saw besides the messages it handed over.
#[derive(Debug, Clone, Default)]
pub struct BagReport {
    /// Messages handed to the handler.
    pub n_messages: u64,
    /// Connections seen, by id.
    pub connections: BTreeMap<u32, Connection>,
    /// `Some(reason)` when the read stopped before a complete bag's end (cut, damaged or never
    /// indexed): every message before it was still delivered.
    pub stopped_early: Option<String>,
    /// The same fact as data (`footer_missing`: the bag has no index).
    pub unfinished: Option<Unfinished>,
}

/// True if `path` starts like a ROS bag (`#ROSBAG V`, any version): how readers tell one by
/// content.
pub fn has_rosbag_magic(path: &Path) -> std::io::Result<bool> {
    let mut head = [0u8; ROSBAG_MAGIC_PREFIX.len()];
    let n = read_full(&mut File::open(path)?, &mut head)?;
    Ok(n == head.len() && head == *ROSBAG_MAGIC_PREFIX)
}

/// Reads every message of the bag `path` in file order and hands it over with its connection
/// and record time (Unix epoch ns). See [`for_each_message_with_progress`].
pub fn for_each_message(
    path: &Path,
    on_message: impl FnMut(&Connection, u64, &[u8]) -> Result<(), String>,
) -> Result<BagReport, Ros1BagError> {
    for_each_message_with_progress(path, &mut |_, _| {}, on_message)
}

/// [`for_each_message`], reporting `(bytes read so far, file size)` after every record of the
/// file (monotone; ends at the file size when the whole file was read).
///
/// Returns an error only when the file cannot be read, is not a 2.0 bag, uses an unknown
/// compression or the handler fails; a cut or damaged bag ends the read with
/// [`BagReport::stopped_early`] set.
pub fn for_each_message_with_progress(
    path: &Path,
    on_progress: &mut dyn FnMut(u64, u64),
    mut on_message: impl FnMut(&Connection, u64, &[u8]) -> Result<(), String>,
) -> Result<BagReport, Ros1BagError> {
    let io = |source| Ros1BagError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = File::open(path).map_err(io)?;
    let total = file.metadata().map_err(io)?.len();
    on_progress(0, total);
    let mut pass = Pass {
        path,
        reader: BufReader::with_capacity(1 << 20, file),
        pos: 0,
        index_pos: 0,
        report: BagReport::default(),
        last_time_ns: None,
        header: Vec::new(),
        data: Vec::new(),
        chunk: Vec::new(),
    };
    pass.start()?;
    on_progress(pass.pos, total);
    let end = loop {
        let at = pass.pos;
        let end = match pass.next_record().map_err(io)? {
            Next::Record => pass.top_record(at, &mut on_message)?,
            Next::Cut => pass.cut_record(at, &mut on_message)?,
            other => Some(other),
        };
        on_progress(pass.pos.min(total), total);
        if let Some(end) = end {
            break end;
        }
    };
    Ok(pass.finish(end))
}

/// What the next record read gave.
#[derive(Debug)]
enum Next {
    /// A whole record is in `header` and `data`.
    Record,
    /// The file ended exactly between records.
    End,
    /// The file ended inside the record: `header` is whole when `data` holds its first bytes.
    Cut,
    /// The read stopped at damage (the reason).
    Damaged(String),
}

/// One front-to-back read.
struct Pass<'p> {
    path: &'p Path,
    reader: BufReader<File>,
    /// Bytes consumed from the file.
    pos: u64,
    /// The bag header's `index_pos` (0: never indexed).
    index_pos: u64,
    report: BagReport,
    last_time_ns: Option<u64>,
    /// The current record's header and data.
    header: Vec<u8>,
    data: Vec<u8>,
    /// The current chunk decompressed.
    chunk: Vec<u8>,
}

impl<'p> Pass<'p> {
    fn not_bag(&self, message: impl Into<String>) -> Ros1BagError {
        Ros1BagError::NotBag {
            path: self.path.to_path_buf(),
            message: message.into(),
        }
    }

    /// The version line and the bag header record.
    fn start(&mut self) -> Result<(), Ros1BagError> {
        let mut magic = [0u8; ROSBAG_V2.len()];
        let n = read_full(&mut self.reader, &mut magic).map_err(|source| Ros1BagError::Io {
            path: self.path.to_path_buf(),
            source,
        })?;
        self.pos = n as u64;
        if magic[..n] != ROSBAG_V2[..n] || n < magic.len() {
            let line = magic[..n].split(|b| *b == b'\n').next().unwrap_or(&[]);
            return Err(self.not_bag(format!(
                "starts with `{}`",
                String::from_utf8_lossy(line).escape_debug()
            )));
        }
        let next = self.next_record().map_err(|source| Ros1BagError::Io {
            path: self.path.to_path_buf(),
            source,
        })?;
        if !matches!(next, Next::Record) {
            return Err(self.not_bag("no bag header record after the version line"));
        }
        let mut op = None;
        for (name, value) in Fields(&self.header) {
            match name {
                b"op" => op = value.first().copied(),
                b"index_pos" => self.index_pos = le_u64(value).unwrap_or(0),
                _ => {}
            }
        }
        if op != Some(OP_BAG_HEADER) {
            return Err(self.not_bag("the first record is not the bag header"));
        }
        Ok(())
    }

    /// Reads the next top-level record into `header` and `data`.
    fn next_record(&mut self) -> std::io::Result<Next> {
        let mut len = [0u8; 4];
        // What `header` and `data` hold is this record's from here on: a record cut in its
        // length field has neither (the previous record's would be handed over again).
        self.header.clear();
        self.data.clear();
        match read_full(&mut self.reader, &mut len)? {
            0 => return Ok(Next::End),
            4 => {}
            n => {
                self.pos += n as u64;
                return Ok(Next::Cut);
            }
        }
        self.pos += 4;
        let header_len = u32::from_le_bytes(len);
        if header_len > MAX_HEADER_BYTES {
            return Ok(Next::Damaged(format!(
                "record at byte {} has a {header_len}-byte header",
                self.pos - 4
            )));
        }
        if !self.fill(Buf::Header, header_len)? {
            self.data.clear();
            return Ok(Next::Cut);
        }
        match read_full(&mut self.reader, &mut len)? {
            4 => self.pos += 4,
            n => {
                self.pos += n as u64;
                self.data.clear();
                return Ok(Next::Cut);
            }
        }
        let data_len = u32::from_le_bytes(len);
        if data_len > MAX_DATA_BYTES {
            return Ok(Next::Damaged(format!(
                "record at byte {} has {data_len} bytes of data",
                self.pos
            )));
        }
        Ok(if self.fill(Buf::Data, data_len)? {
            Next::Record
        } else {
            Next::Cut
        })
    }

    /// Reads `n` bytes into a buffer; false (with the bytes there were) at the file's end.
    fn fill(&mut self, which: Buf, n: u32) -> std::io::Result<bool> {
        let buf = match which {
            Buf::Header => &mut self.header,
            Buf::Data => &mut self.data,
        };
        buf.clear();
        let got = (&mut self.reader).take(u64::from(n)).read_to_end(buf)?;
        self.pos += got as u64;
        Ok(got == n as usize)
    }

    /// A whole top-level record; `Some` ends the read.
    fn top_record(
        &mut self,
        at: u64,
        on_message: &mut impl FnMut(&Connection, u64, &[u8]) -> Result<(), String>,
    ) -> Result<Option<Next>, Ros1BagError> {
        let header = std::mem::take(&mut self.header);
        let data = std::mem::take(&mut self.data);
        let out = if op_of(&header) == Some(OP_CHUNK) {
            self.chunk(at, &header, &data, true, on_message)
        } else {
            self.record(&header, &data, on_message)
        };
        self.header = header;
        self.data = data;
        out
    }

    /// The file ended inside the record at `at`: a chunk gives the records its bytes hold.
    fn cut_record(
        &mut self,
        at: u64,
        on_message: &mut impl FnMut(&Connection, u64, &[u8]) -> Result<(), String>,
    ) -> Result<Option<Next>, Ros1BagError> {
        let header = std::mem::take(&mut self.header);
        let data = std::mem::take(&mut self.data);
        let cut = format!(
            "file ends at byte {} inside the record at byte {at}; it was not closed cleanly",
            self.pos
        );
        let out = if op_of(&header) == Some(OP_CHUNK) && !data.is_empty() {
            match self.chunk(at, &header, &data, false, on_message)? {
                Some(Next::Damaged(why)) => Some(Next::Damaged(why)),
                _ => Some(Next::Damaged(cut)),
            }
        } else {
            Some(Next::Damaged(cut))
        };
        self.header = header;
        self.data = data;
        Ok(out)
    }

    /// A chunk's records. `whole`: all its data is there; else only the first bytes are.
    fn chunk(
        &mut self,
        at: u64,
        header: &[u8],
        data: &[u8],
        whole: bool,
        on_message: &mut impl FnMut(&Connection, u64, &[u8]) -> Result<(), String>,
    ) -> Result<Option<Next>, Ros1BagError> {
        let (mut compression, mut size) = (String::new(), 0u32);
        for (name, value) in Fields(header) {
            match name {
                b"compression" => compression = String::from_utf8_lossy(value).into_owned(),
                b"size" => size = le_u32(value).unwrap_or(0),
                _ => {}
            }
        }
        // A killed `rosbag record` never fills in its last chunk's sizes: an uncompressed
        // chunk's records then follow as if at the top level (and are read so), a compressed
        // one's stream runs to the end of the file.
        let sizes_unset = whole && data.is_empty() && size == 0;
        let mut rest = Vec::new();
        let (data, whole) = if sizes_unset && compression != "none" {
            let got = (&mut self.reader)
                .take(u64::from(MAX_DATA_BYTES))
                .read_to_end(&mut rest)
                .map_err(|source| Ros1BagError::Io {
                    path: self.path.to_path_buf(),
                    source,
                })?;
            self.pos += got as u64;
            (&rest[..], false)
        } else {
            (data, whole)
        };
        let mut chunk = std::mem::take(&mut self.chunk);
        chunk.clear();
        let decoded: Result<&[u8], String> = match compression.as_str() {
            "none" => Ok(data),
            "bz2" | "lz4" if size > MAX_DATA_BYTES => {
                Err(format!("chunk at byte {at} says it holds {size} bytes"))
            }
            "bz2" | "lz4" => {
                chunk.reserve(size as usize);
                let limit = u64::from(size).max(if whole { 0 } else { u64::from(MAX_DATA_BYTES) });
                let result = if compression == "bz2" {
                    bzip2::read::BzDecoder::new(data)
                        .take(limit)
                        .read_to_end(&mut chunk)
                } else {
                    lz4_flex::frame::FrameDecoder::new(data)
                        .take(limit)
                        .read_to_end(&mut chunk)
                };
                match result {
                    // A cut chunk's stream fails where its bytes end: what it gave is kept.
                    Err(_) if !whole => Ok(&chunk[..]),
                    Err(e) => Err(format!("chunk at byte {at}: {compression}: {e}")),
                    Ok(_) => Ok(&chunk[..]),
                }
            }
            _ => {
                return Err(Ros1BagError::Compression {
                    path: self.path.to_path_buf(),
                    offset: at,
                    compression,
                });
            }
        };
        let out = match decoded {
            Err(why) => Ok(Some(Next::Damaged(why))),
            Ok(bytes) => self.chunk_records(at, bytes, whole, on_message),
        };
        self.chunk = chunk;
        out
    }

    /// The records inside a decompressed chunk.
    fn chunk_records(
        &mut self,
        at: u64,
        bytes: &[u8],
        whole: bool,
        on_message: &mut impl FnMut(&Connection, u64, &[u8]) -> Result<(), String>,
    ) -> Result<Option<Next>, Ros1BagError> {
        let mut pos = 0usize;
        while pos < bytes.len() {
            let Some((header, data, next)) = split_record(bytes, pos) else {
                return Ok(Some(Next::Damaged(if whole {
                    format!("chunk at byte {at}: its record at chunk byte {pos} is damaged")
                } else {
                    format!(
                        "file ends at byte {} inside the chunk at byte {at}; it was not \
                         closed cleanly",
                        self.pos
                    )
                })));
            };
            if let Some(end) = self.record(header, data, on_message)? {
                return Ok(Some(end));
            }
            pos = next;
        }
        Ok(None)
    }

    /// A message or connection record (at the top level or in a chunk); others are skipped.
    fn record(
        &mut self,
        header: &[u8],
        data: &[u8],
        on_message: &mut impl FnMut(&Connection, u64, &[u8]) -> Result<(), String>,
    ) -> Result<Option<Next>, Ros1BagError> {
        match op_of(header) {
            Some(OP_MESSAGE) => {
                let (mut conn, mut time_ns) = (None, 0);
                for (name, value) in Fields(header) {
                    match name {
                        b"conn" => conn = le_u32(value),
                        b"time" => time_ns = time_of(value).unwrap_or(0),
                        _ => {}
                    }
                }
                let Some(c) = conn.and_then(|c| self.report.connections.get(&c)) else {
                    return Ok(Some(Next::Damaged(format!(
                        "message on unknown connection {conn:?} (damaged bag)"
                    ))));
                };
                on_message(c, time_ns, data).map_err(|message| Ros1BagError::Message {
                    path: self.path.to_path_buf(),
                    topic: c.topic.clone(),
                    time_ns,
                    message,
                })?;
                self.report.n_messages += 1;
                self.last_time_ns = self.last_time_ns.max(Some(time_ns));
            }
            Some(OP_CONNECTION) => {
                let (mut id, mut topic) = (None, String::new());
                for (name, value) in Fields(header) {
                    match name {
                        b"conn" => id = le_u32(value),
                        b"topic" => topic = String::from_utf8_lossy(value).into_owned(),
                        _ => {}
                    }
                }
                let Some(id) = id else {
                    return Ok(Some(Next::Damaged(
                        "connection record without `conn`".into(),
                    )));
                };
                let mut c = Connection {
                    id,
                    topic,
                    msg_type: String::new(),
                    md5sum: String::new(),
                    message_definition: String::new(),
                };
                for (name, value) in Fields(data) {
                    let text = || String::from_utf8_lossy(value).into_owned();
                    match name {
                        b"type" => c.msg_type = text(),
                        b"md5sum" => c.md5sum = text(),
                        b"message_definition" => c.message_definition = text(),
                        _ => {}
                    }
                }
                // The index section repeats every connection; the first record stands.
                self.report.connections.entry(id).or_insert(c);
            }
            _ => {}
        }
        Ok(None)
    }

    fn finish(mut self, end: Next) -> BagReport {
        let index_missing = self.index_pos == 0 || self.index_pos > self.pos;
        let reason = match end {
            Next::Damaged(why) => Some(why),
            _ if self.index_pos == 0 => Some(
                "the bag has no index (index_pos 0): its recorder stopped without closing it"
                    .to_string(),
            ),
            _ if index_missing => Some(format!(
                "file ends at byte {}, before its index at byte {}",
                self.pos, self.index_pos
            )),
            _ => None,
        };
        self.report.unfinished = reason.as_ref().map(|reason| Unfinished {
            footer_missing: index_missing,
            reason: reason.clone(),
            n_messages: self.report.n_messages,
            last_log_time_ns: self.last_time_ns,
            repair: format!("rosbag reindex {}", self.path.display()),
        });
        self.report.stopped_early = reason;
        self.report
    }
}

#[derive(Clone, Copy)]
enum Buf {
    Header,
    Data,
}

/// Reads until `buf` is full or the file ends; returns how many bytes it holds.
fn read_full(r: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match r.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
}

/// The record starting at `pos` of `bytes`: header, data, the next record's offset; `None` if
/// it runs past the end.
fn split_record(bytes: &[u8], pos: usize) -> Option<(&[u8], &[u8], usize)> {
    let header_len = le_u32(bytes.get(pos..pos.checked_add(4)?)?)? as usize;
    let h = pos + 4;
    let header = bytes.get(h..h.checked_add(header_len)?)?;
    let d = h + header_len;
    let data_len = le_u32(bytes.get(d..d.checked_add(4)?)?)? as usize;
    let data = bytes.get(d + 4..(d + 4).checked_add(data_len)?)?;
    Some((header, data, d + 4 + data_len))
}

/// A record header's `op` field.
fn op_of(header: &[u8]) -> Option<u8> {
    Fields(header)
        .find(|(name, _)| *name == b"op")
        .and_then(|(_, v)| v.first().copied())
}

/// The `name=value` fields of a record header (or a connection record's data), each a
/// `uint32` length and its bytes; stops at the first malformed one.
struct Fields<'a>(&'a [u8]);

impl<'a> Iterator for Fields<'a> {
    type Item = (&'a [u8], &'a [u8]);

    fn next(&mut self) -> Option<Self::Item> {
        let len = le_u32(self.0.get(..4)?)? as usize;
        let Some(field) = self.0.get(4..4usize.checked_add(len)?) else {
            self.0 = &[];
            return None;
        };
        self.0 = &self.0[4 + len..];
        let eq = field.iter().position(|b| *b == b'=')?;
        Some((&field[..eq], &field[eq + 1..]))
    }
}

fn le_u32(b: &[u8]) -> Option<u32> {
    Some(u32::from_le_bytes(b.get(..4)?.try_into().ok()?))
}

fn le_u64(b: &[u8]) -> Option<u64> {
    Some(u64::from_le_bytes(b.get(..8)?.try_into().ok()?))
}

/// A record's `time` field: `uint32` seconds and nanoseconds.
fn time_of(b: &[u8]) -> Option<u64> {
    let sec = le_u32(b)?;
    let nsec = le_u32(b.get(4..)?)?;
    Some(u64::from(sec) * 1_000_000_000 + u64::from(nsec))
}
