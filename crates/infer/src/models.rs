//! The two networks inference runs, and where the bundled ones are found.

use std::path::{Path, PathBuf};

use burn::tensor::Device;
use model::{
    Checkpoint, CheckpointError, CoarseModel, MismatchProblem, ModelConfig, OperatingPoint, RefineModel,
    Stage,
};

/// The trained networks, ready for inference.
pub struct Models {
    /// E_c.
    pub coarse: CoarseModel,
    /// E_r; without it the result has only coarse paths.
    pub refine: Option<RefineModel>,
    /// Their configuration (architecture and input contract).
    pub config: ModelConfig,
    /// How a path budget is split between regions, E_c and E_r: the one measured for these
    /// models and stored in the coarse checkpoint, or [`OperatingPoint::default`].
    pub operating_point: OperatingPoint,
}

impl Models {
    /// Loads E_c from `coarse` and, if given, E_r from `refine` (both must share a configuration).
    pub fn load(coarse: &Path, refine: Option<&Path>, device: &Device) -> Result<Self, CheckpointError> {
        let checkpoint = Checkpoint::load(coarse)?;
        checkpoint.expect_stage(Stage::Coarse, coarse)?;
        let config = checkpoint.model_config.clone();
        let operating_point = checkpoint.inference.unwrap_or_default();
        let coarse_model = checkpoint.apply(CoarseModel::new(&config, device), coarse)?;
        let refine = match refine {
            None => None,
            Some(path) => {
                let checkpoint = Checkpoint::load(path)?;
                checkpoint.expect_stage(Stage::Refine, path)?;
                if checkpoint.model_config != config {
                    return Err(CheckpointError::Mismatch {
                        path: path.to_path_buf(),
                        problem: MismatchProblem::ConfigDiffers(coarse.to_path_buf()),
                    });
                }
                Some(checkpoint.apply(RefineModel::new(&config, device), path)?)
            }
        };
        Ok(Self { coarse: coarse_model, refine, config, operating_point })
    }
}

/// Environment variable naming a folder with `coarse.ckpt` and `refine.ckpt`.
pub const MODELS_ENV: &str = "SUPERSVG_MODELS";

/// Why the models could not be found or loaded.
#[derive(Debug, thiserror::Error)]
pub enum ModelsError {
    /// `$SUPERSVG_MODELS` is set but the folder has no such file.
    #[error("{MODELS_ENV}={} has no {name}", dir.display())]
    NotInEnv {
        /// The folder the variable names.
        dir: PathBuf,
        /// The file looked for.
        name: String,
    },
    /// No bundled checkpoint in any of the places looked in.
    #[error(
        "no bundled {name} (looked in {}); pass it explicitly or set {MODELS_ENV} to its folder",
        looked.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", ")
    )]
    NotFound {
        /// The file looked for.
        name: String,
        /// The folders looked in.
        looked: Vec<PathBuf>,
    },
    /// A checkpoint was found but could not be loaded.
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
}

/// The bundled checkpoint `name` (`coarse.ckpt` or `refine.ckpt`): in `$SUPERSVG_MODELS` when
/// it is set (and nowhere else: a mistyped folder is an error, not a silent fallback), else in
/// a `models/` folder next to the executable or up to three levels above it (a cargo build
/// inside the repository), or in the source tree this program was built from.
pub fn bundled(name: &str) -> Result<PathBuf, ModelsError> {
    // Set but empty (`SUPERSVG_MODELS=`) is unset, as shells treat it.
    if let Some(dir) = std::env::var_os(MODELS_ENV).filter(|dir| !dir.is_empty()) {
        let dir = PathBuf::from(dir);
        let path = dir.join(name);
        return if path.is_file() { Ok(path) } else { Err(ModelsError::NotInEnv { dir, name: name.into() }) };
    }
    let mut places: Vec<PathBuf> = Vec::new();
    if let Ok(exe) = std::env::current_exe() {
        places.extend(exe.ancestors().skip(1).take(4).map(|dir| dir.join("models")));
    }
    places.push(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models"));
    let found = places.iter().map(|dir| dir.join(name)).find(|path| path.is_file());
    match found {
        Some(path) => Ok(std::fs::canonicalize(&path).unwrap_or(path)),
        None => Err(ModelsError::NotFound { name: name.into(), looked: places }),
    }
}
