//! Repairing a recording whose writer died (kill -9, power loss): like `ros2 bag reindex` and
//! `mcap recover`, every complete record of the unfinished file is rewritten with the `mcap`
//! crate's writer, which adds the summary, the chunk and message indexes and the footer. Then
//! every reader opens it with default options (Python `mcap`'s `make_reader(f).iter_messages()`
//! needs the summary; `rosbags` too).
//!
//! Safety of the original: the repaired copy is written next to it (`X.mcap.recovering`),
//! verified (read back front to back with every chunk CRC checked, and its summary read and
//! compared: the same number of messages, channels and schemas as were copied), and only then
//! swapped in: the original is renamed to `X.mcap.orig`, the copy to `X.mcap`, and the original
//! is removed unless the caller keeps it. A crash at any point leaves either the original under
//! its own name, or the verified copy under the name and the original as `.orig`;
//! [`recover_dir`] finishes such a half-done swap.

use std::collections::BTreeSet;
use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Seek};
use std::path::{Path, PathBuf};

use mcap::records::Record;
use mcap::sans_io::summary_reader::{SummaryReadEvent, SummaryReader};

use crate::mcap_read::records::{self, End, Event, RecordStream};
use crate::mcap_read::{self, McapReadError};

/// Suffix of the repaired copy while it is written and verified.
pub const RECOVERING_SUFFIX: &str = ".recovering";
/// Suffix of the original while the verified copy is swapped in.
pub const ORIGINAL_SUFFIX: &str = ".orig";

/// Why a recording could not be repaired. The original is left untouched in every case.
#[derive(Debug, thiserror::Error)]
pub enum RecoverError {
    /// Reading the original failed (cannot open it, not MCAP).
    #[error(transparent)]
    Read(#[from] McapReadError),
    /// A file operation failed.
    #[error("{path}: {what}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What was being done.
        what: &'static str,
        /// Why it failed.
        #[source]
        source: std::io::Error,
    },
    /// Writing the repaired copy failed.
    #[error("{path}: writing the repaired copy")]
    Write {
        /// The copy.
        path: PathBuf,
        /// Why.
        #[source]
        source: mcap::McapError,
    },
    /// Another process holds the file open for writing (its lock), or a `.orig` of it exists.
    #[error("{path}: {message}; left as it is")]
    Busy {
        /// The recording.
        path: PathBuf,
        /// Why.
        message: String,
    },
    /// The repaired copy did not read back as written; it was removed.
    #[error("{path}: the repaired copy failed verification: {message}")]
    Verify {
        /// The copy.
        path: PathBuf,
        /// What differed.
        message: String,
    },
}

/// What a repair did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Recovered {
    /// The repaired recording (the original's path).
    pub path: PathBuf,
    /// Why the original was unfinished (where its read stopped).
    pub reason: String,
    /// Messages kept (every complete one).
    pub n_messages: u64,
    /// Metadata records kept.
    pub n_metadata: u64,
    /// Latest log time kept, Unix epoch ns.
    pub last_log_time_ns: Option<u64>,
    /// Size of the original, bytes.
    pub original_bytes: u64,
    /// Size of the repaired file, bytes.
    pub repaired_bytes: u64,
    /// Where the original was kept (`Some` only when asked to keep it).
    pub original_kept: Option<PathBuf>,
}

fn io_err(path: &Path, what: &'static str) -> impl FnOnce(std::io::Error) -> RecoverError {
    let path = path.to_path_buf();
    move |source| RecoverError::Io { path, what, source }
}

fn with_suffix(path: &Path, suffix: &str) -> PathBuf {
    let mut s = path.as_os_str().to_owned();
    s.push(suffix);
    PathBuf::from(s)
}

/// True when `path` ends with a footer record and the closing magic, as a writer that finished
/// leaves it (a cheap check of the last 45 bytes; [`recover`] reads the whole file).
pub fn is_finished(path: &Path) -> std::io::Result<bool> {
    // Footer: opcode, length (20), summary start, summary offset start, summary CRC; then magic.
    const TAIL: u64 = 1 + 8 + 8 + 8 + 4 + 8;
    let mut f = File::open(path)?;
    let len = f.metadata()?.len();
    if len < mcap::MAGIC.len() as u64 + TAIL {
        return Ok(false);
    }
    f.seek(std::io::SeekFrom::End(-(TAIL as i64)))?;
    let mut tail = [0u8; TAIL as usize];
    f.read_exact(&mut tail)?;
    Ok(tail[0] == 0x02 && tail[1..9] == 20u64.to_le_bytes() && tail[29..] == *mcap::MAGIC)
}

/// Counts of what was copied, for the verification.
#[derive(Debug, Default)]
struct Copied {
    messages: u64,
    metadata: u64,
    channels: BTreeSet<u16>,
    schemas: BTreeSet<u16>,
    last_log_time_ns: Option<u64>,
    stopped: Option<String>,
}

type CopyWriter = mcap::Writer<BufWriter<File>>;

/// The writer of the repaired copy, with the original's profile and library.
fn start_writer(header: Option<mcap::records::Header>, out: File) -> mcap::McapResult<CopyWriter> {
    let (profile, library) = header.map(|h| (h.profile, h.library)).unwrap_or_default();
    mcap::WriteOptions::new()
        .profile(profile)
        .library(library)
        .compression(Some(mcap::Compression::Zstd))
        .chunk_size(Some(1024 * 1024))
        .create(BufWriter::new(out))
}

/// Copies every complete record of `src` into a new file `copy` (up to the first damage or the
/// end of the data section) and finishes it with summary, indexes and footer.
fn copy_records(src: &Path, copy: &Path) -> Result<Copied, RecoverError> {
    let read_err = |source| McapReadError::Io {
        path: src.to_path_buf(),
        source,
    };
    let write_err = |source| RecoverError::Write {
        path: copy.to_path_buf(),
        source,
    };
    let file = File::open(src).map_err(read_err)?;
    let out = File::create(copy).map_err(io_err(copy, "creating the repaired copy"))?;
    let mut stream = RecordStream::new(BufReader::with_capacity(1 << 16, file));
    let mut writer: Option<CopyWriter> = None;
    let mut out = Some(out);
    let mut c = Copied::default();
    let mut header = None;
    loop {
        let (opcode, data) = match stream.next_event().map_err(read_err)? {
            Event::Record { opcode, body } => (opcode, body),
            Event::End(End::Complete) => break,
            Event::End(End::Stopped { reason, .. }) => {
                c.stopped = Some(reason);
                break;
            }
        };
        let record = match records::parse_record(opcode, data) {
            Ok(r) => r,
            Err(e) => {
                c.stopped = Some(format!("undecodable record: {e}"));
                break;
            }
        };
        if let Record::Header(h) = record {
            header = Some(h);
            continue;
        }
        if matches!(record, Record::DataEnd(_) | Record::Footer(_)) {
            break;
        }
        let w = match &mut writer {
            Some(w) => w,
            None => {
                let out = out.take().expect("created once");
                writer.insert(start_writer(header.take(), out).map_err(write_err)?)
            }
        };
        if !copy_record(w, record, &mut c).map_err(write_err)? {
            break;
        }
    }
    let Some(mut w) = writer else {
        return Err(McapReadError::NotMcap {
            path: src.to_path_buf(),
            message: "no records".into(),
        }
        .into());
    };
    w.finish().map_err(write_err)?;
    let f = w
        .into_inner()
        .into_inner()
        .map_err(|e| io_err(copy, "writing the repaired copy")(e.into_error()))?;
    f.sync_all()
        .map_err(io_err(copy, "syncing the repaired copy"))?;
    Ok(c)
}

/// Copies one record; `Ok(false)` stops the copy (a message on an unknown channel: damage).
fn copy_record(w: &mut CopyWriter, record: Record<'_>, c: &mut Copied) -> mcap::McapResult<bool> {
    match record {
        Record::Schema { header, data } if header.id != 0 && c.schemas.insert(header.id) => {
            w.add_schema_with_id(header.id, &header.name, &header.encoding, &data)?;
        }
        Record::Channel(ch) => {
            let schema_known = ch.schema_id == 0 || c.schemas.contains(&ch.schema_id);
            if schema_known && c.channels.insert(ch.id) {
                w.add_channel_with_id(
                    ch.id,
                    ch.schema_id,
                    &ch.topic,
                    &ch.message_encoding,
                    &ch.metadata,
                )?;
            }
        }
        Record::Message { header, data } => {
            if !c.channels.contains(&header.channel_id) {
                c.stopped = Some(format!(
                    "message on unknown channel {} (damaged file)",
                    header.channel_id
                ));
                return Ok(false);
            }
            w.write_to_known_channel(&header, &data)?;
            c.messages += 1;
            c.last_log_time_ns = c.last_log_time_ns.max(Some(header.log_time));
        }
        Record::Metadata(m) => {
            w.write_metadata(&m)?;
            c.metadata += 1;
        }
        Record::Attachment { header, data, .. } => w.attach(&mcap::Attachment {
            log_time: header.log_time,
            create_time: header.create_time,
            name: header.name,
            media_type: header.media_type,
            data,
        })?,
        // Chunks arrive as their records; indexes and statistics are rebuilt by the writer.
        _ => {}
    }
    Ok(true)
}

/// Reads `copy`'s summary (as a seeking reader does) and its records front to back, and checks
/// both against what was copied.
fn verify(copy: &Path, c: &Copied) -> Result<(), String> {
    if !is_finished(copy).map_err(|e| e.to_string())? {
        return Err("no footer".into());
    }
    let mut f = File::open(copy).map_err(|e| e.to_string())?;
    let mut summary = SummaryReader::new();
    while let Some(event) = summary.next_event() {
        match event.map_err(|e| format!("summary: {e}"))? {
            SummaryReadEvent::ReadRequest(need) => {
                let n = f.read(summary.insert(need)).map_err(|e| e.to_string())?;
                summary.notify_read(n);
            }
            SummaryReadEvent::SeekRequest(to) => {
                let pos = f.seek(to).map_err(|e| e.to_string())?;
                summary.notify_seeked(pos);
            }
        }
    }
    let summary = summary.finish().ok_or("no summary section")?;
    let stats = summary.stats.ok_or("no statistics record")?;
    if stats.message_count != c.messages
        || summary.channels.len() != c.channels.len()
        || summary.schemas.len() != c.schemas.len()
        || (c.messages > 0 && summary.chunk_indexes.is_empty())
    {
        return Err(format!(
            "summary says {} messages, {} channels, {} schemas, {} chunks; copied {}, {}, {}",
            stats.message_count,
            summary.channels.len(),
            summary.schemas.len(),
            summary.chunk_indexes.len(),
            c.messages,
            c.channels.len(),
            c.schemas.len()
        ));
    }
    let report = mcap_read::for_each_message(copy, |_, _, _| Ok(())).map_err(|e| e.to_string())?;
    if let Some(why) = report.stopped_early {
        return Err(format!("reading it back stopped early: {why}"));
    }
    if report.n_messages != c.messages {
        return Err(format!(
            "read back {} messages of {}",
            report.n_messages, c.messages
        ));
    }
    Ok(())
}

/// Repairs `path` if it is unfinished (see the module doc); `Ok(None)` when it already has its
/// footer. With `keep_original` the original stays as `path.orig`.
pub fn recover(path: &Path, keep_original: bool) -> Result<Option<Recovered>, RecoverError> {
    let original_bytes = std::fs::metadata(path)
        .map_err(|source| McapReadError::Io {
            path: path.to_path_buf(),
            source,
        })?
        .len();
    if is_finished(path).map_err(io_err(path, "reading the end of the file"))? {
        return Ok(None);
    }
    let orig = with_suffix(path, ORIGINAL_SUFFIX);
    if orig.exists() {
        return Err(RecoverError::Busy {
            path: path.to_path_buf(),
            message: format!("{} exists (an earlier repair's original)", orig.display()),
        });
    }
    // Held until the swap is done: a writer (the recorder locks its file) must not be alive.
    let guard = File::open(path).map_err(io_err(path, "opening"))?;
    if let Err(std::fs::TryLockError::WouldBlock) = guard.try_lock() {
        return Err(RecoverError::Busy {
            path: path.to_path_buf(),
            message: "a live process is writing it".into(),
        });
    }
    let copy = with_suffix(path, RECOVERING_SUFFIX);
    let copied = match copy_records(path, &copy) {
        Ok(c) => c,
        Err(e) => {
            let _ = std::fs::remove_file(&copy);
            return Err(e);
        }
    };
    if let Err(message) = verify(&copy, &copied) {
        let _ = std::fs::remove_file(&copy);
        return Err(RecoverError::Verify {
            path: copy,
            message,
        });
    }
    std::fs::rename(path, &orig).map_err(io_err(path, "renaming the original to .orig"))?;
    std::fs::rename(&copy, path).map_err(io_err(&copy, "moving the repaired copy in place"))?;
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        // Make both renames durable before the original goes.
        File::open(dir)
            .and_then(|d| d.sync_all())
            .map_err(io_err(dir, "syncing the directory"))?;
    }
    drop(guard);
    let original_kept = if keep_original {
        Some(orig)
    } else {
        std::fs::remove_file(&orig).map_err(io_err(&orig, "removing the original"))?;
        None
    };
    let repaired_bytes = std::fs::metadata(path)
        .map_err(io_err(path, "reading the repaired file's size"))?
        .len();
    Ok(Some(Recovered {
        path: path.to_path_buf(),
        reason: copied
            .stopped
            .unwrap_or_else(|| "the file ends where its footer should begin".into()),
        n_messages: copied.messages,
        n_metadata: copied.metadata,
        last_log_time_ns: copied.last_log_time_ns,
        original_bytes,
        repaired_bytes,
        original_kept,
    }))
}

/// Repairs every unfinished `*.mcap` in `dir` whose name starts with `prefix` (the daemon's
/// start-up step: no process may be writing them). First finishes what an interrupted repair
/// left: a leftover `.recovering` copy is removed; an `X.mcap.orig` without `X.mcap` is put
/// back and repaired; an `X.mcap.orig` beside a finished `X.mcap` (the swap completed) is
/// removed. Returns one result per file that needed a repair, in name order.
pub fn recover_dir(
    dir: &Path,
    prefix: &str,
) -> std::io::Result<Vec<(PathBuf, Result<Recovered, RecoverError>)>> {
    let mut names: Vec<PathBuf> = std::fs::read_dir(dir)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with(prefix) && n.contains(".mcap"))
        })
        .collect();
    names.sort();
    let mut mcaps = BTreeSet::new();
    for p in &names {
        let name = p.to_string_lossy();
        if name.ends_with(RECOVERING_SUFFIX) {
            std::fs::remove_file(p)?;
        } else if let Some(stem) = name.strip_suffix(ORIGINAL_SUFFIX) {
            let stem = PathBuf::from(stem);
            if !stem.exists() {
                std::fs::rename(p, &stem)?;
                mcaps.insert(stem);
            } else if is_finished(&stem)? {
                std::fs::remove_file(p)?;
            }
        } else if name.ends_with(".mcap") {
            mcaps.insert(p.clone());
        }
    }
    let mut out = Vec::new();
    for p in mcaps {
        match recover(&p, false) {
            Ok(None) => {}
            Ok(Some(r)) => out.push((p, Ok(r))),
            Err(e) => out.push((p, Err(e))),
        }
    }
    Ok(out)
}
