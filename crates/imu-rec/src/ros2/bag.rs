//! rosbag2 directories: the files a bag's `metadata.yaml` lists, in order, so a bag is read as
//! one recording (MCAP or sqlite3 storage, `sqlite.rs`). Only the keys a reader needs are read
//! (`storage_identifier`, `relative_file_paths`, `compression_format`), each from its own line,
//! in the block layout rosbag2 and `rosbags` write; anything else in the file is ignored. A file
//! compressed whole (`compression_mode: file`, zstd) is decompressed into a temporary file by
//! [`decompress_zstd_file`]; each file's format is then told by its content.

use std::path::{Path, PathBuf};

/// The name of a bag's metadata file inside its directory.
pub const BAG_METADATA: &str = "metadata.yaml";

/// Why a directory could not be read as a rosbag2 bag.
#[derive(Debug, thiserror::Error)]
pub enum BagError {
    /// The metadata file could not be read.
    #[error("{path}: cannot read")]
    Io {
        /// The metadata file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The metadata file does not say what a reader needs, or says something it cannot read.
    #[error("{path}:{line}: {message}")]
    Metadata {
        /// The metadata file.
        path: PathBuf,
        /// 1-based line (0: the file as a whole).
        line: usize,
        /// What is wrong and what to do.
        message: String,
    },
}

/// The data files of a bag, in the order its metadata lists them.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BagFiles {
    /// The storage plugin (`mcap` or `sqlite3`).
    pub storage: String,
    /// The files, as paths under the bag directory.
    pub files: Vec<PathBuf>,
}

/// True if `dir` is a rosbag2 directory (holds a `metadata.yaml`).
pub fn is_bag_dir(dir: &Path) -> bool {
    dir.is_dir() && dir.join(BAG_METADATA).is_file()
}

/// Reads `dir/metadata.yaml`: the storage plugin (MCAP or sqlite3) and the files.
pub fn bag_files(dir: &Path) -> Result<BagFiles, BagError> {
    let path = dir.join(BAG_METADATA);
    let text = std::fs::read_to_string(&path).map_err(|source| BagError::Io {
        path: path.clone(),
        source,
    })?;
    let bad = |(line, message): (usize, String)| BagError::Metadata {
        path: path.clone(),
        line,
        message,
    };
    let Metadata {
        storage,
        files,
        compression,
    } = parse_metadata(&text).map_err(bad)?;
    if let Some((line, format)) = compression.filter(|(_, f)| !f.is_empty() && f != "zstd") {
        return Err(bad((
            line,
            format!("compression_format `{format}`: only zstd (rosbag2's only one) is read"),
        )));
    }
    let storage = storage.ok_or_else(|| {
        bad((
            0,
            "no `storage_identifier`: is this a rosbag2 metadata file?".into(),
        ))
    })?;
    if storage != "mcap" && storage != "sqlite3" {
        return Err(bad((
            0,
            format!(
                "storage `{storage}`: MCAP and sqlite3 bags are read (convert with `ros2 bag \
                 convert`, output storage_id mcap)"
            ),
        )));
    }
    if files.is_empty() {
        return Err(bad((0, "`relative_file_paths` lists no file".into())));
    }
    let mut out = Vec::with_capacity(files.len());
    for (line, f) in files {
        let p = dir.join(&f);
        if !p.is_file() {
            return Err(bad((
                line,
                format!("listed file `{f}` is not in {}", dir.display()),
            )));
        }
        out.push(p);
    }
    Ok(BagFiles {
        storage,
        files: out,
    })
}

/// Decompresses a zstd-compressed file (a rosbag2 file compressed whole) into a temporary
/// file, streaming (memory bounded by zstd's window), and returns it; it is removed when
/// dropped.
pub fn decompress_zstd_file(path: &Path) -> Result<tempfile::NamedTempFile, BagError> {
    let io = |source| BagError::Io {
        path: path.to_path_buf(),
        source,
    };
    let input = std::fs::File::open(path).map_err(io)?;
    let mut out = tempfile::Builder::new()
        .prefix("imud-bag-")
        .tempfile()
        .map_err(io)?;
    let mut writer = std::io::BufWriter::with_capacity(1 << 20, out.as_file_mut());
    zstd::stream::copy_decode(std::io::BufReader::new(input), &mut writer).map_err(|e| {
        BagError::Metadata {
            path: path.to_path_buf(),
            line: 0,
            message: format!("cannot decompress (zstd): {e}"),
        }
    })?;
    std::io::Write::flush(&mut writer).map_err(io)?;
    drop(writer);
    Ok(out)
}

/// What a reader takes from `metadata.yaml`.
#[derive(Debug, Default)]
struct Metadata {
    storage: Option<String>,
    /// The listed files with their 1-based lines.
    files: Vec<(usize, String)>,
    /// `compression_format` and its line.
    compression: Option<(usize, String)>,
}

/// The keys a reader needs; an error is a line and what is wrong there.
fn parse_metadata(text: &str) -> Result<Metadata, (usize, String)> {
    let (mut storage, mut files, mut compression) = (None, Vec::new(), None);
    let mut in_files: Option<usize> = None;
    for (i, raw) in text.lines().enumerate() {
        let indent = raw.len() - raw.trim_start().len();
        let line = raw.trim();
        if let Some(key_indent) = in_files {
            // Block sequence items sit at the key's indentation or deeper.
            if let Some(item) = line.strip_prefix("- ").filter(|_| indent >= key_indent) {
                files.push((i + 1, unquote(item).to_string()));
                continue;
            }
            in_files = None;
        }
        if let Some(v) = line.strip_prefix("storage_identifier:") {
            storage = Some(unquote(v.trim()).to_string());
        } else if let Some(v) = line.strip_prefix("compression_format:") {
            compression = Some((i + 1, unquote(v.trim()).to_string()));
        } else if let Some(v) = line.strip_prefix("relative_file_paths:") {
            match v.trim() {
                "" => in_files = Some(indent),
                flow => {
                    let Some(inner) = flow.strip_prefix('[').and_then(|f| f.strip_suffix(']'))
                    else {
                        return Err((i + 1, format!("cannot read `{flow}` as a list of files")));
                    };
                    files.extend(
                        inner
                            .split(',')
                            .map(|f| unquote(f.trim()))
                            .filter(|f| !f.is_empty())
                            .map(|f| (i + 1, f.to_string())),
                    );
                }
            }
        }
    }
    Ok(Metadata {
        storage,
        files,
        compression,
    })
}

fn unquote(s: &str) -> &str {
    s.strip_prefix('\'')
        .and_then(|s| s.strip_suffix('\''))
        .or_else(|| s.strip_prefix('"').and_then(|s| s.strip_suffix('"')))
        .unwrap_or(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn block_and_flow_lists_and_refusals() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::write(d.join("b_0.mcap"), b"x").unwrap();
        std::fs::write(d.join("b_1.mcap"), b"x").unwrap();
        let meta = d.join(BAG_METADATA);
        assert!(!is_bag_dir(d));
        std::fs::write(
            &meta,
            "rosbag2_bagfile_information:\n  files:\n  - path: b_0.mcap\n  relative_file_paths:\n  \
             - b_0.mcap\n  - 'b_1.mcap'\n  storage_identifier: mcap\n  version: 9\n",
        )
        .unwrap();
        assert!(is_bag_dir(d));
        let b = bag_files(d).unwrap();
        assert_eq!(b.files, vec![d.join("b_0.mcap"), d.join("b_1.mcap")]);
        std::fs::write(
            &meta,
            "x:\n  storage_identifier: mcap\n  relative_file_paths: [b_1.mcap, b_0.mcap]\n",
        )
        .unwrap();
        assert_eq!(
            bag_files(d).unwrap().files,
            vec![d.join("b_1.mcap"), d.join("b_0.mcap")]
        );
        std::fs::write(d.join("b.db3"), b"x").unwrap();
        std::fs::write(
            &meta,
            "x:\n  storage_identifier: sqlite3\n  relative_file_paths:\n  - b.db3\n",
        )
        .unwrap();
        assert_eq!(bag_files(d).unwrap().storage, "sqlite3");
        std::fs::write(
            &meta,
            "x:\n  storage_identifier: rosbag_v2\n  relative_file_paths:\n  - b.db3\n",
        )
        .unwrap();
        let e = bag_files(d).unwrap_err().to_string();
        assert!(
            e.contains("storage `rosbag_v2`") && e.contains("metadata.yaml"),
            "{e}"
        );
        std::fs::write(
            &meta,
            "x:\n  storage_identifier: sqlite3\n  compression_format: lz4\n  \
             relative_file_paths:\n  - b.db3\n",
        )
        .unwrap();
        let e = bag_files(d).unwrap_err().to_string();
        assert!(e.contains("metadata.yaml:3:") && e.contains("`lz4`"), "{e}");
        std::fs::write(
            &meta,
            "x:\n  storage_identifier: mcap\n  relative_file_paths:\n  - gone.mcap\n",
        )
        .unwrap();
        let e = bag_files(d).unwrap_err().to_string();
        assert!(
            e.contains("metadata.yaml:4:") && e.contains("gone.mcap"),
            "{e}"
        );
    }
}
