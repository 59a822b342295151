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

use std::path::{Path, PathBuf};

use burn::module::Module;
use burn::store::{ModuleRecord, RecordError};
use burn::tensor::{Bytes, DType, Device, TensorData};
use burn_pack::{Reader, Writer};

use crate::coarse::CoarseModel;
use crate::config::{InvalidSetting, ModelConfig};
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
    /// The file is not a supersvg checkpoint, or its contents are damaged.
    #[error("{path}: not a supersvg checkpoint ({problem})")]
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
    #[error(
        "the weights do not match their checksum (stored {stored}, computed {computed}): the file is damaged"
    )]
    Checksum {
        /// The checksum in the metadata.
        stored: String,
        /// The checksum of the weights read.
        computed: String,
    },
    /// The stage, configuration, trainer's state or optimizer state are not the ones written.
    #[error(
        "the training state does not match its checksum (stored {stored}, computed {computed}): the file is damaged"
    )]
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
    /// The weights, as burnpack bytes of a [`ModuleRecord`].
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
        let write = |source: burn_pack::Error| CheckpointError::Write { path: path.to_path_buf(), source };
        let mut tensors: Vec<Entry> = entries(&self.model)
            .map_err(write)?
            .into_iter()
            .map(|e| Entry { name: format!("{MODEL_PREFIX}{}", e.name), ..e })
            .collect();
        if let Some(optimizer) = &self.optimizer {
            let data = TensorData::new(optimizer.to_vec(), [optimizer.len()]);
            tensors.push(Entry { name: OPTIMIZER_BLOB.into(), id: None, data });
        }
        let model_entries = tensors.iter().filter(|e| e.name != OPTIMIZER_BLOB);
        let sum =
            checksum(model_entries.map(|e| (e.name.strip_prefix(MODEL_PREFIX).unwrap_or(&e.name), &e.data)));
        let tensors = tensors.into_iter().map(Entry::into_pack).collect();
        let model_json = serde_json::to_string(&self.model_config).expect("configs serialize");
        let inference =
            self.inference.as_ref().map(|point| serde_json::to_string(point).expect("serializes"));
        let state = state_checksum(State {
            stage: self.stage.name(),
            model: &model_json,
            training: self.training.as_deref(),
            inference: inference.as_deref(),
            optimizer: self.optimizer.as_deref(),
        });
        let mut writer = Writer::new(tensors)
            .with_metadata(key::FORMAT, FORMAT)
            .with_metadata(key::STAGE, self.stage.name())
            .with_metadata(key::MODEL, &model_json)
            .with_metadata(key::CHECKSUM, &sum)
            .with_metadata(key::STATE, &state)
            .auto_extension(false);
        if let Some(training) = &self.training {
            writer = writer.with_metadata(key::TRAINING, training);
        }
        if let Some(point) = &inference {
            writer = writer.with_metadata(key::INFERENCE, point);
        }
        let bytes = writer.into_bytes().map_err(write)?;
        common::write::write_atomic(path, &bytes)
            .map_err(|source| CheckpointError::Store { path: path.to_path_buf(), source })
    }

    /// Reads a checkpoint from `path`.
    pub fn load(path: &Path) -> Result<Self, CheckpointError> {
        if path.is_dir() {
            return Err(CheckpointError::Folder { path: path.to_path_buf() });
        }
        if !path.exists() {
            return Err(CheckpointError::Missing { path: path.to_path_buf() });
        }
        Self::read(path).map_err(|problem| CheckpointError::Format { path: path.to_path_buf(), problem })
    }

    /// Reads a checkpoint held in memory (one built into a program); `name` stands for it in
    /// errors, as a path does for a file.
    pub fn from_bytes(bytes: &[u8], name: &Path) -> Result<Self, CheckpointError> {
        Reader::from_bytes(Bytes::from_bytes_vec(bytes.to_vec()))
            .map_err(FormatProblem::from)
            .and_then(Self::parse)
            .map_err(|problem| CheckpointError::Format { path: name.to_path_buf(), problem })
    }

    /// The checksum of the weights (what every checkpoint stores and loading verifies): the
    /// identity of a model, whatever file it came in.
    pub fn weights_checksum(&self) -> String {
        let entries = entries(&self.model).expect("the weights were read from a burnpack");
        checksum(entries.iter().map(|e| (e.name.as_str(), &e.data)))
    }

    /// [`Checkpoint::load`] of a file that exists.
    fn read(path: &Path) -> Result<Self, FormatProblem> {
        Self::parse(Reader::from_file(path)?)
    }

    /// The checkpoint in a burnpack `reader`.
    fn parse(reader: Reader) -> Result<Self, FormatProblem> {
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
        let stored = (format != FORMAT_UNCHECKED).then(|| get(key::CHECKSUM)).transpose()?;
        let (model, optimizer) = split(reader.into_tensors()?, stored.as_deref())?;
        if format == FORMAT {
            let stored = get(key::STATE)?;
            let computed = state_checksum(State {
                stage: stage.name(),
                model: &get(key::MODEL)?,
                training: metadata.get(key::TRAINING).map(String::as_str),
                inference: metadata.get(key::INFERENCE).map(String::as_str),
                optimizer: optimizer.as_deref(),
            });
            if computed != stored {
                return Err(FormatProblem::StateChecksum { stored, computed });
            }
        }
        Ok(Self {
            stage,
            model_config,
            model,
            optimizer,
            training: metadata.get(key::TRAINING).cloned(),
            inference,
        })
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
        let mismatch = |source: RecordError| CheckpointError::Mismatch {
            path: path.to_path_buf(),
            problem: source.into(),
        };
        // In f32, the dtype every model here computes in, loaded as stored: casting to each
        // parameter's own dtype instead reads its current value, which draws the random
        // initialization of every weight only to replace it (a fifth of `infer`'s instructions
        // on one photo).
        let weights = convert(&self.model, DType::F32)
            .map_err(|source| CheckpointError::Format { path: path.to_path_buf(), problem: source.into() })?;
        let record = ModuleRecord::from_bytes(weights).map_err(mismatch)?;
        model.try_load_record(record).map_err(mismatch)
    }
}

/// Loads a coarse model and its configuration from a checkpoint file.
pub fn load_coarse(path: &Path, device: &Device) -> Result<(CoarseModel, ModelConfig), CheckpointError> {
    let checkpoint = Checkpoint::load(path)?;
    checkpoint.expect_stage(Stage::Coarse, path)?;
    let model = checkpoint.apply(CoarseModel::new(&checkpoint.model_config, device), path)?;
    Ok((model, checkpoint.model_config))
}

/// Loads a refinement model and its configuration from a checkpoint file.
pub fn load_refine(path: &Path, device: &Device) -> Result<(RefineModel, ModelConfig), CheckpointError> {
    let checkpoint = Checkpoint::load(path)?;
    checkpoint.expect_stage(Stage::Refine, path)?;
    let model = checkpoint.apply(RefineModel::new(&checkpoint.model_config, device), path)?;
    Ok((model, checkpoint.model_config))
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
    let entries = entries(bytes)?
        .into_iter()
        .map(|entry| {
            let data =
                if entry.data.dtype().is_float() { entry.data.convert_dtype(dtype) } else { entry.data };
            Entry { data, ..entry }
        })
        .collect();
    pack(entries)
}

/// FNV-1a, 64 bits: what a flipped bit anywhere in what it is fed changes.
struct Fnv(u64);

impl Fnv {
    fn new() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }

    fn feed(&mut self, bytes: &[u8]) {
        for &byte in bytes {
            self.0 = (self.0 ^ u64::from(byte)).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    fn finish(&self) -> String {
        format!("{:016x}", self.0)
    }
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
            Some(bytes) => {
                hash.feed(&(bytes.len() as u64).to_le_bytes());
                hash.feed(bytes);
            }
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

/// Splits a checkpoint's tensors back into the model and optimizer burnpack buffers, checking the
/// model's against `stored` (its checksum, when the format has one) and for non-finite values.
fn split(
    tensors: Vec<burn_pack::Tensor>,
    stored: Option<&str>,
) -> Result<(Bytes, Option<Bytes>), FormatProblem> {
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
    if let Some(stored) = stored {
        let computed = checksum(model.iter().map(|e| (e.name.as_str(), &e.data)));
        if computed != stored {
            return Err(FormatProblem::Checksum { stored: stored.to_string(), computed });
        }
    }
    if let Some(entry) = model.iter().find(|e| !is_finite(&e.data)) {
        return Err(FormatProblem::NonFinite(entry.name.clone()));
    }
    Ok((pack(model)?, optimizer))
}
