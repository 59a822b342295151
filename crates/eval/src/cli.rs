//! What the evaluation programs share: reading a folder of images, loading the models, and
//! turning a run's result into an exit code.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use burn::tensor::Device;
use infer::models::{Models, bundled};

/// Prints a failed run's error and gives the exit code: 0 on success, 1 on error.
pub fn finish(result: Result<(), String>) -> ExitCode {
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err}");
            ExitCode::FAILURE
        }
    }
}

/// The files directly in `dir`, sorted (whether they are images is for the decoder to say).
pub fn files_in(dir: &Path) -> Result<Vec<PathBuf>, String> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|err| format!("{}: {err}", dir.display()))?
        .filter_map(|entry| entry.ok().map(|e| e.path()))
        .filter(|path| path.is_file())
        .collect();
    files.sort();
    Ok(files)
}

/// Both models, from the given checkpoints or the bundled ones, with the files they came from.
pub fn load_models(
    coarse: Option<&Path>,
    refine: Option<&Path>,
    device: &Device,
) -> Result<(Models, PathBuf, PathBuf), String> {
    let coarse = coarse.map_or_else(|| bundled("coarse.ckpt"), |p| Ok(p.to_path_buf()))?;
    let refine = refine.map_or_else(|| bundled("refine.ckpt"), |p| Ok(p.to_path_buf()))?;
    let models = Models::load(&coarse, Some(&refine), device).map_err(|err| err.to_string())?;
    Ok((models, coarse, refine))
}
