//! Checkpoint files: one burnpack file holding a model's weights, its configuration and stage,
//! and, for training, the optimizer state and the trainer's own state.
//!
//! Model tensors are stored under `model/…`; the optimizer's own burnpack container (tensors,
//! scalars such as Adam's step count, and parameter paths) is embedded whole as the byte tensor
//! `optimizer`, so nothing of its state is lost. Metadata keys are `supersvg.format`,
//! `supersvg.stage`, `supersvg.model` (the [`ModelConfig`] as JSON), `supersvg.training` (an
//! opaque JSON string owned by the trainer) and `supersvg.inference` (the measured
//! [`OperatingPoint`] as JSON, in coarse checkpoints that have one) and `supersvg.checksum` (of
//! the model tensors: names, dtypes, shapes and bytes) and `supersvg.state` (of everything else
//! a run reads back: the stage, the JSON values and the optimizer's bytes). Loading needs no
//! flags: the configuration rebuilds the model before its weights are applied. Loading refuses a
//! file whose weights or state do not match their checksums (damaged on disk or in transfer) or
//! whose weights hold a NaN or infinity, naming it.
//! Writes are atomic (`common::write::write_atomic`), so an interrupted save never leaves a
//! partial checkpoint.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use burn::module::{Module, ModuleMapper, Param, ParamId};
use burn::store::RecordError;
use burn::tensor::kind::Basic;
use burn::tensor::{AllocationProperty, Bool, Bytes, DType, Device, Float, Int, Shape, Tensor, TensorData};
use burn_pack::{Reader, Writer};
use common::fingerprint::Fnv;
use common::readable::{self, Readable, StreamError};
use half::f16;
use half::slice::HalfFloatSliceExt;
use rayon::prelude::*;

use crate::coarse::CoarseModel;
use crate::config::{InvalidSetting, ModelConfig};
use crate::learned::{LearnedOptimizer, OPTIMIZER_STAGE};
use crate::mover::Mover;
use crate::operating::OperatingPoint;
use crate::refine::RefineModel;

const FORMAT: &str = "supersvg-checkpoint/3";
/// The format with the weights' checksum alone: still read, the rest unchecked.
const FORMAT_WEIGHTS_CHECKED: &str = "supersvg-checkpoint/2";
/// The format before any checksum: still read, without the checks.
const FORMAT_UNCHECKED: &str = "supersvg-checkpoint/1";
const MODEL_PREFIX: &str = "model/";
const OPTIMIZER_BLOB: &str = "optimizer";

/// The metadata keys of a checkpoint file, written and read only through these.
mod key {
    /// The file format's version ([`super::FORMAT`]).
    pub const FORMAT: &str = "supersvg.format";
    /// [`super::Stage::name`].
    pub const STAGE: &str = "supersvg.stage";
    /// The model configuration, JSON.
    pub const MODEL: &str = "supersvg.model";
    /// The trainer's state, JSON (optional).
    pub const TRAINING: &str = "supersvg.training";
    /// The operating point, JSON (optional).
    pub const INFERENCE: &str = "supersvg.inference";
    /// [`super::checksum`] of the model tensors, 16 hex digits.
    pub const CHECKSUM: &str = "supersvg.checksum";
    /// [`super::state_checksum`] of the rest, 16 hex digits.
    pub const STATE: &str = "supersvg.state";
}

/// Which network a checkpoint holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// The coarse model E_c.
    Coarse,
    /// The refinement model E_r.
    Refine,
}

impl Stage {
    /// Both stages.
    pub const ALL: [Stage; 2] = [Stage::Coarse, Stage::Refine];

    /// The stage's name as written in checkpoint files ("coarse", "refine").
    pub fn name(self) -> &'static str {
        match self {
            Stage::Coarse => "coarse",
            Stage::Refine => "refine",
        }
    }

    /// The stage named `name` ([`Stage::name`]).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|stage| stage.name() == name)
    }
}

/// Why a checkpoint could not be written, read or applied. Every message names the file.
#[derive(Debug, thiserror::Error)]
pub enum CheckpointError {
    /// There is no file at the path.
    #[error("{path}: no such file")]
    Missing {
        /// The checkpoint file.
        path: PathBuf,
    },
    /// A folder where a checkpoint file was expected.
    #[error("{path}: is a folder, not a checkpoint file")]
    Folder {
        /// The path given.
        path: PathBuf,
    },
    /// The file could not be written.
    #[error("{path}: {source}")]
    Write {
        /// The checkpoint file.
        path: PathBuf,
        /// The burnpack writer's reason.
        source: burn_pack::Error,
    },
    /// The file could not be stored.
    #[error("{path}: {source}")]
    Store {
        /// The checkpoint file.
        path: PathBuf,
        /// The file system's reason.
        source: std::io::Error,
    },
    /// The file (or the stream: a pipe, `<(…)`) could not be read.
    #[error("{path}: {source}")]
    Read {
        /// The checkpoint file.
        path: PathBuf,
        /// Why.
        source: StreamError,
    },
    /// The file is not a supersvg checkpoint, or its contents are damaged.
    #[error("{path}: {}", format_problem(problem))]
    Format {
        /// The checkpoint file.
        path: PathBuf,
        /// What is missing or wrong.
        problem: FormatProblem,
    },
    /// The checkpoint holds the other network.
    #[error("{path}: this is a {found} checkpoint, a {expected} checkpoint is needed here")]
    WrongStage {
        /// The checkpoint file.
        path: PathBuf,
        /// The stage that was asked for.
        expected: &'static str,
        /// The stage the file holds.
        found: &'static str,
    },
    /// The weights do not fit the model they are loaded into.
    #[error("{path}: the weights do not fit the model: {problem}")]
    Mismatch {
        /// The checkpoint file.
        path: PathBuf,
        /// Which parameter differs, and how.
        problem: MismatchProblem,
    },
}

/// What is wrong with a file that should hold a checkpoint.
#[derive(Debug, thiserror::Error)]
pub enum FormatProblem {
    /// Not a burnpack container, or a damaged one.
    #[error(transparent)]
    Container(#[from] burn_pack::Error),
    /// A metadata key every checkpoint has is absent.
    #[error("missing `{0}`")]
    MissingKey(&'static str),
    /// `supersvg.format` names a version this build does not read.
    #[error("unsupported format `{0}`")]
    UnsupportedFormat(String),
    /// `supersvg.stage` is neither `coarse` nor `refine`.
    #[error("unknown stage `{0}`")]
    UnknownStage(String),
    /// `supersvg.model` is not a model configuration.
    #[error("model config: {0}")]
    ModelConfig(serde_json::Error),
    /// `supersvg.model` parses but holds a value out of range.
    #[error("model config: {0}")]
    InvalidModelConfig(InvalidSetting),
    /// `supersvg.inference` is not an operating point.
    #[error("operating point: {0}")]
    OperatingPoint(serde_json::Error),
    /// `supersvg.inference` parses but holds a value out of range.
    #[error("operating point: {0}")]
    InvalidOperatingPoint(InvalidSetting),
    /// A tensor that is neither a model weight nor the optimizer state.
    #[error("unexpected tensor `{0}`")]
    UnexpectedTensor(String),
    /// The file holds no model weights.
    #[error("no model weights")]
    NoWeights,
    /// The weights are not the ones written: damaged on disk or in transfer.
    #[error("the weights do not match their checksum (stored {stored}, computed {computed})")]
    Checksum {
        /// The checksum in the metadata.
        stored: String,
        /// The checksum of the weights read.
        computed: String,
    },
    /// The stage, configuration, trainer's state or optimizer state are not the ones written.
    #[error("the training state does not match its checksum (stored {stored}, computed {computed})")]
    StateChecksum {
        /// The checksum in the metadata.
        stored: String,
        /// The checksum of what was read.
        computed: String,
    },
    /// A weight is NaN or infinite: the model was saved from a diverged training.
    #[error("weight `{0}` holds a NaN or an infinity")]
    NonFinite(String),
}

/// How [`CheckpointError::Format`] says its problem: a checkpoint whose checksums or values do
/// not hold is damaged; anything else is not a checkpoint of ours.
fn format_problem(problem: &FormatProblem) -> String {
    match problem {
        FormatProblem::Checksum { .. }
        | FormatProblem::StateChecksum { .. }
        | FormatProblem::NonFinite(_) => {
            format!("a damaged checkpoint: {problem}")
        }
        _ => format!("not a supersvg checkpoint ({problem})"),
    }
}

/// Why stored weights cannot be applied to a model.
#[derive(Debug, thiserror::Error)]
pub enum MismatchProblem {
    /// A parameter is missing or has another shape (burn's record validation).
    #[error(transparent)]
    Record(#[from] RecordError),
    /// A refinement checkpoint made for another coarse model's configuration.
    #[error("its model configuration differs from {}'s", .0.display())]
    ConfigDiffers(PathBuf),
}

/// The contents of a checkpoint file.
#[derive(Clone)]
pub struct Checkpoint {
    /// Which network the weights belong to.
    pub stage: Stage,
    /// The network's configuration.
    pub model_config: ModelConfig,
    /// The weights, as burnpack bytes of a [`burn::store::ModuleRecord`].
    pub model: Bytes,
    /// The optimizer state, as burnpack bytes, when the checkpoint is for resuming training.
    pub optimizer: Option<Bytes>,
    /// The trainer's own state as JSON (step, schedules, data order…), opaque here.
    pub training: Option<String>,
    /// How inference should split a path budget with this model, when it was measured.
    pub inference: Option<OperatingPoint>,
}

impl Checkpoint {
    /// A checkpoint of `model`'s current weights, stored in `dtype` (F32 for training, F16 to
    /// ship smaller files; loading converts back to the model's dtype).
    pub fn of_model<M: Module>(stage: Stage, model_config: &ModelConfig, model: &M, dtype: DType) -> Self {
        let record = model.clone().into_record().into_bytes().expect("a record serializes to memory");
        let model = convert(&record, dtype).expect("a fresh record converts");
        Self {
            stage,
            model_config: model_config.clone(),
            model,
            optimizer: None,
            training: None,
            inference: None,
        }
    }

    /// The same weights without the optimizer state, stored in `dtype`: what inference needs,
    /// in a file a fraction of the size (F16 halves the weights; Adam's two moments go). The
    /// trainer's state stays, so a shipped model still says how long it was trained.
    pub fn for_inference(&self, dtype: DType, path: &Path) -> Result<Self, CheckpointError> {
        let model = convert(&self.model, dtype)
            .map_err(|source| CheckpointError::Format { path: path.to_path_buf(), problem: source.into() })?;
        Ok(Self { model, optimizer: None, ..self.clone() })
    }

    /// Writes the checkpoint to `path` atomically.
    pub fn save(&self, path: &Path) -> Result<(), CheckpointError> {
        let model_json = serde_json::to_string(&self.model_config).expect("configs serialize");
        let inference =
            self.inference.as_ref().map(|point| serde_json::to_string(point).expect("serializes"));
        let header = Header {
            format: FORMAT,
            stage: self.stage.name(),
            model: Some(&model_json),
            training: self.training.as_deref(),
            inference: inference.as_deref(),
        };
        write(path, &header, &self.model, self.optimizer.as_ref())
    }

    /// Reads a checkpoint from `path`.
    pub fn load(path: &Path) -> Result<Self, CheckpointError> {
        Self::open(path)?.into_checkpoint()
    }

    /// Opens the checkpoint at `path`: what it says about itself, read and checked now, and
    /// its weights, read when a network is built from them ([`Opened::build`]).
    pub fn open(path: &Path) -> Result<Opened, CheckpointError> {
        let reader = reader_of(path)?;
        Opened::new(reader, path)
            .map_err(|problem| CheckpointError::Format { path: path.to_path_buf(), problem })
    }

    /// [`Checkpoint::open`] of a checkpoint built into the program, read where it lies (not
    /// copied: a program that never builds the network never touches its weights); `name`
    /// stands for it in errors.
    ///
    /// The bytes must start on a [`burn_pack::TENSOR_ALIGNMENT`] boundary to be read in place
    /// (tensors are read as slices of f16 or f32); others are copied first.
    pub fn open_bytes(bytes: &'static [u8], name: &Path) -> Result<Opened, CheckpointError> {
        Reader::from_bytes(in_place(bytes))
            .map_err(FormatProblem::from)
            .and_then(|reader| Opened::new(reader, name))
            .map_err(|problem| CheckpointError::Format { path: name.to_path_buf(), problem })
    }

    /// The checksum of the weights (what every checkpoint stores and loading verifies): the
    /// identity of a model, whatever file it came in.
    pub fn weights_checksum(&self) -> String {
        let entries = entries(&self.model).expect("the weights were read from a burnpack");
        checksum(entries.iter().map(|e| (e.name.as_str(), &e.data)))
    }

    /// Fails unless the checkpoint holds `stage`.
    pub fn expect_stage(&self, stage: Stage, path: &Path) -> Result<(), CheckpointError> {
        if self.stage == stage {
            Ok(())
        } else {
            Err(CheckpointError::WrongStage {
                path: path.to_path_buf(),
                expected: stage.name(),
                found: self.stage.name(),
            })
        }
    }

    /// Applies the stored weights to `model`, in f32.
    pub fn apply<M: Module>(&self, model: M, path: &Path) -> Result<M, CheckpointError> {
        let weights = entries(&self.model)
            .map_err(|source| CheckpointError::Format { path: path.to_path_buf(), problem: source.into() })?;
        apply(model, weights.iter().map(Entry::to_f32).collect(), path)
    }
}

/// The most bytes of a checkpoint read from a stream (a pipe, `<(…)`), which is read whole
/// first: the paper preset's training checkpoint, Adam's moments included, is about a quarter
/// of it.
pub const MAX_STREAMED_CHECKPOINT: u64 = 1 << 30;

/// The container at `path`: a regular file read where it lies, anything else that can be read
/// (a pipe, `<(…)`, a device) read whole first, at most [`MAX_STREAMED_CHECKPOINT`] bytes,
/// without waiting on a pipe no program writes to.
fn reader_of(path: &Path) -> Result<Reader, CheckpointError> {
    let fail = |problem: FormatProblem| CheckpointError::Format { path: path.to_path_buf(), problem };
    let read = |source: StreamError| CheckpointError::Read { path: path.to_path_buf(), source };
    match readable::open(path) {
        Err(err) if err.kind() == std::io::ErrorKind::NotFound => {
            Err(CheckpointError::Missing { path: path.to_path_buf() })
        }
        Err(err) if err.kind() == std::io::ErrorKind::IsADirectory => {
            Err(CheckpointError::Folder { path: path.to_path_buf() })
        }
        Err(err) => Err(read(err.into())),
        Ok(Readable::File(_)) => Reader::from_file_exact(path).map_err(|e| fail(e.into())),
        Ok(Readable::Stream(stream)) => {
            let bytes = readable::read_whole(stream, MAX_STREAMED_CHECKPOINT).map_err(read)?;
            Reader::from_bytes(Bytes::from_bytes_vec(bytes)).map_err(|e| fail(e.into()))
        }
    }
}

/// `bytes` (a file built into the program) read where they lie when they start on a
/// [`burn_pack::TENSOR_ALIGNMENT`] boundary (tensors are read as slices of f16 or f32), else a copy.
fn in_place(bytes: &'static [u8]) -> Bytes {
    if (bytes.as_ptr() as usize).is_multiple_of(burn_pack::TENSOR_ALIGNMENT as usize) {
        Bytes::from_shared(bytes::Bytes::from_static(bytes), AllocationProperty::Other)
    } else {
        Bytes::from_bytes_vec(bytes.to_vec())
    }
}

/// What a checkpoint file says about itself besides its tensors.
struct Header<'a> {
    format: &'a str,
    stage: &'a str,
    /// The model configuration as JSON (none in a mover's file, whose size is fixed).
    model: Option<&'a str>,
    training: Option<&'a str>,
    inference: Option<&'a str>,
}

/// Writes `model` (burnpack bytes of a record) and `optimizer` to `path` atomically, under
/// `header` and the checksums of both.
fn write(
    path: &Path,
    header: &Header,
    model: &Bytes,
    optimizer: Option<&Bytes>,
) -> Result<(), CheckpointError> {
    let fail = |source: burn_pack::Error| CheckpointError::Write { path: path.to_path_buf(), source };
    let mut tensors: Vec<Entry> = entries(model)
        .map_err(fail)?
        .into_iter()
        .map(|e| Entry { name: format!("{MODEL_PREFIX}{}", e.name), ..e })
        .collect();
    if let Some(optimizer) = optimizer {
        let data = TensorData::new(optimizer.to_vec(), [optimizer.len()]);
        tensors.push(Entry { name: OPTIMIZER_BLOB.into(), id: None, data });
    }
    let model_entries = tensors.iter().filter(|e| e.name != OPTIMIZER_BLOB);
    let sum =
        checksum(model_entries.map(|e| (e.name.strip_prefix(MODEL_PREFIX).unwrap_or(&e.name), &e.data)));
    let tensors = tensors.into_iter().map(Entry::into_pack).collect();
    let state = state_checksum(State {
        stage: header.stage,
        model: header.model.unwrap_or(""),
        training: header.training,
        inference: header.inference,
        optimizer: optimizer.map(|bytes| &bytes[..]),
    });
    let mut writer = Writer::new(tensors)
        .with_metadata(key::FORMAT, header.format)
        .with_metadata(key::STAGE, header.stage)
        .with_metadata(key::CHECKSUM, &sum)
        .with_metadata(key::STATE, &state)
        .auto_extension(false);
    let optional =
        [(key::MODEL, header.model), (key::TRAINING, header.training), (key::INFERENCE, header.inference)];
    for (key, value) in optional {
        if let Some(value) = value {
            writer = writer.with_metadata(key, value);
        }
    }
    let bytes = writer.into_bytes().map_err(fail)?;
    common::write::write_atomic(path, &bytes)
        .map_err(|source| CheckpointError::Store { path: path.to_path_buf(), source })
}

/// `model` with `weights` (tensors named by module path, floats already in f32:
/// [`Entry::to_f32`]), each placed in the dtype it holds, with no record built in between: a
/// parameter's own dtype is not asked, which would draw its random initialization only to
/// replace it. Every parameter must get a weight of its shape, and every weight a parameter.
fn apply<M: Module>(model: M, weights: Vec<Entry>, path: &Path) -> Result<M, CheckpointError> {
    let weights = weights.into_iter().map(|entry| (entry.name, (entry.id, entry.data))).collect();
    let mut placing = Placing { path: Vec::new(), weights, problems: Vec::new() };
    let model = model.map(&mut placing);
    let mut unused: Vec<&String> = placing.weights.keys().collect();
    unused.sort_unstable();
    placing.problems.extend(unused.into_iter().map(|name| format!("{name}: no parameter of the model")));
    match placing.problems.is_empty() {
        true => Ok(model),
        false => Err(CheckpointError::Mismatch {
            path: path.to_path_buf(),
            problem: RecordError::Validation(placing.problems.join("; ")).into(),
        }),
    }
}

/// The walk over a model's parameters that places its stored weights ([`apply`]).
struct Placing {
    /// The module path where the walk is.
    path: Vec<String>,
    /// The weights not yet placed, by module path: their parameter ids and data.
    weights: HashMap<String, (Option<u64>, TensorData)>,
    /// What did not fit, in the words errors use.
    problems: Vec<String>,
}

impl Placing {
    /// The weight for the parameter here, as a tensor of `shape` on `device`, and its id;
    /// none (and a problem noted) when it is missing or of another shape.
    fn take<const D: usize, K: Basic>(
        &mut self,
        shape: Shape,
        device: &Device,
    ) -> Option<(Tensor<D, K>, ParamId)> {
        let path = self.path.join(".");
        let Some((id, data)) = self.weights.remove(&path) else {
            self.problems.push(format!("{path}: no weight stored"));
            return None;
        };
        if *data.shape() != shape {
            self.problems.push(format!("{path}: stored {:?}, the model has {shape:?}", data.shape()));
            return None;
        }
        let (dtype, id) = (data.dtype(), id.map_or_else(ParamId::new, ParamId::from));
        Some((Tensor::from_data(data, (device, dtype)), id))
    }
}

/// One `ModuleMapper` method: the parameter with its weight placed, or as it was.
macro_rules! place {
    ($method:ident, $kind:ty) => {
        fn $method<const D: usize>(&mut self, param: Param<Tensor<D, $kind>>) -> Param<Tensor<D, $kind>> {
            let (shape, device) = (param.lazy_shape(), param.lazy_device());
            match self.take(shape, &device) {
                Some((tensor, id)) => param.transform_for_load(tensor, id),
                None => param,
            }
        }
    };
}

impl ModuleMapper for Placing {
    fn enter_module(&mut self, name: &str, _container_type: &str) {
        self.path.push(name.to_string());
    }

    fn exit_module(&mut self, _name: &str, _container_type: &str) {
        self.path.pop();
    }

    place!(map_float, Float);
    place!(map_int, Int);
    place!(map_bool, Bool);
}

/// A checkpoint opened ([`Checkpoint::open`]): what it says about itself, read and checked
/// without its tensors, and its weights, read and verified only when a network is built from
/// them. Inference opens both networks at once and builds each the first time it is used.
pub struct Opened {
    /// Which network the weights belong to.
    pub stage: Stage,
    /// The network's configuration.
    pub model_config: ModelConfig,
    /// How inference should split a path budget with this model, when it was measured.
    pub inference: Option<OperatingPoint>,
    /// The trainer's own state as JSON, when stored.
    pub training: Option<String>,
    /// The weights' checksum as stored ([`Checkpoint::weights_checksum`]), verified when they
    /// are read; none in the first format.
    pub checksum: Option<String>,
    /// Whether the format stores [`state_checksum`].
    state_checked: bool,
    metadata: std::collections::BTreeMap<String, String>,
    reader: Reader,
    name: PathBuf,
}

impl Opened {
    /// What the checkpoint in `reader` says about itself, checked; `name` stands for it in errors.
    fn new(reader: Reader, name: &Path) -> Result<Self, FormatProblem> {
        let metadata = reader.metadata().clone();
        let get = |key: &'static str| metadata.get(key).cloned().ok_or(FormatProblem::MissingKey(key));
        let format = get(key::FORMAT)?;
        if ![FORMAT, FORMAT_WEIGHTS_CHECKED, FORMAT_UNCHECKED].contains(&format.as_str()) {
            return Err(FormatProblem::UnsupportedFormat(format));
        }
        let stage = get(key::STAGE)?;
        let stage = Stage::from_name(&stage).ok_or(FormatProblem::UnknownStage(stage))?;
        let model_config: ModelConfig =
            serde_json::from_str(&get(key::MODEL)?).map_err(FormatProblem::ModelConfig)?;
        model_config.validate().map_err(FormatProblem::InvalidModelConfig)?;
        let inference = match metadata.get(key::INFERENCE) {
            None => None,
            Some(json) => {
                let point: OperatingPoint =
                    serde_json::from_str(json).map_err(FormatProblem::OperatingPoint)?;
                point.validate().map_err(FormatProblem::InvalidOperatingPoint)?;
                Some(point)
            }
        };
        let checksum = (format != FORMAT_UNCHECKED).then(|| get(key::CHECKSUM)).transpose()?;
        let state_checked = format == FORMAT;
        if state_checked {
            get(key::STATE)?;
        }
        Ok(Self {
            stage,
            model_config,
            inference,
            training: metadata.get(key::TRAINING).cloned(),
            checksum,
            state_checked,
            metadata,
            reader,
            name: name.to_path_buf(),
        })
    }

    /// Fails unless the checkpoint holds `stage`.
    pub fn expect_stage(&self, stage: Stage) -> Result<(), CheckpointError> {
        if self.stage == stage {
            Ok(())
        } else {
            Err(CheckpointError::WrongStage {
                path: self.name.clone(),
                expected: stage.name(),
                found: self.stage.name(),
            })
        }
    }

    /// `model` with the stored weights, in f32: the tensors are read once and converted once,
    /// while (on another core, where there is one) they are verified against their checksums
    /// and for non-finite values; the model is built only from verified weights.
    pub fn build<M: Module>(self, model: M) -> Result<M, CheckpointError> {
        let name = self.name.clone();
        let format = |problem: FormatProblem| CheckpointError::Format { path: name.clone(), problem };
        let (_, _, weights) =
            self.tensors_with(|stored| stored.par_iter().map(Entry::to_f32).collect()).map_err(format)?;
        apply(model, weights, &name)
    }

    /// The whole checkpoint, as training reads it to resume.
    fn into_checkpoint(self) -> Result<Checkpoint, CheckpointError> {
        let name = self.name.clone();
        let format = |problem: FormatProblem| CheckpointError::Format { path: name.clone(), problem };
        let (stage, model_config, training, inference) =
            (self.stage, self.model_config.clone(), self.training.clone(), self.inference);
        let (weights, optimizer, ()) = self.tensors_with(|_| ()).map_err(format)?;
        let model = pack(weights).map_err(|source| format(source.into()))?;
        Ok(Checkpoint { stage, model_config, model, optimizer, training, inference })
    }

    /// The model's tensors and the optimizer's bytes, verified against the stored checksums
    /// (every byte a run reads back) and the weights for non-finite values, and what
    /// `alongside` makes of the weights while they are verified (returned only if they pass).
    fn tensors_with<T: Send>(
        self,
        alongside: impl FnOnce(&[Entry]) -> T + Send,
    ) -> Result<(Vec<Entry>, Option<Bytes>, T), FormatProblem> {
        let (model, optimizer) = split(self.reader.into_tensors()?)?;
        let (verified, made) = rayon::join(|| verify(&model, self.checksum.as_deref()), || alongside(&model));
        verified?;
        if self.state_checked {
            let stored = self.metadata.get(key::STATE).cloned().unwrap_or_default();
            let computed = state_checksum(State {
                stage: self.stage.name(),
                model: self.metadata.get(key::MODEL).map_or("", String::as_str),
                training: self.metadata.get(key::TRAINING).map(String::as_str),
                inference: self.metadata.get(key::INFERENCE).map(String::as_str),
                optimizer: optimizer.as_deref(),
            });
            if computed != stored {
                return Err(FormatProblem::StateChecksum { stored, computed });
            }
        }
        Ok((model, optimizer, made))
    }
}

/// Loads a coarse model and its configuration from a checkpoint file.
pub fn load_coarse(path: &Path, device: &Device) -> Result<(CoarseModel, ModelConfig), CheckpointError> {
    let opened = Checkpoint::open(path)?;
    opened.expect_stage(Stage::Coarse)?;
    let config = opened.model_config.clone();
    Ok((opened.build(CoarseModel::new(&config, device))?, config))
}

/// Loads a refinement model and its configuration from a checkpoint file.
pub fn load_refine(path: &Path, device: &Device) -> Result<(RefineModel, ModelConfig), CheckpointError> {
    let opened = Checkpoint::open(path)?;
    opened.expect_stage(Stage::Refine)?;
    let config = opened.model_config.clone();
    Ok((opened.build(RefineModel::new(&config, device))?, config))
}

/// A network small enough to be sized by its module alone (no [`ModelConfig`]), stored in a
/// [`SmallCheckpoint`] of its own format: the mover E_m and the learned optimizer E_o.
pub trait SmallNetwork: Module {
    /// The file's format, `supersvg-NAME/VERSION`.
    const FORMAT: &'static str;
    /// The stage the file names (what errors call the network).
    const STAGE: &'static str;
    /// The network with burn's initial weights on `device`.
    fn fresh(device: &Device) -> Self;
}

impl SmallNetwork for Mover {
    const FORMAT: &'static str = "supersvg-mover/1";
    const STAGE: &'static str = MOVER_STAGE;
    fn fresh(device: &Device) -> Self {
        Mover::new(device)
    }
}

/// The stage a mover's file names.
pub const MOVER_STAGE: &str = "move";

/// A mover's file ([`Mover`]).
pub type MoverCheckpoint = SmallCheckpoint<Mover>;

impl SmallNetwork for LearnedOptimizer {
    const FORMAT: &'static str = "supersvg-optimizer/1";
    const STAGE: &'static str = OPTIMIZER_STAGE;
    fn fresh(device: &Device) -> Self {
        LearnedOptimizer::new(device)
    }
}

/// The learned optimizer's file ([`LearnedOptimizer`]).
pub type OptimizerCheckpoint = SmallCheckpoint<LearnedOptimizer>;

/// A small network's file ([`SmallNetwork`]): its weights and, for resuming training, the
/// optimizer state and the trainer's own state. The container, keys and checks of
/// [`Checkpoint`], without a [`ModelConfig`]: the network's size is its module's.
pub struct SmallCheckpoint<M> {
    /// The weights, as burnpack bytes of a [`burn::store::ModuleRecord`].
    pub model: Bytes,
    /// The optimizer state, as burnpack bytes, when the file is for resuming training.
    pub optimizer: Option<Bytes>,
    /// The trainer's own state as JSON, opaque here.
    pub training: Option<String>,
    network: std::marker::PhantomData<fn() -> M>,
}

impl<M> Clone for SmallCheckpoint<M> {
    fn clone(&self) -> Self {
        Self {
            model: self.model.clone(),
            optimizer: self.optimizer.clone(),
            training: self.training.clone(),
            network: std::marker::PhantomData,
        }
    }
}

impl<M: SmallNetwork> SmallCheckpoint<M> {
    /// A file of `network`'s current weights, in f32 (the network is small).
    pub fn of_model(network: &M) -> Self {
        let model = network.clone().into_record().into_bytes().expect("a record serializes to memory");
        Self { model, optimizer: None, training: None, network: std::marker::PhantomData }
    }

    /// The same weights without the optimizer state, stored in `dtype`: what inference needs.
    /// The trainer's state stays, so a shipped network still says how it was trained.
    pub fn for_inference(&self, dtype: DType, path: &Path) -> Result<Self, CheckpointError> {
        let model = convert(&self.model, dtype)
            .map_err(|source| CheckpointError::Format { path: path.to_path_buf(), problem: source.into() })?;
        Ok(Self {
            model,
            optimizer: None,
            training: self.training.clone(),
            network: std::marker::PhantomData,
        })
    }

    /// Writes it to `path` atomically.
    pub fn save(&self, path: &Path) -> Result<(), CheckpointError> {
        let header = Header {
            format: M::FORMAT,
            stage: M::STAGE,
            model: None,
            training: self.training.as_deref(),
            inference: None,
        };
        write(path, &header, &self.model, self.optimizer.as_ref())
    }

    /// Reads the network's file at `path` (or a stream: [`Checkpoint::open`]), checked against
    /// its checksums.
    pub fn load(path: &Path) -> Result<Self, CheckpointError> {
        Self::read(reader_of(path)?, path)
    }

    /// [`SmallCheckpoint::load`] of a file built into the program; `name` stands for it in
    /// errors.
    pub fn from_bytes(bytes: &'static [u8], name: &Path) -> Result<Self, CheckpointError> {
        let reader = Reader::from_bytes(in_place(bytes))
            .map_err(|source| CheckpointError::Format { path: name.to_path_buf(), problem: source.into() })?;
        Self::read(reader, name)
    }

    fn read(reader: Reader, name: &Path) -> Result<Self, CheckpointError> {
        let format = |problem: FormatProblem| CheckpointError::Format { path: name.to_path_buf(), problem };
        let metadata = reader.metadata().clone();
        let get = |key: &'static str| metadata.get(key).cloned().ok_or(FormatProblem::MissingKey(key));
        let found = get(key::FORMAT).map_err(format)?;
        if found != M::FORMAT {
            // Another network's file given for this one's.
            let stage = metadata.get(key::STAGE).cloned();
            let ours = found.starts_with("supersvg-");
            return Err(match stage {
                Some(stage) if ours => CheckpointError::WrongStage {
                    path: name.to_path_buf(),
                    expected: M::STAGE,
                    found: stage_name(&stage),
                },
                _ => format(FormatProblem::UnsupportedFormat(found)),
            });
        }
        let stored = get(key::CHECKSUM).map_err(format)?;
        let stored_state = get(key::STATE).map_err(format)?;
        let training = metadata.get(key::TRAINING).cloned();
        let (model, optimizer) =
            split(reader.into_tensors().map_err(|e| format(e.into()))?).map_err(format)?;
        verify(&model, Some(&stored)).map_err(format)?;
        let computed = state_checksum(State {
            stage: M::STAGE,
            model: "",
            training: training.as_deref(),
            inference: None,
            optimizer: optimizer.as_deref(),
        });
        if computed != stored_state {
            return Err(format(FormatProblem::StateChecksum { stored: stored_state, computed }));
        }
        let model = pack(model).map_err(|source| format(source.into()))?;
        Ok(Self { model, optimizer, training, network: std::marker::PhantomData })
    }

    /// The checksum of the weights, which the file stores and reading verifies: the network's
    /// identity.
    pub fn weights_checksum(&self) -> String {
        let entries = entries(&self.model).expect("the weights were read from a burnpack");
        checksum(entries.iter().map(|e| (e.name.as_str(), &e.data)))
    }

    /// The network with these weights on `device`; `name` stands for the file in errors.
    pub fn build(&self, device: &Device, name: &Path) -> Result<M, CheckpointError> {
        let weights = entries(&self.model)
            .map_err(|source| CheckpointError::Format { path: name.to_path_buf(), problem: source.into() })?;
        apply(M::fresh(device), weights.iter().map(Entry::to_f32).collect(), name)
    }
}

/// The name errors give a stage a file names: E_c's and E_r's, the small networks', or the
/// file's own word.
fn stage_name(stage: &str) -> &'static str {
    if let Some(stage) = Stage::from_name(stage) {
        return stage.name();
    }
    match stage {
        MOVER_STAGE => MOVER_STAGE,
        OPTIMIZER_STAGE => OPTIMIZER_STAGE,
        _ => "another network's",
    }
}

/// One tensor of a burnpack container.
struct Entry {
    name: String,
    id: Option<u64>,
    data: TensorData,
}

impl Entry {
    fn from_pack(tensor: burn_pack::Tensor) -> Result<Self, burn_pack::Error> {
        let (name, dtype, shape, id, bytes) = tensor.into_parts()?;
        Ok(Self { name, id, data: TensorData::from_bytes(bytes, shape, dtype) })
    }

    /// The entry with a float tensor stored in `dtype`.
    fn in_dtype(self, dtype: DType) -> Self {
        let data = if self.data.dtype().is_float() { self.data.convert_dtype(dtype) } else { self.data };
        Self { data, ..self }
    }

    /// A copy with a float tensor in f32: half precision converted a slice at a time (the
    /// processor's conversion instructions where it has them), not value by value.
    fn to_f32(&self) -> Self {
        let data = match (self.data.dtype(), self.data.as_slice::<f16>()) {
            (DType::F16, Ok(halves)) => {
                let mut values = vec![0.0f32; halves.len()];
                halves.convert_to_f32_slice(&mut values);
                TensorData::new(values, self.data.shape().clone())
            }
            (dtype, _) if dtype.is_float() => self.data.clone().convert_dtype(DType::F32),
            _ => self.data.clone(),
        };
        Self { name: self.name.clone(), id: self.id, data }
    }

    fn into_pack(self) -> burn_pack::Tensor {
        let (bytes, shape, dtype) = self.data.into_parts();
        burn_pack::Tensor::new(self.name, dtype, shape, self.id, bytes)
    }
}

/// The tensors of a burnpack buffer.
fn entries(bytes: &Bytes) -> Result<Vec<Entry>, burn_pack::Error> {
    let tensors = Reader::from_bytes(bytes.clone()).and_then(Reader::into_tensors)?;
    tensors.into_iter().map(Entry::from_pack).collect()
}

/// A burnpack buffer of `entries`.
fn pack(entries: Vec<Entry>) -> Result<Bytes, burn_pack::Error> {
    Writer::new(entries.into_iter().map(Entry::into_pack).collect()).into_bytes()
}

/// `bytes` (a burnpack buffer) with every float tensor stored in `dtype`.
fn convert(bytes: &Bytes, dtype: DType) -> Result<Bytes, burn_pack::Error> {
    pack(entries(bytes)?.into_iter().map(|entry| entry.in_dtype(dtype)).collect())
}

/// [`Fnv`] over each tensor's name, dtype, shape and bytes, in order.
fn checksum<'a>(tensors: impl Iterator<Item = (&'a str, &'a TensorData)>) -> String {
    let mut hash = Fnv::new();
    for (name, data) in tensors {
        hash.feed(name.as_bytes());
        hash.feed(format!("{:?}{:?}", data.dtype(), data.shape()).as_bytes());
        hash.feed(data.as_bytes());
    }
    hash.finish()
}

/// What a checkpoint holds beside its weights, as stored.
struct State<'a> {
    stage: &'a str,
    model: &'a str,
    training: Option<&'a str>,
    inference: Option<&'a str>,
    optimizer: Option<&'a [u8]>,
}

/// [`Fnv`] over a checkpoint's [`State`], each part tagged and its length given, so that a part
/// missing or moved to another changes it too: with the weights' checksum, every byte that
/// `--resume` reads is checked.
fn state_checksum(state: State) -> String {
    let mut hash = Fnv::new();
    let parts = [
        ("stage", Some(state.stage.as_bytes())),
        ("model", Some(state.model.as_bytes())),
        ("training", state.training.map(str::as_bytes)),
        ("inference", state.inference.map(str::as_bytes)),
        ("optimizer", state.optimizer),
    ];
    for (tag, part) in parts {
        hash.feed(tag.as_bytes());
        match part {
            Some(bytes) => hash.feed_part(bytes),
            None => hash.feed(b"none"),
        }
    }
    hash.finish()
}

/// Whether every value of a float tensor is finite (other tensors are). Half-precision values
/// are read from their bits (all exponent bits set: infinite or NaN), not converted.
fn is_finite(data: &TensorData) -> bool {
    let halves = |exponent: u16| {
        data.as_bytes().chunks_exact(2).all(|v| u16::from_le_bytes([v[0], v[1]]) & exponent != exponent)
    };
    match data.dtype() {
        DType::F16 => halves(0x7c00),
        DType::BF16 => halves(0x7f80),
        DType::F32 => data.as_slice::<f32>().is_ok_and(|values| values.iter().all(|v| v.is_finite())),
        dtype if dtype.is_float() => {
            let values = data.clone().convert_dtype(DType::F32);
            values.as_slice::<f32>().is_ok_and(|values| values.iter().all(|v| v.is_finite()))
        }
        _ => true,
    }
}

/// Splits a checkpoint's tensors back into the model's and the optimizer's burnpack buffer.
fn split(tensors: Vec<burn_pack::Tensor>) -> Result<(Vec<Entry>, Option<Bytes>), FormatProblem> {
    let (mut model, mut optimizer) = (Vec::new(), None);
    for tensor in tensors {
        let entry = Entry::from_pack(tensor)?;
        if let Some(rest) = entry.name.strip_prefix(MODEL_PREFIX) {
            model.push(Entry { name: rest.to_string(), ..entry });
        } else if entry.name == OPTIMIZER_BLOB {
            optimizer = Some(entry.data.into_bytes());
        } else {
            return Err(FormatProblem::UnexpectedTensor(entry.name));
        }
    }
    if model.is_empty() {
        return Err(FormatProblem::NoWeights);
    }
    Ok((model, optimizer))
}

/// Checks the model's tensors against `stored` (their checksum, when the format has one) and
/// for non-finite values.
fn verify(model: &[Entry], stored: Option<&str>) -> Result<(), FormatProblem> {
    if let Some(stored) = stored {
        let computed = checksum(model.iter().map(|e| (e.name.as_str(), &e.data)));
        if computed != stored {
            return Err(FormatProblem::Checksum { stored: stored.to_string(), computed });
        }
    }
    if let Some(entry) = model.iter().find(|e| !is_finite(&e.data)) {
        return Err(FormatProblem::NonFinite(entry.name.clone()));
    }
    Ok(())
}
