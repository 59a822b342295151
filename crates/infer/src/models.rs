//! The networks inference runs, and where the bundled ones are found.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, OnceLock, PoisonError};

use burn::module::Module;
use burn::tensor::Device;
use model::{
    Checkpoint, CheckpointError, CoarseModel, LearnedOptimizer, MismatchProblem, ModelConfig, Mover, Opened,
    OperatingPoint, RefineModel, SmallCheckpoint, SmallNetwork, Stage,
};

/// Where a checkpoint is read from: a file, or the copy of a bundled model built into this
/// program (so an installed `infer` needs nothing else on disk).
#[derive(Clone, Debug, PartialEq)]
pub enum ModelSource {
    /// A checkpoint file.
    File(PathBuf),
    /// A bundled checkpoint built in ([`BUILT_IN_COARSE`], [`BUILT_IN_REFINE`], [`BUILT_IN_MOVER`]).
    BuiltIn(&'static BuiltIn),
    /// Networks built in memory by the caller (not loadable), named by it.
    Memory(&'static str),
}

/// A bundled checkpoint compiled into the program (E_c's and E_r's f16 weights are about 4.5 MB
/// each; the mover's f32 weights 20 KB).
#[derive(Debug, PartialEq)]
pub struct BuiltIn {
    /// Its file name in `models/`.
    pub name: &'static str,
    /// The checkpoint file's bytes.
    pub bytes: &'static [u8],
}

/// A file's bytes compiled into the program on a 256-byte boundary, as burnpack aligns the
/// tensors inside a file: so that the checkpoint is read where it lies
/// ([`Checkpoint::open_bytes`]), not copied.
macro_rules! include_aligned {
    ($path:literal) => {{
        #[repr(C, align(256))]
        struct Aligned<B: ?Sized>(B);
        const ALIGNED: &Aligned<[u8]> = &Aligned(*include_bytes!($path));
        &ALIGNED.0
    }};
}

/// The bundled E_c, `models/coarse.ckpt` as it was when this program was built.
pub static BUILT_IN_COARSE: BuiltIn =
    BuiltIn { name: "coarse.ckpt", bytes: include_aligned!("../../../models/coarse.ckpt") };

/// The bundled E_r, `models/refine.ckpt` as it was when this program was built.
pub static BUILT_IN_REFINE: BuiltIn =
    BuiltIn { name: "refine.ckpt", bytes: include_aligned!("../../../models/refine.ckpt") };

/// The bundled mover E_m, `models/mover.ckpt` as it was when this program was built.
pub static BUILT_IN_MOVER: BuiltIn =
    BuiltIn { name: "mover.ckpt", bytes: include_aligned!("../../../models/mover.ckpt") };

impl ModelSource {
    /// The small network's file it holds (the mover's, E_o's), read and checked.
    pub fn open_small<M: SmallNetwork>(&self) -> Result<SmallCheckpoint<M>, CheckpointError> {
        match self {
            Self::File(path) => SmallCheckpoint::load(path),
            Self::BuiltIn(built_in) => SmallCheckpoint::from_bytes(built_in.bytes, &self.name()),
            Self::Memory(_) => Err(CheckpointError::Missing { path: self.name() }),
        }
    }

    /// The checkpoint it holds, opened: its header read and checked, its weights not yet.
    pub fn open(&self) -> Result<Opened, CheckpointError> {
        match self {
            Self::File(path) => Checkpoint::open(path),
            Self::BuiltIn(built_in) => Checkpoint::open_bytes(built_in.bytes, &self.name()),
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

/// One network's identity, for the line that says which models drew: where it comes from,
/// the checksum its weights are stored with, whether they were verified against it yet, and
/// how it was trained (the trainer's state: step, config).
#[derive(Clone, Debug)]
pub struct Identity {
    /// Where it was read from.
    pub source: ModelSource,
    /// [`Checkpoint::weights_checksum`] as stored, which the weights are verified against when
    /// read ("unchecked" for the first format, which has none).
    pub checksum: String,
    /// Whether the weights were read and verified against their checksums when this identity
    /// was made (a file is, before any work); otherwise they are the first time a stage uses
    /// them (a built-in network a job may never run).
    pub verified: bool,
    /// The trainer's state stored with it, when there is one.
    pub training: Option<String>,
}

impl std::fmt::Display for Identity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} (weights {}", self.source.name().display(), self.checksum)?;
        match (self.verified, matches!(self.source, ModelSource::Memory(_)) || self.checksum == "unchecked") {
            (_, true) => {}
            (true, false) => write!(f, ", verified")?,
            (false, false) => write!(f, ", verified when first used")?,
        }
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

/// One network of inference: which it is, and its weights, read and verified the first time a
/// stage asks for them ([`Network::get`]), so a job that never runs it never pays for reading
/// it. Cloning shares the weights, read or not.
#[derive(Clone)]
pub struct Network<M> {
    /// Which network this is.
    pub identity: Identity,
    weights: Arc<Weights<M>>,
}

/// A network's weights: built once, by the first caller that needs them.
struct Weights<M> {
    built: OnceLock<M>,
    /// Held while the weights are read, so two threads asking at once read them once.
    reading: Mutex<()>,
    /// How to build the network from its checkpoint; none for one built in memory.
    recipe: Option<Recipe<M>>,
}

/// What building a network from its checkpoint takes.
struct Recipe<M> {
    stage: Stage,
    config: ModelConfig,
    device: Device,
    new: fn(&ModelConfig, &Device) -> M,
}

impl<M: Module> Network<M> {
    /// The network in `source`: `opened` is that checkpoint's header, already checked to hold
    /// `stage`; the network is built with `config` on `device`. A file's weights are read and
    /// verified now, so a damaged file is refused before any work; a built-in network's when
    /// a stage first uses it ([`Network::get`]), so a job that never runs it never reads it.
    fn opened(
        source: &ModelSource,
        opened: Opened,
        stage: Stage,
        new: fn(&ModelConfig, &Device) -> M,
        device: &Device,
    ) -> Result<Self, CheckpointError> {
        let eager = matches!(source, ModelSource::File(_));
        let identity = Identity {
            source: source.clone(),
            checksum: opened.checksum.clone().unwrap_or_else(|| "unchecked".into()),
            verified: eager && opened.checksum.is_some(),
            training: opened.training.clone(),
        };
        let recipe = Recipe { stage, config: opened.model_config.clone(), device: device.clone(), new };
        // A file is read once, here (a pipe cannot be read twice).
        let built = match eager {
            true => OnceLock::from(opened.build(new(&recipe.config, device))?),
            false => OnceLock::new(),
        };
        Ok(Self {
            identity,
            weights: Arc::new(Weights { built, reading: Mutex::new(()), recipe: Some(recipe) }),
        })
    }

    /// A network the caller built in memory (a model in training, a test's), named `name`.
    pub fn in_memory(model: M, name: &'static str) -> Self {
        let built = OnceLock::from(model);
        Self {
            identity: Identity {
                source: ModelSource::Memory(name),
                checksum: "-".into(),
                verified: false,
                training: None,
            },
            weights: Arc::new(Weights { built, reading: Mutex::new(()), recipe: None }),
        }
    }

    /// The network, its weights read from its checkpoint and verified (checksum, finite
    /// values, shapes) the first time it is asked for.
    pub fn get(&self) -> Result<&M, CheckpointError> {
        let weights = &*self.weights;
        if let Some(model) = weights.built.get() {
            return Ok(model);
        }
        let _reading = weights.reading.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(model) = weights.built.get() {
            return Ok(model);
        }
        let source = &self.identity.source;
        let Some(recipe) = &weights.recipe else {
            return Err(CheckpointError::Missing { path: source.name() });
        };
        let opened = source.open()?;
        opened.expect_stage(recipe.stage)?;
        let model = opened.build((recipe.new)(&recipe.config, &recipe.device))?;
        Ok(weights.built.get_or_init(|| model))
    }
}

/// A small network inference runs (the mover E_m, the learned optimizer E_o): which it is, and
/// the network, read and verified when loaded (it is small). Cloning shares it.
#[derive(Clone)]
pub struct SmallModel<M> {
    /// Which network this is.
    pub identity: Identity,
    /// The network.
    pub network: Arc<M>,
}

/// The mover inference runs.
pub type MoverNetwork = SmallModel<Mover>;
/// The learned optimizer SuperSVG-F runs first.
pub type OptimizerNetwork = SmallModel<LearnedOptimizer>;

impl<M: SmallNetwork> SmallModel<M> {
    /// The network in `source`, read, verified and built on `device`.
    pub fn load(source: &ModelSource, device: &Device) -> Result<Self, CheckpointError> {
        let file = source.open_small::<M>()?;
        let network = file.build(device, &source.name())?;
        let identity = Identity {
            source: source.clone(),
            checksum: file.weights_checksum(),
            verified: true,
            training: file.training,
        };
        Ok(Self { identity, network: Arc::new(network) })
    }
}

impl OptimizerNetwork {
    /// How many of SuperSVG-F's steps E_o takes first: the rollouts it was trained on
    /// (`rollout.steps` of its trainer's state), 4 where the file does not say.
    pub fn steps(&self) -> usize {
        let state = self
            .identity
            .training
            .as_deref()
            .and_then(|json| serde_json::from_str::<serde_json::Value>(json).ok());
        state.and_then(|state| state["config"]["rollout"]["steps"].as_u64()).map_or(4, |steps| steps as usize)
    }
}

/// The trained networks inference runs, E_c and E_r each read the first time a stage uses it
/// (cloning shares them).
#[derive(Clone)]
pub struct Models {
    /// E_c.
    pub coarse: Network<CoarseModel>,
    /// E_r; without it the result has only coarse paths.
    pub refine: Option<Network<RefineModel>>,
    /// E_m; without it B's outlines stay where B drew them.
    pub mover: Option<MoverNetwork>,
    /// E_o; without it SuperSVG-F is Adam alone.
    pub optimizer: Option<OptimizerNetwork>,
    /// Their configuration (architecture and input contract).
    pub config: ModelConfig,
    /// How a path budget is split between regions, E_c and E_r: the one measured for these
    /// models and stored in the coarse checkpoint, or [`OperatingPoint::default`].
    pub operating_point: OperatingPoint,
}

impl Models {
    /// E_c from `coarse` and, if given, E_r from `refine` (both must share a configuration);
    /// no mover ([`Models::with_mover`] adds one).
    pub fn load(coarse: &Path, refine: Option<&Path>, device: &Device) -> Result<Self, CheckpointError> {
        let refine = refine.map(|path| ModelSource::File(path.to_path_buf()));
        Self::from_sources(&ModelSource::File(coarse.to_path_buf()), refine.as_ref(), device)
    }

    /// The bundled models ([`bundled`]): E_c, E_r when `refine` is true, and E_m.
    pub fn bundled(refine: bool, device: &Device) -> Result<Self, ModelsError> {
        let coarse = bundled(&BUILT_IN_COARSE)?;
        let refine = refine.then(|| bundled(&BUILT_IN_REFINE)).transpose()?;
        let models = Self::from_sources(&coarse, refine.as_ref(), device)?;
        Ok(models.with_mover(&bundled(&BUILT_IN_MOVER)?, device)?)
    }

    /// The same networks with the mover in `source`.
    pub fn with_mover(self, source: &ModelSource, device: &Device) -> Result<Self, CheckpointError> {
        Ok(Self { mover: Some(MoverNetwork::load(source, device)?), ..self })
    }

    /// The same networks with the learned optimizer in `source`, which SuperSVG-F runs first.
    pub fn with_optimizer(self, source: &ModelSource, device: &Device) -> Result<Self, CheckpointError> {
        Ok(Self { optimizer: Some(OptimizerNetwork::load(source, device)?), ..self })
    }

    /// [`Models::load`] from files or built-in copies. What each checkpoint says about itself
    /// (its stage, its configuration, the operating point) is read and checked now, and a
    /// file's weights too; a built-in network's weights when a stage first uses them
    /// ([`Network::get`]).
    pub fn from_sources(
        coarse: &ModelSource,
        refine: Option<&ModelSource>,
        device: &Device,
    ) -> Result<Self, CheckpointError> {
        let opened = coarse.open()?;
        opened.expect_stage(Stage::Coarse)?;
        let config = opened.model_config.clone();
        let operating_point = opened.inference.unwrap_or_default();
        let coarse_network = Network::opened(coarse, opened, Stage::Coarse, CoarseModel::new, device)?;
        let refine = match refine {
            None => None,
            Some(source) => {
                let opened = source.open()?;
                opened.expect_stage(Stage::Refine)?;
                if !config.serves_refine(&opened.model_config) {
                    return Err(CheckpointError::Mismatch {
                        path: source.name(),
                        problem: MismatchProblem::ConfigDiffers(coarse.name()),
                    });
                }
                Some(Network::opened(source, opened, Stage::Refine, RefineModel::new, device)?)
            }
        };
        Ok(Self { coarse: coarse_network, refine, mover: None, optimizer: None, config, operating_point })
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

/// Environment variable naming a folder with `coarse.ckpt`, `refine.ckpt` and `mover.ckpt`, used
/// instead of the built-in models.
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
