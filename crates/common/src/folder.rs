//! The files of a folder of inputs, in a stable order: what the evaluation programs and the
//! benchmarks read.

use std::path::{Path, PathBuf};

/// A folder of images that could not be listed.
#[derive(Debug, thiserror::Error)]
#[error("{}: {source}", dir.display())]
pub struct ListError {
    /// The folder.
    pub dir: PathBuf,
    /// Why.
    pub source: std::io::Error,
}

/// The files directly in `dir`, sorted (whether they are images is for the decoder to say).
pub fn files_in(dir: &Path) -> Result<Vec<PathBuf>, ListError> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|source| ListError { dir: dir.to_path_buf(), source })?
        .filter_map(|entry| entry.ok().map(|e| e.path()))
        .filter(|path| path.is_file())
        .collect();
    files.sort();
    Ok(files)
}
