//! What the evaluation programs share: reading a folder of images, loading the models, and
//! turning a run's result into an exit code.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use burn::tensor::Device;
use infer::models::{BUILT_IN_COARSE, BUILT_IN_REFINE, ModelSource, Models, ModelsError, bundled};

/// Prints a failed run's error and gives the exit code: 0 on success, 1 on error.
pub fn finish(result: anyhow::Result<()>) -> ExitCode {
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            ExitCode::FAILURE
        }
    }
}

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

/// Both models, from the given checkpoints or the bundled ones ([`Models::identities`] says
/// which).
pub fn load_models(
    coarse: Option<&Path>,
    refine: Option<&Path>,
    device: &Device,
) -> Result<Models, ModelsError> {
    let source = |path: Option<&Path>, built_in| match path {
        Some(path) => Ok(ModelSource::File(path.to_path_buf())),
        None => bundled(built_in),
    };
    let coarse = source(coarse, &BUILT_IN_COARSE)?;
    let refine = source(refine, &BUILT_IN_REFINE)?;
    Ok(Models::from_sources(&coarse, Some(&refine), device)?)
}
