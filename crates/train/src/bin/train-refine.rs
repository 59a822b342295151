//! `train-refine`: trains the refinement model E_r, guided by a trained coarse model.
//!
//! `train-refine --config configs/refine.toml --init DIR/coarse.ckpt [--weights E_R.ckpt] [--out DIR] [--backend …] [--steps N] [--resume]`

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;
use model::{RefineModel, load_coarse, load_refine};
use train::cli::{CommonArgs, finish};
use train::config::{self, RefineConfig};
use train::inference::RefineCheck;
use train::objective::RefineObjective;
use train::trainer::{Run, checkpoint_path, model_from, resume_from, train};
use train::validation::Validation;

/// Train the refinement model E_r of SuperSVG from a trained coarse model.
#[derive(Parser, Debug)]
#[command(name = "train-refine", version)]
struct Args {
    #[command(flatten)]
    common: CommonArgs,
    /// The trained coarse checkpoint: the frozen teacher, and E_r's initial encoder.
    #[arg(long)]
    init: PathBuf,
    /// Start from this refinement checkpoint's weights (fine-tuning an E_r, such as
    /// models/refine.ckpt) instead of a fresh decoder on E_c's encoder; its model must be the
    /// `--init` model's.
    #[arg(long)]
    weights: Option<PathBuf>,
}

fn main() -> ExitCode {
    let args = Args::parse();
    finish(run(args.common, args.init, args.weights))
}

fn run(
    args: CommonArgs,
    init: PathBuf,
    weights: Option<PathBuf>,
) -> Result<train::trainer::Summary, Box<dyn std::error::Error>> {
    // Before any image is read: a stop while decoding is heard, and ends the program cleanly.
    train::trainer::catch_interrupts();
    let mut config: RefineConfig = config::load(&args.config)?;
    if let Some(steps) = args.steps {
        config.train.steps = steps;
    }
    let dir = args.out.unwrap_or_else(|| "runs/refine".into());
    let device = args.backend.autodiff_device()?;
    let (teacher, coarse_config) = load_coarse(&init, &device)?;
    let model_config = config.model.apply(&coarse_config);
    let resume = if args.resume { Some(resume_from::<RefineObjective>(&dir)?) } else { None };
    let path = checkpoint_path::<RefineObjective>(&dir);
    let weights = match weights {
        Some(path) => {
            let (model, config) = load_refine(&path, &device)?;
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
    let fresh = |c: &model::ModelConfig| {
        weights.clone().unwrap_or_else(|| RefineModel::new(c, &device).inherit_encoder(&teacher))
    };
    let start = model_from(fresh, &model_config.clone(), resume, &path, (&device, config.train.seed))?;
    let mut objective = RefineObjective::new(&config, teacher, model_config.input);
    objective.check = RefineCheck::build(&config.validation, config.data.compactness, &start.model_config)?;
    let config_json = serde_json::to_value(&config)?;
    let validation = Validation::scheduled(
        &config.validation,
        &config.data,
        &start.model_config,
        config.loss.boundary.dilation,
    )?;
    let run = Run { dir, device, validation, overwrite: args.overwrite };
    Ok(train(&objective, start, &config.train, &config.data, config_json, &run)?)
}
