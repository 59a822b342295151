//! The two networks inference runs, and where the bundled ones are found.

use std::path::{Path, PathBuf};

use burn::tensor::Device;
use model::{
    Checkpoint, CheckpointError, CoarseModel, MismatchProblem, ModelConfig, OperatingPoint, RefineModel,
    Stage,
};

/// Where a checkpoint is read from: a file, or the copy of a bundled model built into this
/// program (so an installed `infer` needs nothing else on disk).
#[derive(Clone, Debug, PartialEq)]
pub enum ModelSource {
    /// A checkpoint file.
    File(PathBuf),
    /// A bundled checkpoint built in ([`BUILT_IN_COARSE`], [`BUILT_IN_REFINE`]).
    BuiltIn(&'static BuiltIn),
    /// Networks built in memory by the caller (not loadable), named by it.
    Memory(&'static str),
}

/// A bundled checkpoint compiled into the program (f16 weights, about 4.5 MB each).
#[derive(Debug, PartialEq)]
pub struct BuiltIn {
    /// Its file name in `models/`.
    pub name: &'static str,
    /// The checkpoint file's bytes.
    pub bytes: &'static [u8],
}

/// The bundled E_c, `models/coarse.ckpt` as it was when this program was built.
pub static BUILT_IN_COARSE: BuiltIn =
    BuiltIn { name: "coarse.ckpt", bytes: include_bytes!("../../../models/coarse.ckpt") };

/// The bundled E_r, `models/refine.ckpt` as it was when this program was built.
pub static BUILT_IN_REFINE: BuiltIn =
    BuiltIn { name: "refine.ckpt", bytes: include_bytes!("../../../models/refine.ckpt") };

impl ModelSource {
    /// The checkpoint it holds.
    pub fn load(&self) -> Result<Checkpoint, CheckpointError> {
        match self {
            Self::File(path) => Checkpoint::load(path),
            Self::BuiltIn(built_in) => Checkpoint::from_bytes(built_in.bytes, &self.name()),
            Self::Memory(_) => Err(CheckpointError::Missing { path: self.name() }),
        }
    }

    /// What errors call it: the file's path, or `built-in NAME`.
    pub fn name(&self) -> PathBuf {
        match self {
            Self::File(path) => path.clone(),
            Self::BuiltIn(built_in) => PathBuf::from(format!("built-in {}", built_in.name)),
            Self::Memory(name) => PathBuf::from(name),
        }
    }
}

/// One loaded network's identity, for the line that says which models drew: where it came
/// from, the checksum of its weights and how it was trained (the trainer's state: step,
/// config).
#[derive(Clone, Debug)]
pub struct Identity {
    /// Where it was read from.
    pub source: ModelSource,
    /// [`Checkpoint::weights_checksum`].
    pub checksum: String,
    /// The trainer's state stored with it, when there is one.
    pub training: Option<String>,
}

impl Identity {
    /// The identity of networks the caller built in memory, named `name`.
    pub fn in_memory(name: &'static str) -> Self {
        Self { source: ModelSource::Memory(name), checksum: "-".into(), training: None }
    }
}

impl std::fmt::Display for Identity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} (weights {}", self.source.name().display(), self.checksum)?;
        if let Some(step) = self.training.as_deref().and_then(training_summary) {
            write!(f, ", {step}")?;
        }
        write!(f, ")")
    }
}

/// "trained N steps in S s" from a trainer's state, when it names its step.
fn training_summary(training: &str) -> Option<String> {
    let state: serde_json::Value = serde_json::from_str(training).ok()?;
    let step = state.get("step")?.as_u64()?;
    Some(match state.get("seconds").and_then(serde_json::Value::as_f64) {
        Some(seconds) => format!("trained {step} steps in {seconds:.0} s"),
        None => format!("trained {step} steps"),
    })
}

/// The trained networks, ready for inference (cloning shares their weights).
#[derive(Clone)]
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
    /// Which E_c and E_r these are.
    pub identities: (Identity, Option<Identity>),
}

impl Models {
    /// Loads E_c from `coarse` and, if given, E_r from `refine` (both must share a configuration).
    pub fn load(coarse: &Path, refine: Option<&Path>, device: &Device) -> Result<Self, CheckpointError> {
        let refine = refine.map(|path| ModelSource::File(path.to_path_buf()));
        Self::from_sources(&ModelSource::File(coarse.to_path_buf()), refine.as_ref(), device)
    }

    /// The bundled models ([`bundled`]): E_c, and E_r when `refine` is true.
    pub fn bundled(refine: bool, device: &Device) -> Result<Self, ModelsError> {
        let coarse = bundled(&BUILT_IN_COARSE)?;
        let refine = refine.then(|| bundled(&BUILT_IN_REFINE)).transpose()?;
        Ok(Self::from_sources(&coarse, refine.as_ref(), device)?)
    }

    /// [`Models::load`] from files or built-in copies.
    pub fn from_sources(
        coarse: &ModelSource,
        refine: Option<&ModelSource>,
        device: &Device,
    ) -> Result<Self, CheckpointError> {
        let checkpoint = coarse.load()?;
        let coarse_name = coarse.name();
        checkpoint.expect_stage(Stage::Coarse, &coarse_name)?;
        let config = checkpoint.model_config.clone();
        let operating_point = checkpoint.inference.unwrap_or_default();
        let coarse_model = checkpoint.apply(CoarseModel::new(&config, device), &coarse_name)?;
        let identity = |source: &ModelSource, checkpoint: &Checkpoint| Identity {
            source: source.clone(),
            checksum: checkpoint.weights_checksum(),
            training: checkpoint.training.clone(),
        };
        let coarse_identity = identity(coarse, &checkpoint);
        let refine = match refine {
            None => None,
            Some(source) => {
                let checkpoint = source.load()?;
                let name = source.name();
                checkpoint.expect_stage(Stage::Refine, &name)?;
                if !config.serves_refine(&checkpoint.model_config) {
                    return Err(CheckpointError::Mismatch {
                        path: name,
                        problem: MismatchProblem::ConfigDiffers(coarse_name),
                    });
                }
                let model = checkpoint.apply(RefineModel::new(&checkpoint.model_config, device), &name)?;
                Some((model, identity(source, &checkpoint)))
            }
        };
        let (refine, refine_identity) = refine.unzip();
        Ok(Self {
            coarse: coarse_model,
            refine,
            config,
            operating_point,
            identities: (coarse_identity, refine_identity),
        })
    }
}

/// What a stage needs to run a network: the models' configuration (architecture and input
/// contract), how many crops go into one call, and the device.
#[derive(Clone, Copy)]
pub struct Context<'a> {
    /// The models' configuration.
    pub config: &'a ModelConfig,
    /// Crops per network call (at least 1).
    pub batch: usize,
    /// Where the networks run.
    pub device: &'a Device,
}

/// Environment variable naming a folder with `coarse.ckpt` and `refine.ckpt`, used instead of
/// the built-in models.
pub const MODELS_ENV: &str = "SUPERSVG_MODELS";

/// Why the bundled models could not be found or loaded.
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
    /// A checkpoint was found but could not be loaded.
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
}

/// The bundled checkpoint `built_in` stands for: the file of its name in `$SUPERSVG_MODELS`
/// when that is set (and nowhere else: a mistyped folder is an error, not a silent fallback),
/// else the built-in copy.
pub fn bundled(built_in: &'static BuiltIn) -> Result<ModelSource, ModelsError> {
    // Set but empty (`SUPERSVG_MODELS=`) is unset, as shells treat it.
    match std::env::var_os(MODELS_ENV).filter(|dir| !dir.is_empty()) {
        None => Ok(ModelSource::BuiltIn(built_in)),
        Some(dir) => {
            let dir = PathBuf::from(dir);
            let path = dir.join(built_in.name);
            if path.is_file() {
                Ok(ModelSource::File(path))
            } else {
                Err(ModelsError::NotInEnv { dir, name: built_in.name.into() })
            }
        }
    }
}
