//! Repairing unfinished recordings (`imu_rec::recover`): what a kill leaves (every flushed
//! byte, or a cut in the middle of a chunk) is rewritten with summary, indexes and footer,
//! keeping every complete record; Python `mcap`'s default `make_reader(f).iter_messages()` and
//! `rosbags` then read it; the original is never lost on the way.

mod recording_common;

use std::path::{Path, PathBuf};

use imu_rec::mcap_read::for_each_message;
use imu_rec::recording::{Recorder, read_recording};
use imu_rec::recover::{self, RecoverError};
use recording_common::*;

/// A live recording of 200 samples in four flushed chunks, copied as a SIGKILL would leave it
/// (`snapshot.mcap`), and the same cut three quarters of the way (`cut.mcap`: mid-chunk).
fn unfinished_files(dir: &Path) -> (PathBuf, PathBuf) {
    let rec = Recorder::start(test_config(dir), Vec::new()).unwrap();
    let mut n = 0;
    for batch in 0..4 {
        for r in mixed(batch * 50, 50) {
            assert!(rec.log(r));
            n += 1;
        }
        wait_until("the batch is flushed", || rec.stats().flushed == n);
    }
    let live = rec.stats().current_file.unwrap();
    let snapshot = dir.join("snapshot.mcap");
    std::fs::copy(&live, &snapshot).unwrap();
    let bytes = std::fs::read(&snapshot).unwrap();
    let cut = dir.join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 3 / 4]).unwrap();
    rec.finish().unwrap();
    std::fs::remove_file(live).unwrap();
    (snapshot, cut)
}

#[test]
fn a_killed_recording_is_repaired_with_every_complete_record() {
    let dir = tempfile::tempdir().unwrap();
    let (snapshot, cut) = unfinished_files(dir.path());
    for file in [&snapshot, &cut] {
        let before = read_recording(file).unwrap();
        let tolerant = for_each_message(file, |_, _, _| Ok(())).unwrap();
        let unfinished = tolerant.unfinished.clone().expect("no footer");
        assert!(unfinished.footer_missing, "{unfinished:?}");
        assert_eq!(unfinished.n_messages, tolerant.n_messages);
        assert!(!recover::is_finished(file).unwrap());

        let python_before = run_peer("recording_default_read.py", &[file.as_os_str()]);
        if let Some(out) = &python_before {
            assert!(
                !out["error"].is_null(),
                "the unrepaired file should defeat the default reader: {out}"
            );
        }

        let done = recover::recover(file, true)
            .unwrap()
            .expect("it was unfinished");
        assert_eq!(
            done.n_messages, tolerant.n_messages,
            "every complete record kept"
        );
        assert_eq!(done.last_log_time_ns, unfinished.last_log_time_ns);
        assert!(recover::is_finished(file).unwrap());
        let orig = done.original_kept.clone().unwrap();
        assert_eq!(orig, PathBuf::from(format!("{}.orig", file.display())));
        assert_eq!(std::fs::metadata(&orig).unwrap().len(), done.original_bytes);

        let after = read_recording(file).unwrap();
        assert_eq!(after.stopped_early, None);
        assert_eq!(after.raw, before.raw);
        assert_eq!(after.frames, before.frames);
        assert_eq!(after.metadata, before.metadata);
        // Finished now: a second repair has nothing to do.
        assert_eq!(recover::recover(file, false).unwrap(), None);

        let Some(out) = run_peer("recording_default_read.py", &[file.as_os_str()]) else {
            continue;
        };
        assert!(out["error"].is_null(), "{out}");
        let total: u64 = out["count"]
            .as_object()
            .unwrap()
            .values()
            .map(|v| v.as_u64().unwrap())
            .sum();
        assert_eq!(total, tolerant.n_messages);
        let seqs: Vec<u64> = before.raw.iter().map(|s| s.seq).collect();
        assert_eq!(out["raw_seq"], serde_json::json!(seqs));
        assert_eq!(
            out["last_log_time_ns"].as_u64(),
            unfinished.last_log_time_ns
        );
        if let Some(bag) = run_peer("recording_rosbags.py", &[file.as_os_str()]) {
            assert_eq!(bag["raw_seq"], serde_json::json!(seqs));
        }
    }
}

#[test]
fn a_directory_is_repaired_and_interrupted_repairs_are_finished() {
    let dir = tempfile::tempdir().unwrap();
    let (snapshot, cut) = unfinished_files(dir.path());
    let n_snapshot = read_recording(&snapshot).unwrap().raw.len();
    let n_cut = read_recording(&cut).unwrap().raw.len();
    let name = |f: &str| dir.path().join(f);
    // A repair that died after moving the original aside, and one that died while copying.
    std::fs::rename(&snapshot, name("test-a.mcap.orig")).unwrap();
    std::fs::rename(&cut, name("test-b.mcap")).unwrap();
    std::fs::write(name("test-b.mcap.recovering"), b"half a copy").unwrap();
    // Not ours (another instance's prefix), and not MCAP at all.
    std::fs::copy(name("test-b.mcap"), name("other-c.mcap")).unwrap();
    std::fs::write(name("test-d.mcap"), b"").unwrap();

    let results = recover::recover_dir(dir.path(), "test-").unwrap();
    let paths: Vec<&Path> = results.iter().map(|(p, _)| p.as_path()).collect();
    assert_eq!(
        paths,
        [
            name("test-a.mcap"),
            name("test-b.mcap"),
            name("test-d.mcap")
        ]
    );
    assert!(results[0].1.is_ok() && results[1].1.is_ok());
    assert!(
        matches!(&results[2].1, Err(RecoverError::Read(_))),
        "{:?}",
        results[2].1
    );
    assert_eq!(
        read_recording(&name("test-a.mcap")).unwrap().raw.len(),
        n_snapshot
    );
    assert_eq!(
        read_recording(&name("test-b.mcap")).unwrap().raw.len(),
        n_cut
    );
    for gone in [
        "test-a.mcap.orig",
        "test-b.mcap.orig",
        "test-b.mcap.recovering",
    ] {
        assert!(!name(gone).exists(), "{gone} left behind");
    }
    assert!(!recover::is_finished(&name("other-c.mcap")).unwrap());
    assert!(
        name("test-d.mcap").exists(),
        "an unreadable file is left as it is"
    );
}

#[test]
fn a_file_a_live_recorder_writes_is_left_alone() {
    let dir = tempfile::tempdir().unwrap();
    let rec = Recorder::start(test_config(dir.path()), Vec::new()).unwrap();
    let records = mixed(0, 20);
    let n = records.len() as u64;
    for r in records {
        assert!(rec.log(r));
    }
    wait_until("flushed", || rec.stats().flushed == n);
    let live = rec.stats().current_file.unwrap();
    let err = recover::recover(&live, false).unwrap_err();
    assert!(matches!(err, RecoverError::Busy { .. }), "{err}");
    let stats = rec.finish().unwrap();
    assert_eq!(read_recording(&live).unwrap().raw.len(), 20, "{stats:?}");
}
