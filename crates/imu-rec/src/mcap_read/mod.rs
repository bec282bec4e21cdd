//! Streaming, truncation-tolerant MCAP reading shared by every offline tool.
//!
//! Recordings are read front to back by [`records::RecordStream`], so memory stays bounded by one
//! chunk whatever the file size, and a file whose writer died (no summary, a half-written chunk) is
//! read up to its last good record: the damage is reported in [`ReadReport::stopped_early`] instead
//! of failing the whole read.

pub(crate) mod records;

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

use mcap::records::{MessageHeader, Record};

use records::{End, Event, RecordStream};

/// What went wrong opening or decoding a recording (set-up errors only; damage after the first
/// good records is reported in [`ReadReport`] instead).
#[derive(Debug, thiserror::Error)]
pub enum McapReadError {
    /// The file could not be opened or read.
    #[error("{path}: cannot read")]
    Io {
        /// The recording.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The file is not an MCAP file at all (bad magic or no records).
    #[error("{path}: not an MCAP file: {message}")]
    NotMcap {
        /// The recording.
        path: PathBuf,
        /// What the reader said.
        message: String,
    },
    /// The caller's message handler refused a message.
    #[error("{path}: topic {topic}, message at log time {log_time_ns} ns: {message}")]
    Message {
        /// The recording.
        path: PathBuf,
        /// The channel's topic.
        topic: String,
        /// The message's log time.
        log_time_ns: u64,
        /// What the handler said.
        message: String,
    },
}

/// A channel as announced in the recording.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ChannelInfo {
    /// Channel id within the file.
    pub id: u16,
    /// Topic name, e.g. `/truth/sample`.
    pub topic: String,
    /// Message encoding, e.g. `json` or `cdr`.
    pub message_encoding: String,
    /// Schema name (empty when the channel has none).
    pub schema_name: String,
    /// Schema encoding, e.g. `jsonschema` or `ros2msg`.
    pub schema_encoding: String,
}

/// What a read saw besides the messages it handed over.
#[derive(Debug, Clone, Default)]
pub struct ReadReport {
    /// Messages handed to the handler.
    pub n_messages: u64,
    /// Metadata records, by name.
    pub metadata: BTreeMap<String, BTreeMap<String, String>>,
    /// Channels seen, by id.
    pub channels: BTreeMap<u16, ChannelInfo>,
    /// `Some(reason)` when the file ended before its footer (truncated or damaged): every message
    /// before the damage was still delivered.
    pub stopped_early: Option<String>,
    /// The same fact as data, with how far the read got (`None` for a complete file).
    pub unfinished: Option<Unfinished>,
}

/// A recording read only up to its last good record: its writer was killed before writing the
/// footer (summary and index), or a record is damaged. Readers that need the summary (Python
/// `mcap`'s default `make_reader(f).iter_messages()`) cannot open such a file until it is
/// repaired ([`crate::recover`], `imud recover FILE`).
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct Unfinished {
    /// True when the file ends before its footer (the writer never closed it); false when a
    /// damaged record stopped the read.
    pub footer_missing: bool,
    /// Why the read stopped.
    pub reason: String,
    /// Messages read before the stop.
    pub n_messages: u64,
    /// Latest log time among the messages read, Unix epoch ns (`None` when none was read).
    pub last_log_time_ns: Option<u64>,
    /// The command that repairs the file (`imud recover FILE`, `rosbag reindex FILE`).
    pub repair: String,
}

/// True if `path` starts with the MCAP magic bytes: how every reader tells an MCAP file from
/// text, by content and never by extension.
pub fn has_mcap_magic(path: &Path) -> std::io::Result<bool> {
    let mut magic = [0u8; 8];
    let mut file = File::open(path)?;
    let mut n = 0;
    while n < magic.len() {
        match file.read(&mut magic[n..])? {
            0 => break,
            k => n += k,
        }
    }
    Ok(n == magic.len() && magic == *mcap::MAGIC)
}

/// Reads every message of `path` in file order and hands it to `on_message`.
///
/// Returns an error only when the file cannot be opened, is not MCAP, or the handler fails;
/// truncation and corruption after the header end the read quietly with
/// [`ReadReport::stopped_early`] set.
pub fn for_each_message(
    path: &Path,
    on_message: impl FnMut(&ChannelInfo, &MessageHeader, &[u8]) -> Result<(), String>,
) -> Result<ReadReport, McapReadError> {
    for_each_message_with_progress(path, &mut |_, _| {}, on_message)
}

/// [`for_each_message`], reporting `(bytes read so far, file size)` after every read from the
/// file (monotone; the last call has `bytes read == file size` unless the read stopped early),
/// for progress bars on long reads.
pub fn for_each_message_with_progress(
    path: &Path,
    on_progress: &mut dyn FnMut(u64, u64),
    mut on_message: impl FnMut(&ChannelInfo, &MessageHeader, &[u8]) -> Result<(), String>,
) -> Result<ReadReport, McapReadError> {
    let (mut pass, file) = Pass::open(path, on_progress)?;
    // A whole chunk is checked against its CRC before its first message is delivered (a damaged
    // one delivers none); a chunk cut by the file's end delivers every message before the cut.
    let mut stream = RecordStream::new(BufReader::with_capacity(1 << 16, file));
    loop {
        // Where the previous record left the reader.
        pass.advanced(stream.read_bytes(), stream.hit_eof());
        let event = stream.next_event().map_err(|e| pass.io_err(e))?;
        let flow = match event {
            Event::End(End::Complete) => Flow::Stop,
            Event::End(End::Stopped { reason, .. }) => pass.stopped(reason)?,
            // Only the records a read uses are parsed: indexes, statistics and attachments
            // are skipped unread (the summary repeats what the data section said).
            Event::Record { opcode, body } if USED_OPCODES.contains(&opcode) => {
                pass.record(records::parse_record(opcode, body), &mut on_message)?
            }
            Event::Record { .. } => pass.skipped(),
        };
        if flow == Flow::Stop {
            break;
        }
    }
    pass.advanced(stream.read_bytes(), stream.hit_eof());
    pass.finish()
}

/// The records a read parses: schemas and channels (to name the messages' topics), messages,
/// metadata; and the header, the first record, which says the file is MCAP.
const USED_OPCODES: [u8; 5] = [
    mcap::records::op::HEADER,
    mcap::records::op::SCHEMA,
    mcap::records::op::CHANNEL,
    mcap::records::op::MESSAGE,
    mcap::records::op::METADATA,
];

/// Whether the read goes on after an event.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Flow {
    Continue,
    Stop,
}

/// One front-to-back read of a file: what has been seen so far.
struct Pass<'p> {
    path: &'p Path,
    on_progress: &'p mut dyn FnMut(u64, u64),
    total_bytes: u64,
    read_bytes: u64,
    report: ReadReport,
    schemas: BTreeMap<u16, (String, String)>,
    saw_record: bool,
    hit_eof: bool,
    last_log_time_ns: Option<u64>,
}

impl<'p> Pass<'p> {
    fn io_err(&self, source: std::io::Error) -> McapReadError {
        McapReadError::Io {
            path: self.path.to_path_buf(),
            source,
        }
    }

    /// Opens the file; the pass starts at its first byte.
    fn open(
        path: &'p Path,
        on_progress: &'p mut dyn FnMut(u64, u64),
    ) -> Result<(Self, File), McapReadError> {
        let io_err = |source| McapReadError::Io {
            path: path.to_path_buf(),
            source,
        };
        let file = File::open(path).map_err(io_err)?;
        let total_bytes = file.metadata().map_err(io_err)?.len();
        on_progress(0, total_bytes);
        let pass = Pass {
            path,
            on_progress,
            total_bytes,
            read_bytes: 0,
            report: ReadReport::default(),
            schemas: BTreeMap::new(),
            saw_record: false,
            hit_eof: false,
            last_log_time_ns: None,
        };
        Ok((pass, file))
    }

    /// Follows the reader's position: progress is reported whenever it moved.
    fn advanced(&mut self, read_bytes: u64, hit_eof: bool) {
        self.hit_eof = hit_eof;
        if read_bytes != self.read_bytes {
            self.read_bytes = read_bytes;
            (self.on_progress)(read_bytes.min(self.total_bytes), self.total_bytes);
        }
    }

    /// The read stopped before the footer: not MCAP at all before the first record, a cut or
    /// damaged file after it.
    fn stopped(&mut self, reason: String) -> Result<Flow, McapReadError> {
        if !self.saw_record {
            return Err(McapReadError::NotMcap {
                path: self.path.to_path_buf(),
                message: reason,
            });
        }
        self.report.stopped_early = Some(reason);
        Ok(Flow::Stop)
    }

    /// A record the read does not use.
    fn skipped(&mut self) -> Flow {
        self.saw_record = true;
        Flow::Continue
    }

    /// One record: schemas and channels are remembered, messages handed over, metadata kept.
    fn record(
        &mut self,
        parsed: Result<Record<'_>, mcap::McapError>,
        on_message: &mut impl FnMut(&ChannelInfo, &MessageHeader, &[u8]) -> Result<(), String>,
    ) -> Result<Flow, McapReadError> {
        self.saw_record = true;
        let record = match parsed {
            Ok(r) => r,
            Err(e) => {
                self.report.stopped_early = Some(format!("undecodable record: {e}"));
                return Ok(Flow::Stop);
            }
        };
        match record {
            Record::Schema { header, .. } => {
                self.schemas
                    .insert(header.id, (header.name, header.encoding));
            }
            Record::Channel(ch) => {
                let (schema_name, schema_encoding) =
                    self.schemas.get(&ch.schema_id).cloned().unwrap_or_default();
                self.report.channels.insert(
                    ch.id,
                    ChannelInfo {
                        id: ch.id,
                        topic: ch.topic,
                        message_encoding: ch.message_encoding,
                        schema_name,
                        schema_encoding,
                    },
                );
            }
            Record::Message { header, data } => return self.message(&header, &data, on_message),
            Record::Metadata(m) => {
                self.report.metadata.insert(m.name, m.metadata);
            }
            _ => {}
        }
        Ok(Flow::Continue)
    }

    fn message(
        &mut self,
        header: &MessageHeader,
        data: &[u8],
        on_message: &mut impl FnMut(&ChannelInfo, &MessageHeader, &[u8]) -> Result<(), String>,
    ) -> Result<Flow, McapReadError> {
        let Some(channel) = self.report.channels.get(&header.channel_id) else {
            self.report.stopped_early = Some(format!(
                "message on unknown channel {} (damaged file)",
                header.channel_id
            ));
            return Ok(Flow::Stop);
        };
        on_message(channel, header, data).map_err(|message| McapReadError::Message {
            path: self.path.to_path_buf(),
            topic: channel.topic.clone(),
            log_time_ns: header.log_time,
            message,
        })?;
        self.report.n_messages += 1;
        self.last_log_time_ns = self.last_log_time_ns.max(Some(header.log_time));
        Ok(Flow::Continue)
    }

    fn finish(mut self) -> Result<ReadReport, McapReadError> {
        if !self.saw_record {
            return Err(McapReadError::NotMcap {
                path: self.path.to_path_buf(),
                message: "no records".into(),
            });
        }
        self.report.unfinished = self.report.stopped_early.as_ref().map(|reason| Unfinished {
            // The read may stop at damage before the end (a killed writer's last chunk is often
            // cut short); whether the file has its footer is read from its end.
            footer_missing: self.hit_eof
                || !crate::recover::is_finished(self.path).unwrap_or(false),
            reason: reason.clone(),
            n_messages: self.report.n_messages,
            last_log_time_ns: self.last_log_time_ns,
            repair: format!("imud recover {}", self.path.display()),
        });
        if self.read_bytes < self.total_bytes && self.report.stopped_early.is_none() {
            // The reader had all it needed before the end of the file (trailing bytes).
            (self.on_progress)(self.total_bytes, self.total_bytes);
        }
        Ok(self.report)
    }
}
