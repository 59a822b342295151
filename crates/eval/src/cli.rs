//! What the evaluation programs share: loading the models and turning a run's result into an
//! exit code (a folder's images are listed by [`common::folder::files_in`]).

use std::path::Path;
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
