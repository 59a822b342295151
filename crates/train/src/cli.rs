//! The command line both training programs share, and what each runs: `train-coarse` and
//! `train-refine` are their flags and one call here.

use std::error::Error;
use std::path::PathBuf;

use burn::tensor::Device;
use clap::Args;
use model::{CoarseModel, RefineModel, load_coarse, load_refine};
use raster::Backend;

use crate::config::{self, CoarseConfig, DataConfig, OptimConfig, RefineConfig, ValidationConfig};
use crate::data::DataError;
use crate::inference::{CoarseCheck, RefineCheck};
use crate::objective::{CoarseObjective, Objective, RefineObjective};
use crate::stop::catch_interrupts;
use crate::trainer::{Run, Start, Summary, TrainError, checkpoint_path, model_from, resume_from, train};
use crate::validation::Validation;

/// Flags common to `train-coarse` and `train-refine`.
#[derive(Args, Debug)]
pub struct CommonArgs {
    /// The TOML config file.
    #[arg(long)]
    pub config: PathBuf,
    /// Output folder: checkpoint, metrics.jsonl, previews.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Compute backend: flex, ndarray or wgpu.
    #[arg(long, default_value = "flex")]
    pub backend: Backend,
    /// Total steps (at least 1), overriding `train.steps` of the config.
    #[arg(long, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub steps: Option<usize>,
    /// Continue from the checkpoint in the output folder.
    #[arg(long, conflicts_with = "overwrite")]
    pub resume: bool,
    /// Start afresh where the output folder already holds a checkpoint, replacing it (without
    /// this or `--resume`, such a folder is refused).
    #[arg(long)]
    pub overwrite: bool,
}

/// Prints a training result and turns it into the process's exit code: 0 done, 130
/// interrupted (checkpoint saved), 1 any error.
pub fn finish(result: Result<Summary, Box<dyn std::error::Error>>) -> std::process::ExitCode {
    use std::process::ExitCode;
    match result {
        Ok(summary) => {
            common::say!(
                "done: {} steps, final loss {:.5}, {:.0} s of training; checkpoint {}",
                summary.steps,
                summary.final_loss,
                summary.seconds,
                summary.checkpoint.display()
            );
            ExitCode::SUCCESS
        }
        Err(err) => {
            common::say!("error: {}", common::say::chain(err.as_ref()));
            let interrupted =
                err.downcast_ref::<TrainError>().is_some_and(|e| {
                    matches!(e, TrainError::Interrupted { .. } | TrainError::Data(DataError::Interrupted(_)))
                }) || err.downcast_ref::<DataError>().is_some_and(|e| matches!(e, DataError::Interrupted(_)));
            ExitCode::from(if interrupted { 130 } else { 1 })
        }
    }
}

/// A program's run: the folder, the device and the checkpoint it resumes, read off its flags.
struct Launch<'a> {
    args: &'a CommonArgs,
    dir: PathBuf,
    device: Device,
}

impl<'a> Launch<'a> {
    /// Catches interrupts first (a stop while the data is read is heard and ends the program
    /// cleanly), then opens the device; the output folder defaults to `runs/STAGE`.
    fn new(args: &'a CommonArgs, stage: &str) -> Result<Self, Box<dyn Error>> {
        catch_interrupts();
        let dir = args.out.clone().unwrap_or_else(|| PathBuf::from("runs").join(stage));
        Ok(Self { args, dir, device: args.backend.autodiff_device()? })
    }

    /// Refuses a run whose checkpoint or metrics would land on one of `inputs` (its config,
    /// `--init`, `--weights`), by any name.
    fn refuse_inputs<O: Objective>(&self, inputs: &[Option<&PathBuf>]) -> Result<(), Box<dyn Error>> {
        let inputs: Vec<&PathBuf> =
            std::iter::once(&self.args.config).chain(inputs.iter().flatten().copied()).collect();
        for output in [checkpoint_path::<O>(&self.dir), self.dir.join("metrics.jsonl")] {
            common::outputs::check_not_input(&output, &inputs)?;
        }
        Ok(())
    }

    /// The model to start from: the checkpoint in the folder with `--resume`, else `fresh`.
    fn start<O: Objective>(
        &self,
        fresh: impl Fn(&model::ModelConfig) -> O::Model,
        config: &model::ModelConfig,
        seed: u64,
    ) -> Result<Start<O::Model>, TrainError> {
        let resume = if self.args.resume { Some(resume_from::<O>(&self.dir)?) } else { None };
        model_from(fresh, config, resume, &checkpoint_path::<O>(&self.dir), (&self.device, seed))
    }

    /// Trains `objective` from `start`, scoring the config's validation set on schedule.
    fn train<O: Objective>(
        self,
        objective: &O,
        start: Start<O::Model>,
        (optim, data, validation, dilation): (&OptimConfig, &DataConfig, &ValidationConfig, usize),
        config_json: serde_json::Value,
    ) -> Result<Summary, Box<dyn Error>> {
        let validation = Validation::scheduled(validation, data, &start.model_config, dilation)?;
        let run = Run { dir: self.dir, device: self.device, validation, overwrite: self.args.overwrite };
        Ok(train(objective, start, optim, data, config_json, &run)?)
    }
}

/// `train-coarse`: E_c from a random start, or from `init`'s weights (fine-tuning).
pub fn train_coarse(args: &CommonArgs, init: Option<PathBuf>) -> Result<Summary, Box<dyn Error>> {
    let launch = Launch::new(args, "coarse")?;
    launch.refuse_inputs::<CoarseObjective>(&[init.as_ref()])?;
    let mut config: CoarseConfig = config::load(&args.config)?;
    config.train.steps = args.steps.unwrap_or(config.train.steps);
    let init = match init {
        Some(path) => {
            let (model, model_config) = load_coarse(&path, &launch.device)?;
            if model_config != config.model.0 {
                let config_path = args.config.display();
                return Err(
                    format!("{}: its model is not the [model] of {config_path}", path.display()).into()
                );
            }
            Some(model)
        }
        None => None,
    };
    let device = launch.device.clone();
    let fresh = |c: &model::ModelConfig| init.clone().unwrap_or_else(|| CoarseModel::new(c, &device));
    let start = launch.start::<CoarseObjective>(fresh, &config.model.0, config.train.seed)?;
    let mut objective = CoarseObjective::new(&config);
    objective.check = CoarseCheck::build(&config.validation, config.data.compactness, &start.model_config)?;
    let settings = (&config.train, &config.data, &config.validation, config.loss.boundary.dilation);
    launch.train(&objective, start, settings, serde_json::to_value(&config)?)
}

/// `train-refine`: E_r guided by the trained E_c of `init`, from a fresh head on E_c's encoder
/// or from `weights` (fine-tuning an E_r).
pub fn train_refine(
    args: &CommonArgs,
    init: PathBuf,
    weights: Option<PathBuf>,
) -> Result<Summary, Box<dyn Error>> {
    let launch = Launch::new(args, "refine")?;
    launch.refuse_inputs::<RefineObjective>(&[Some(&init), weights.as_ref()])?;
    let mut config: RefineConfig = config::load(&args.config)?;
    config.train.steps = args.steps.unwrap_or(config.train.steps);
    let (teacher, coarse_config) = load_coarse(&init, &launch.device)?;
    let model_config = config.model.apply(&coarse_config);
    let weights = match weights {
        Some(path) => {
            let (model, config) = load_refine(&path, &launch.device)?;
            if config != model_config {
                let init = init.display();
                return Err(format!(
                    "{}: its model is not the model of --init {init} with this config's [model]",
                    path.display()
                )
                .into());
            }
            Some(model)
        }
        None => None,
    };
    let device = launch.device.clone();
    let fresh = |c: &model::ModelConfig| {
        weights.clone().unwrap_or_else(|| RefineModel::new(c, &device).inherit_encoder(&teacher))
    };
    let start = launch.start::<RefineObjective>(fresh, &model_config, config.train.seed)?;
    let mut objective = RefineObjective::new(&config, teacher, model_config.input);
    objective.check = RefineCheck::build(&config.validation, config.data.compactness, &start.model_config)?;
    let settings = (&config.train, &config.data, &config.validation, config.loss.boundary.dilation);
    launch.train(&objective, start, settings, serde_json::to_value(&config)?)
}
