//! What the file readers' targets share. An input is `[cut (u16, little-endian), file...]`: the
//! file is read whole and cut to `cut % (len + 1)` bytes, each through a file of its own (the
//! readers take paths); the cut file's messages must be the first messages of the whole file's,
//! in order (nothing after damage is made up, nothing before it is lost where the whole file
//! gave it), and a cut of a file that reads completely must be named (an error, or the read
//! stopped early with `Unfinished`) unless it lost nothing (bytes after the end magic).
//!
//! One exception, where the whole file's read stopped at damage that a checksum at the end of a
//! unit found (an MCAP chunk whose CRC disagrees: none of its messages is delivered): a cut
//! inside that unit removes the checksum, so the cut file's read delivers the unit's messages
//! up to the cut, as for any chunk a killed writer left unfinished. Then the whole file's
//! messages must be the first of the cut file's instead.

use std::cell::RefCell;
use std::path::{Path, PathBuf};

/// One message a reader handed over.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) struct Message {
    /// Its topic.
    pub topic: String,
    /// Its type (ROS 1, ROS 2) or schema name (MCAP).
    pub msg_type: String,
    /// Its log or record time, ns.
    pub time_ns: u64,
    /// Its bytes.
    pub data: Vec<u8>,
}

/// What a read gave.
#[derive(Debug, Clone)]
pub(crate) struct Read {
    /// The messages, in the order handed over.
    pub messages: Vec<Message>,
    /// `Ok(None)`: read to the end; `Ok(Some(why))`: stopped early at damage; `Err(what)`: the
    /// reader refused the file.
    pub outcome: Result<Option<String>, String>,
}

/// A reader's outcome from its result (`n_messages`, `stopped_early`, `unfinished` set), after
/// checking that its report counts the `handed` messages and sets `Unfinished` exactly when the
/// read stopped early.
pub(crate) fn outcome<E: std::fmt::Display>(
    result: Result<(u64, Option<String>, bool), E>,
    handed: usize,
) -> Result<Option<String>, String> {
    let (n_messages, stopped_early, unfinished) = result.map_err(|e| e.to_string())?;
    assert_eq!(
        n_messages, handed as u64,
        "the report counts what was handed over"
    );
    assert_eq!(
        stopped_early.is_some(),
        unfinished,
        "Unfinished is set exactly when the read stopped early"
    );
    Ok(stopped_early)
}

/// The input of a file reader's target: `file` read whole and cut at `cut`.
pub(crate) fn with_cut(cut: usize, file: &[u8]) -> Vec<u8> {
    let cut = u16::try_from(cut).unwrap_or(u16::MAX);
    [&cut.to_le_bytes()[..], file].concat()
}

/// The cut and the file of an input.
pub(crate) fn split_cut(data: &[u8]) -> Option<(usize, &[u8])> {
    let (cut, file) = data.split_at_checked(2)?;
    let cut = usize::from(u16::from_le_bytes([cut[0], cut[1]]));
    Some((cut % (file.len() + 1), file))
}

thread_local! {
    /// A directory per thread for the files the readers open (removed when the thread ends).
    static DIR: RefCell<Option<tempfile::TempDir>> = const { RefCell::new(None) };
}

/// Writes `bytes` to this thread's file `name` and hands its path to `read`.
pub(crate) fn through_file<R>(name: &str, bytes: &[u8], read: impl FnOnce(&Path) -> R) -> R {
    let path: PathBuf = DIR.with(|dir| {
        let mut dir = dir.borrow_mut();
        let dir = dir.get_or_insert_with(|| {
            // A file system in memory where there is one: two files are written per input.
            let shm = Path::new("/dev/shm");
            let parent = if shm.is_dir() {
                shm.to_path_buf()
            } else {
                std::env::temp_dir()
            };
            tempfile::Builder::new()
                .prefix("imu-fuzz-")
                .tempdir_in(parent)
                .expect("the fuzz harness needs a temporary directory")
        });
        dir.path().join(name)
    });
    std::fs::write(&path, bytes).expect("the fuzz harness writes its temporary files");
    read(&path)
}

/// The checks of a file reader (see the module docs); `read` reads one file's bytes.
pub(crate) fn check_cut(data: &[u8], read: fn(&[u8]) -> Read) {
    let Some((cut, file)) = split_cut(data) else {
        return;
    };
    let whole = read(file);
    let part = read(&file[..cut]);
    for r in [&whole, &part] {
        if let Err(e) | Ok(Some(e)) = &r.outcome {
            assert!(!e.is_empty(), "damage is named");
        }
    }
    if cut < file.len() && whole.outcome == Ok(None) && part.outcome == Ok(None) {
        // Only bytes the reader does not need (after the end magic) may go unnoticed.
        assert!(
            part.messages == whole.messages,
            "a file cut at {cut} of {} bytes reads as complete with {} of {} messages",
            file.len(),
            part.messages.len(),
            whole.messages.len()
        );
    }
    if whole.outcome.is_ok() && part.outcome.is_ok() {
        let whole_stopped_at_damage = matches!(whole.outcome, Ok(Some(_)));
        assert!(
            whole.messages.starts_with(&part.messages)
                || (whole_stopped_at_damage && part.messages.starts_with(&whole.messages)),
            "a file cut at {cut} gives {} messages that are not the first of the whole file's {}",
            part.messages.len(),
            whole.messages.len()
        );
    }
}
