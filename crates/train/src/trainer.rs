//! The training loop both stages share: resumable, observable, interruptible.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use burn::module::Module;
use burn::optim::{GradientsParams, ModuleOptimizer};
use burn::store::RecordError;
use burn::tensor::{Bytes, DType, Device};
use model::{Checkpoint, CheckpointError, CropBatch, ModelConfig};
use raster::paint_soft;
use serde::{Deserialize, Serialize};

use crate::config::{DataConfig, OptimConfig};
use crate::data::{DataError, DataSource, Loader};
use crate::objective::Objective;
use crate::optimizer::adamw;
use crate::preview::write_preview;
use crate::report::{Reporter, StepRecord};
use crate::schedule::learning_rate;
use crate::stop::{catch_interrupts, heard, interrupted};
use crate::validation::Validation;

/// Why training stopped early.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    /// A checkpoint could not be read or written.
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
    /// The data could not be prepared.
    #[error(transparent)]
    Data(#[from] DataError),
    /// The output folder or a log could not be written.
    #[error("{path}: {source}")]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// What went wrong.
        source: std::io::Error,
    },
    /// A preview image could not be written.
    #[error("{path}: {source}")]
    Preview {
        /// The preview file.
        path: PathBuf,
        /// The file system's reason.
        source: std::io::Error,
    },
    /// The optimizer state could not be serialized for a checkpoint.
    #[error("{path}: optimizer state: {source}")]
    Optimizer {
        /// The checkpoint being written.
        path: PathBuf,
        /// burn's reason.
        source: RecordError,
    },
    /// The output folder cannot be used (a file in its place, another run writing to it).
    #[error(transparent)]
    Output(#[from] common::outputs::OutputError),
    /// `--resume` found no usable training state.
    #[error("{path}: cannot resume: {problem}")]
    Resume {
        /// The checkpoint.
        path: PathBuf,
        /// What is missing.
        problem: ResumeProblem,
    },
    /// A loss term became NaN or infinite; the last good checkpoint, if any, is kept.
    #[error("loss term `{term}` became {value} at step {step}; stopped, {}", kept_checkpoint(.checkpoint))]
    NonFinite {
        /// The offending term.
        term: String,
        /// Its value.
        value: f32,
        /// The step it happened at (1-based).
        step: usize,
        /// The checkpoint left in place, when one was written (or resumed from).
        checkpoint: Option<PathBuf>,
    },
    /// Ctrl-C or SIGTERM: a checkpoint was saved first (when there was anything to save).
    #[error("interrupted at step {step}; {}", saved_checkpoint(.checkpoint))]
    Interrupted {
        /// Steps completed.
        step: usize,
        /// The checkpoint written; `None` when the run was stopped before its first step.
        checkpoint: Option<PathBuf>,
    },
    /// The output folder already holds this stage's checkpoint and neither `--resume` nor
    /// `--overwrite` was given: a new run would replace a trained model.
    #[error(
        "{}: a checkpoint is already there; continue it with --resume, or start again with --overwrite",
        .0.display()
    )]
    Exists(PathBuf),
}

/// The end of a [`TrainError::NonFinite`] message.
fn kept_checkpoint(checkpoint: &Option<PathBuf>) -> String {
    match checkpoint {
        Some(path) => format!("the last good checkpoint is kept at {}", path.display()),
        None => "before any checkpoint was written".to_string(),
    }
}

/// The end of a [`TrainError::Interrupted`] message.
fn saved_checkpoint(checkpoint: &Option<PathBuf>) -> String {
    match checkpoint {
        Some(path) => format!("saved {} (continue with --resume)", path.display()),
        None => "before the first step, nothing to save".to_string(),
    }
}

/// Why a checkpoint cannot continue a training run.
#[derive(Debug, thiserror::Error)]
pub enum ResumeProblem {
    /// An inference checkpoint (exported): it has no optimizer state.
    #[error("it holds no optimizer state")]
    NoOptimizerState,
    /// It has no trainer state (step, schedules).
    #[error("it holds no training state")]
    NoTrainingState,
    /// The trainer state does not parse.
    #[error("damaged training state: {0}")]
    TrainingState(serde_json::Error),
    /// The optimizer state does not fit this optimizer.
    #[error("optimizer state: {0}")]
    Optimizer(RecordError),
    /// The checkpoint's model is not the one this run builds (another config, or another
    /// `--init`).
    #[error("its model configuration differs from this run's ({0})")]
    ConfigDiffers(String),
}

/// The trainer's own state, stored in checkpoints as JSON.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TrainingState {
    /// Steps completed.
    pub step: usize,
    /// Wall seconds spent training so far.
    pub seconds: f64,
    /// The full configuration the run used.
    pub config: serde_json::Value,
    /// Exponential moving averages (over about the last 50 steps) of every loss term: what the
    /// model currently achieves, e.g. how many paths it keeps visible.
    #[serde(default)]
    pub recent: BTreeMap<String, f32>,
}

/// A run's settings outside the config file.
pub struct Run {
    /// Output folder (checkpoint, metrics, previews).
    pub dir: PathBuf,
    /// The device, with autodiff.
    pub device: Device,
    /// Held-out crops scored (and previewed) every `every` steps and at the end.
    pub validation: Option<(Validation, usize)>,
    /// Start afresh even where the output folder already holds a checkpoint (replacing it, and
    /// starting `metrics.jsonl` again).
    pub overwrite: bool,
}

/// Where a run starts: a fresh model, or a checkpoint's model, optimizer and step.
pub struct Start<M> {
    /// The model to train.
    pub model: M,
    /// Its configuration (stored in every checkpoint).
    pub model_config: ModelConfig,
    /// Optimizer state to restore, steps and seconds already done.
    pub resumed: Option<(Bytes, TrainingState)>,
}

/// What a finished run reports.
#[derive(Clone, Debug)]
pub struct Summary {
    /// Steps completed in total.
    pub steps: usize,
    /// The last step's total loss.
    pub final_loss: f32,
    /// Wall seconds of training, over all sessions.
    pub seconds: f64,
    /// The checkpoint written.
    pub checkpoint: PathBuf,
}

/// The checkpoint a stage writes in `dir`.
pub fn checkpoint_path<O: Objective>(dir: &Path) -> PathBuf {
    let stage = match O::STAGE {
        model::Stage::Coarse => "coarse",
        model::Stage::Refine => "refine",
    };
    dir.join(format!("{stage}.ckpt"))
}

/// Reads what `--resume` needs from the stage's checkpoint in `dir`: the model configuration,
/// the checkpoint (to apply to a model built from that configuration), optimizer and state.
pub fn resume_from<O: Objective>(dir: &Path) -> Result<(Checkpoint, Bytes, TrainingState), TrainError> {
    let path = checkpoint_path::<O>(dir);
    let checkpoint = Checkpoint::load(&path)?;
    checkpoint.expect_stage(O::STAGE, &path)?;
    let resume_error = |problem| TrainError::Resume { path: path.clone(), problem };
    let optimizer =
        checkpoint.optimizer.clone().ok_or_else(|| resume_error(ResumeProblem::NoOptimizerState))?;
    let training =
        checkpoint.training.as_deref().ok_or_else(|| resume_error(ResumeProblem::NoTrainingState))?;
    let state: TrainingState =
        serde_json::from_str(training).map_err(|err| resume_error(ResumeProblem::TrainingState(err)))?;
    Ok((checkpoint, optimizer, state))
}

/// Horizon (steps) of the moving averages kept in [`TrainingState::recent`].
const RECENT_STEPS: f32 = 50.0;

/// Trains `start.model` with `objective` for `optim.steps` steps (from where `start` left off),
/// writing `metrics.jsonl`, previews and checkpoints in `run.dir`.
pub fn train<O: Objective>(
    objective: &O,
    start: Start<O::Model>,
    optim: &OptimConfig,
    data: &DataConfig,
    config_json: serde_json::Value,
    run: &Run,
) -> Result<Summary, TrainError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| TrainError::Io { path, source }
    };
    common::outputs::create_folder(&run.dir)?;
    // One run a folder: a second would replace the first's checkpoint and metrics under it.
    let _lock = common::outputs::lock_folder(&run.dir)?;
    catch_interrupts();
    let checkpoint = checkpoint_path::<O>(&run.dir);
    let Start { mut model, model_config, resumed } = start;
    if resumed.is_none() && !run.overwrite && checkpoint.exists() {
        return Err(TrainError::Exists(checkpoint));
    }
    // The checkpoint a failure leaves in place: the one resumed from, then the latest written.
    let mut kept = resumed.as_ref().map(|_| checkpoint.clone());
    let mut optimizer = adamw(optim);
    let (first_step, mut seconds, mut recent) = match resumed {
        Some((bytes, state)) => {
            optimizer = optimizer.from_bytes(bytes).map_err(|err| TrainError::Resume {
                path: checkpoint.clone(),
                problem: ResumeProblem::Optimizer(err),
            })?;
            (state.step, state.seconds, state.recent)
        }
        None => (0, 0.0, BTreeMap::new()),
    };
    let save = |model: &O::Model,
                optimizer: &ModuleOptimizer,
                step: usize,
                seconds: f64,
                recent: &BTreeMap<String, f32>|
     -> Result<(), TrainError> {
        let mut file = Checkpoint::of_model(O::STAGE, &model_config, model, DType::F32);
        file.optimizer = Some(
            optimizer
                .into_bytes()
                .map_err(|source| TrainError::Optimizer { path: checkpoint.clone(), source })?,
        );
        let state = TrainingState { step, seconds, config: config_json.clone(), recent: recent.clone() };
        file.training = Some(serde_json::to_string(&state).expect("training state serializes"));
        file.save(&checkpoint)?;
        Ok(())
    };

    let source = Arc::new(DataSource::new(data, &model_config, optim.batch_size, optim.seed)?);
    if interrupted() {
        return Err(TrainError::Interrupted { step: first_step, checkpoint: kept });
    }
    let mut loader = Loader::start(source, first_step as u64, data.workers, data.prefetch);
    // A run that does not resume starts the metrics file again: two step-1 series never mix.
    let fresh_log = kept.is_none();
    let mut reporter = Reporter::open(&run.dir, first_step, optim.steps, fresh_log).map_err(io(&run.dir))?;
    if first_step > 0 {
        reporter.say(&format!("resuming from {} at step {first_step}", checkpoint.display()));
    }
    let mut final_loss = f32::NAN;
    for step in first_step..optim.steps {
        if interrupted() {
            heard();
            save(&model, &optimizer, step, seconds, &recent)?;
            reporter.finish();
            return Err(TrainError::Interrupted { step, checkpoint: Some(checkpoint) });
        }
        let started = Instant::now();
        let batch = loader.next_batch()?;
        let data_seconds = started.elapsed().as_secs_f64();
        let output = objective.step(&model, &batch.tensors(&run.device), step);

        let total: f32 = output.total.clone().into_scalar();
        let mut values: Vec<(&'static str, f32)> =
            output.terms.iter().map(|(name, term)| (*name, term.clone().into_scalar::<f32>())).collect();
        if let Some((term, value)) =
            std::iter::once(("loss", total)).chain(values.iter().copied()).find(|(_, v)| !v.is_finite())
        {
            reporter.finish();
            return Err(TrainError::NonFinite { term: term.into(), value, step: step + 1, checkpoint: kept });
        }
        for &(name, value) in std::iter::once(&("loss", total)).chain(&values) {
            let average = recent.entry(name.to_string()).or_insert(value);
            *average += (value - *average) / RECENT_STEPS;
        }
        values.extend(output.weights.iter().copied());

        let lr = learning_rate(optim, step);
        let grads = GradientsParams::from_grads(output.total.backward(), &model);
        model = optimizer.step(lr, model, grads);

        let step_seconds = started.elapsed().as_secs_f64();
        seconds += step_seconds;
        final_loss = total;
        let done = step + 1;
        if done % optim.log_every == 0 || done == optim.steps {
            let record = StepRecord {
                step: done,
                lr,
                loss: total,
                values,
                seconds: step_seconds,
                data_seconds,
                samples_per_second: optim.batch_size as f64 / step_seconds,
            };
            reporter.record(&record).map_err(io(&run.dir))?;
        }
        if let Some((validation, every)) = &run.validation {
            if done % every == 0 || done == optim.steps {
                validate(objective, &model, validation, done, &run.device, &mut reporter, &run.dir)?;
            }
        }
        if done % optim.checkpoint_every == 0 && done != optim.steps {
            save(&model, &optimizer, done, seconds, &recent)?;
            kept = Some(checkpoint.clone());
        }
    }
    save(&model, &optimizer, optim.steps.max(first_step), seconds, &recent)?;
    reporter.finish();
    Ok(Summary { steps: optim.steps.max(first_step), final_loss, seconds, checkpoint })
}

/// Scores `model` on the validation crops into the metrics file and writes a preview of them.
fn validate<O: Objective>(
    objective: &O,
    model: &O::Model,
    validation: &Validation,
    step: usize,
    device: &Device,
    reporter: &mut Reporter,
    dir: &Path,
) -> Result<(), TrainError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| TrainError::Io { path, source }
    };
    let device = device.clone().inner();
    let crops = CropBatch::new(validation.crops(), &device);
    let model = model.valid();
    let paths = objective.draw(&model, &crops);
    let scores = validation.score(&paths.to_scenes());
    reporter.validation(step, &scores).map_err(io(dir))?;
    // Scoring at inference draws whole images and hears a stop between them; scores cut short
    // are not recorded, and the loop saves and ends.
    let at_inference = objective.score_at_inference(&model, &device);
    if interrupted() {
        return Ok(());
    }
    if let Some(scores) = at_inference {
        reporter.at_inference(step, &scores).map_err(io(dir))?;
    }
    let [batch, _, size, _] = crops.pixels.dims();
    let flat = crops.mean_colours().expand([batch, 3, size, size]);
    let render: Vec<f32> =
        paint_soft(flat, &paths, objective.raster()).try_to_vec_as().expect("render is readable");
    let path = dir.join(format!("preview-{step:06}.png"));
    write_preview(&path, validation.crops(), &render, &paths, &validation.mean_colours(), 8)
        .map_err(|source| TrainError::Preview { path: path.clone(), source })
}

/// The settings in which two model configurations differ, as `key: theirs ≠ ours`.
fn describe_difference(theirs: &ModelConfig, ours: &ModelConfig) -> String {
    let (theirs, ours) = (serde_json::to_value(theirs), serde_json::to_value(ours));
    let (Ok(serde_json::Value::Object(theirs)), Ok(serde_json::Value::Object(ours))) = (theirs, ours) else {
        return "the configurations differ".to_string();
    };
    let differing: Vec<String> = theirs
        .iter()
        .filter(|(key, value)| ours.get(*key) != Some(value))
        .map(|(key, value)| format!("{key}: {value} ≠ {}", ours.get(key).unwrap_or(&serde_json::Value::Null)))
        .collect();
    differing.join(", ")
}

/// Builds a model of `config` (its initialization drawn from `seed` on `device`), or takes the
/// checkpoint's weights when resuming, which must be of the same configuration (the config file's
/// model, or for E_r the `--init` model's).
pub fn model_from<M: Module>(
    fresh: impl Fn(&ModelConfig) -> M,
    config: &ModelConfig,
    resume: Option<(Checkpoint, Bytes, TrainingState)>,
    path: &Path,
    (device, seed): (&Device, u64),
) -> Result<Start<M>, TrainError> {
    device.seed(seed);
    match resume {
        None => Ok(Start { model: fresh(config), model_config: config.clone(), resumed: None }),
        Some((checkpoint, optimizer, state)) => {
            if checkpoint.model_config != *config {
                let problem =
                    ResumeProblem::ConfigDiffers(describe_difference(&checkpoint.model_config, config));
                return Err(TrainError::Resume { path: path.to_path_buf(), problem });
            }
            let model = checkpoint.apply(fresh(&checkpoint.model_config), path)?;
            Ok(Start { model, model_config: checkpoint.model_config, resumed: Some((optimizer, state)) })
        }
    }
}
