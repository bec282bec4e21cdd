//! Shared helpers for the end-to-end tests: where the repository's config files live, a
//! process's resident memory, and a recording's summary.

use std::path::PathBuf;

/// The repository root (the parent of this crate).
pub fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}

/// Every file with the given extension under `config/<sub>`, sorted.
pub fn config_files(sub: &str, ext: &str) -> Vec<PathBuf> {
    let dir = repo_root().join("config").join(sub);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.expect("readable directory entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == ext))
        .collect();
    files.sort();
    files
}

/// Resident memory of process `pid`, KiB (`VmRSS`); `None` once it is gone.
pub fn rss_kib(pid: u32) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// The summary of the finished MCAP file `f`, which must hold a chunk index (panics naming the
/// file otherwise).
pub fn summary_with_chunk_index(f: &std::path::Path) -> mcap::Summary {
    let bytes = std::fs::read(f).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
    let summary = mcap::Summary::read(&bytes)
        .unwrap_or_else(|e| panic!("{}: {e}", f.display()))
        .unwrap_or_else(|| panic!("{}: no summary", f.display()));
    assert!(
        !summary.chunk_indexes.is_empty(),
        "{}: no chunk index",
        f.display()
    );
    summary
}
