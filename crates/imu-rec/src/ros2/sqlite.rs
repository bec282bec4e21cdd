//! rosbag2's sqlite3 storage (`.db3`, the default up to Humble): its `topics` and `messages`
//! tables read in insertion order (the order the recorder wrote, as an MCAP is read in file
//! order), one row at a time, so memory stays bounded by one message. Messages compressed one
//! by one (`compression_mode: message`, zstd) are told by their zstd magic and decompressed;
//! CDR never starts with it. A whole file compressed (`compression_mode: file`, `x.db3.zstd`) is
//! decompressed first ([`super::bag::decompress_zstd_file`]).
//!
//! SQLite through `rusqlite` with its bundled library, so nothing is needed on the machine.

use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};

use rusqlite::{Connection, OpenFlags};

/// The first 16 bytes of every SQLite 3 database.
pub const SQLITE_MAGIC: &[u8; 16] = b"SQLite format 3\0";
/// The first 4 bytes of a zstd frame.
pub const ZSTD_MAGIC: [u8; 4] = [0x28, 0xB5, 0x2F, 0xFD];

/// What went wrong reading a `.db3` file (every error names the file the user gave).
#[derive(Debug, thiserror::Error)]
pub enum Db3Error {
    /// The file could not be opened or read.
    #[error("{path}: cannot read")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// SQLite refused the file or a query.
    #[error("{path}: sqlite3 storage: {what}")]
    Sqlite {
        /// The file.
        path: PathBuf,
        /// What was being done.
        what: String,
        /// SQLite's error.
        #[source]
        source: rusqlite::Error,
    },
    /// An SQLite database, but not rosbag2's.
    #[error("{path}: not a rosbag2 sqlite3 file: {message}")]
    NotBag {
        /// The file.
        path: PathBuf,
        /// What is missing.
        message: String,
    },
    /// The caller's message handler refused a message (or it could not be decompressed).
    #[error("{path}: topic {topic}, message {id} at time {time_ns} ns: {message}")]
    Message {
        /// The file.
        path: PathBuf,
        /// The message's topic.
        topic: String,
        /// The message row's id.
        id: i64,
        /// The message's timestamp.
        time_ns: u64,
        /// What went wrong.
        message: String,
    },
}

/// A topic as the `topics` table lists it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Db3Topic {
    /// Row id, what messages refer to.
    pub id: i64,
    /// Topic name.
    pub name: String,
    /// ROS 2 message type, e.g. `sensor_msgs/msg/Imu`.
    pub msg_type: String,
    /// `cdr` for every ROS 2 middleware.
    pub serialization_format: String,
}

/// What a read saw besides the messages.
#[derive(Debug, Clone, Default)]
pub struct Db3Report {
    /// Messages handed to the handler.
    pub n_messages: u64,
    /// Topics, by id.
    pub topics: BTreeMap<i64, Db3Topic>,
}

/// True if `path` starts with `magic`.
pub fn starts_with(path: &Path, magic: &[u8]) -> std::io::Result<bool> {
    let mut head = vec![0u8; magic.len()];
    let mut f = std::fs::File::open(path)?;
    let mut n = 0;
    while n < head.len() {
        match f.read(&mut head[n..])? {
            0 => break,
            k => n += k,
        }
    }
    Ok(n == head.len() && head == magic)
}

/// True if `path` is an SQLite database (by its first bytes).
pub fn has_sqlite_magic(path: &Path) -> std::io::Result<bool> {
    starts_with(path, SQLITE_MAGIC)
}

/// Reads every message of the `.db3` file at `path` in insertion order, decompressing
/// zstd-compressed messages, and hands each to `on_message` with its topic and timestamp (ns).
/// `shown` is the file errors name (the `.db3.zstd` a decompressed copy came from).
/// `on_progress` gets `(bytes, file size)` estimated from the message ids read.
pub fn for_each_message_with_progress(
    path: &Path,
    shown: &Path,
    on_progress: &mut dyn FnMut(u64, u64),
    mut on_message: impl FnMut(&Db3Topic, u64, &[u8]) -> Result<(), String>,
) -> Result<Db3Report, Db3Error> {
    let sql = |what: &str| {
        let what = what.to_string();
        move |source| Db3Error::Sqlite {
            path: shown.to_path_buf(),
            what,
            source,
        }
    };
    let size = std::fs::metadata(path)
        .map_err(|source| Db3Error::Io {
            path: shown.to_path_buf(),
            source,
        })?
        .len();
    on_progress(0, size);
    let db = Connection::open_with_flags(
        path,
        OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
    )
    .map_err(sql("cannot open"))?;
    let report = Db3Report {
        topics: topics(&db, shown)?,
        ..Db3Report::default()
    };
    let max_id: i64 = db
        .query_row("SELECT coalesce(max(id), 0) FROM messages", [], |r| {
            r.get(0)
        })
        .map_err(sql("no messages table"))?;
    let mut stmt = db
        .prepare("SELECT id, topic_id, timestamp, data FROM messages ORDER BY id")
        .map_err(sql("cannot query messages"))?;
    let mut rows = stmt.query([]).map_err(sql("cannot query messages"))?;
    let mut report = report;
    let mut plain = Vec::new();
    while let Some(row) = rows.next().map_err(sql("cannot read a message"))? {
        let id: i64 = row.get(0).map_err(sql("message id"))?;
        let topic_id: i64 = row.get(1).map_err(sql("message topic_id"))?;
        let time_ns = row
            .get::<_, i64>(2)
            .map_err(sql("message timestamp"))?
            .max(0) as u64;
        let data = row
            .get_ref(3)
            .and_then(|v| v.as_blob().map_err(Into::into))
            .map_err(sql("message data"))?;
        let fail = |topic: &str, message: String| Db3Error::Message {
            path: shown.to_path_buf(),
            topic: topic.to_string(),
            id,
            time_ns,
            message,
        };
        let Some(topic) = report.topics.get(&topic_id) else {
            return Err(fail(
                &format!("id {topic_id}"),
                "refers to no row of the topics table".into(),
            ));
        };
        let data = if data.starts_with(&ZSTD_MAGIC) {
            plain.clear();
            zstd::stream::copy_decode(data, &mut plain)
                .map_err(|e| fail(&topic.name, format!("zstd: {e}")))?;
            &plain[..]
        } else {
            data
        };
        on_message(topic, time_ns, data).map_err(|m| fail(&topic.name, m))?;
        report.n_messages += 1;
        if report.n_messages.is_multiple_of(4096) && max_id > 0 {
            on_progress(
                ((size as f64 * id as f64 / max_id as f64) as u64).min(size),
                size,
            );
        }
    }
    on_progress(size, size);
    Ok(report)
}

/// The `topics` table.
fn topics(db: &Connection, shown: &Path) -> Result<BTreeMap<i64, Db3Topic>, Db3Error> {
    let has = |table: &str| -> bool {
        db.query_row(
            "SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name = ?1",
            [table],
            |r| r.get::<_, i64>(0),
        )
        .is_ok_and(|n| n > 0)
    };
    for table in ["topics", "messages"] {
        if !has(table) {
            return Err(Db3Error::NotBag {
                path: shown.to_path_buf(),
                message: format!("an SQLite database without a `{table}` table"),
            });
        }
    }
    let sql = |source| Db3Error::Sqlite {
        path: shown.to_path_buf(),
        what: "cannot read the topics table".into(),
        source,
    };
    let mut stmt = db
        .prepare("SELECT id, name, type, serialization_format FROM topics")
        .map_err(sql)?;
    let rows = stmt
        .query_map([], |r| {
            Ok(Db3Topic {
                id: r.get(0)?,
                name: r.get(1)?,
                msg_type: r.get(2)?,
                serialization_format: r.get(3)?,
            })
        })
        .map_err(sql)?;
    let mut out = BTreeMap::new();
    for t in rows {
        let t = t.map_err(sql)?;
        out.insert(t.id, t);
    }
    Ok(out)
}
