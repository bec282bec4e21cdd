//! Reading and writing a corpus directory: one input per file, read in file-name order so a run
//! is reproducible.

use std::fs;
use std::path::Path;

use anyhow::{Context, Result};

/// Every file in `dir`, in file-name order (subdirectories and hidden files skipped).
pub fn load(dir: &Path) -> Result<Vec<Vec<u8>>> {
    let entries = fs::read_dir(dir).with_context(|| format!("reading corpus {}", dir.display()))?;
    let mut paths = Vec::new();
    for entry in entries {
        let entry = entry.with_context(|| format!("reading corpus {}", dir.display()))?;
        let hidden = entry.file_name().to_string_lossy().starts_with('.');
        if entry.file_type()?.is_file() && !hidden {
            paths.push(entry.path());
        }
    }
    paths.sort();
    paths
        .iter()
        .map(|p| fs::read(p).with_context(|| format!("reading corpus file {}", p.display())))
        .collect()
}

/// Writes `inputs` into `dir` as `<prefix>-NNNN` files (created if missing).
pub fn store(dir: &Path, prefix: &str, inputs: &[Vec<u8>]) -> Result<()> {
    fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    for (i, input) in inputs.iter().enumerate() {
        let path = dir.join(format!("{prefix}-{i:04}"));
        fs::write(&path, input).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}
