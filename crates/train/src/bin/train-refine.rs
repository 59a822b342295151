//! `train-refine`: trains the refinement model E_r, guided by a trained coarse model.
//!
//! `train-refine --config configs/refine.toml --init DIR/coarse.ckpt [--out DIR] [--backend …] [--steps N] [--resume]`

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;
use model::{RefineModel, load_coarse};
use train::cli::{CommonArgs, finish};
use train::config::{self, RefineConfig};
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
}

fn main() -> ExitCode {
    let args = Args::parse();
    finish(run(args.common, args.init))
}

fn run(args: CommonArgs, init: PathBuf) -> Result<train::trainer::Summary, Box<dyn std::error::Error>> {
    // Before any image is read: a stop while decoding is heard, and ends the program cleanly.
    train::trainer::catch_interrupts();
    let mut config: RefineConfig = config::load(&args.config)?;
    if let Some(steps) = args.steps {
        config.train.steps = steps;
    }
    let dir = args.out.unwrap_or_else(|| "runs/refine".into());
    let device = args.backend.autodiff_device()?;
    let (teacher, model_config) = load_coarse(&init, &device)?;
    let resume = if args.resume { Some(resume_from::<RefineObjective>(&dir)?) } else { None };
    let path = checkpoint_path::<RefineObjective>(&dir);
    let fresh = |c: &model::ModelConfig| RefineModel::new(c, &device).inherit_encoder(&teacher);
    let start = model_from(fresh, &model_config.clone(), resume, &path, (&device, config.train.seed))?;
    let objective = RefineObjective::new(&config, teacher, model_config.input);
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
