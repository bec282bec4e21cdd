//! Streaming, truncation-tolerant MCAP reading shared by every offline tool.
//!
//! Recordings are read front to back with mcap's sans-IO [`LinearReader`], so memory stays bounded
//! by one chunk whatever the file size, and a file whose writer died (no summary, a half-written
//! chunk) is read up to its last good record: the damage is reported in [`ReadReport::stopped_early`]
//! instead of failing the whole read.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};

use mcap::records::{MessageHeader, Record};
use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};

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
    let io_err = |source| McapReadError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut file = File::open(path).map_err(io_err)?;
    let total_bytes = file.metadata().map_err(io_err)?.len();
    let mut read_bytes: u64 = 0;
    on_progress(0, total_bytes);
    // Chunk CRCs are checked as each chunk ends (not before its first message), so a damaged
    // chunk still delivers the records that precede the damage. The record length limit keeps a
    // corrupt length field from asking for gigabytes.
    let options = LinearReaderOptions::default()
        .with_validate_chunk_crcs(true)
        .with_record_length_limit(1 << 30);
    let mut reader = LinearReader::new_with_options(options);
    let mut report = ReadReport::default();
    let mut schemas: BTreeMap<u16, (String, String)> = BTreeMap::new();
    let mut saw_record = false;
    let mut hit_eof = false;
    let mut last_log_time_ns: Option<u64> = None;
    while let Some(event) = reader.next_event() {
        let event = match event {
            Ok(ev) => ev,
            Err(e) => {
                if !saw_record {
                    return Err(McapReadError::NotMcap {
                        path: path.to_path_buf(),
                        message: e.to_string(),
                    });
                }
                report.stopped_early = Some(if hit_eof {
                    format!("file ends mid-record ({e}); it was not closed cleanly")
                } else {
                    format!("damaged record: {e}")
                });
                break;
            }
        };
        match event {
            LinearReadEvent::ReadRequest(need) => {
                let n = file.read(reader.insert(need)).map_err(io_err)?;
                if n == 0 {
                    hit_eof = true;
                }
                read_bytes += n as u64;
                on_progress(read_bytes.min(total_bytes), total_bytes);
                reader.notify_read(n);
            }
            LinearReadEvent::Record { opcode, data } => {
                saw_record = true;
                let record = match mcap::parse_record(opcode, data) {
                    Ok(r) => r,
                    Err(e) => {
                        report.stopped_early = Some(format!("undecodable record: {e}"));
                        break;
                    }
                };
                match record {
                    Record::Schema { header, .. } => {
                        schemas.insert(header.id, (header.name, header.encoding));
                    }
                    Record::Channel(ch) => {
                        let (schema_name, schema_encoding) =
                            schemas.get(&ch.schema_id).cloned().unwrap_or_default();
                        report.channels.insert(
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
                    Record::Message { header, data } => {
                        let Some(channel) = report.channels.get(&header.channel_id) else {
                            report.stopped_early = Some(format!(
                                "message on unknown channel {} (damaged file)",
                                header.channel_id
                            ));
                            break;
                        };
                        on_message(channel, &header, &data).map_err(|message| {
                            McapReadError::Message {
                                path: path.to_path_buf(),
                                topic: channel.topic.clone(),
                                log_time_ns: header.log_time,
                                message,
                            }
                        })?;
                        report.n_messages += 1;
                        last_log_time_ns = last_log_time_ns.max(Some(header.log_time));
                    }
                    Record::Metadata(m) => {
                        report.metadata.insert(m.name, m.metadata);
                    }
                    _ => {}
                }
            }
        }
    }
    if !saw_record {
        return Err(McapReadError::NotMcap {
            path: path.to_path_buf(),
            message: "no records".into(),
        });
    }
    report.unfinished = report.stopped_early.as_ref().map(|reason| Unfinished {
        // The read may stop at damage before the end (a killed writer's last chunk is often
        // cut short); whether the file has its footer is read from its end.
        footer_missing: hit_eof || !crate::recover::is_finished(path).unwrap_or(false),
        reason: reason.clone(),
        n_messages: report.n_messages,
        last_log_time_ns,
    });
    if read_bytes < total_bytes && report.stopped_early.is_none() {
        // The reader had all it needed before the end of the file (trailing bytes).
        on_progress(total_bytes, total_bytes);
    }
    Ok(report)
}
