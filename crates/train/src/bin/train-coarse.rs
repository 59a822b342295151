//! `train-coarse`: trains the coarse model E_c.
//!
//! `train-coarse --config configs/coarse.toml [--out DIR] [--backend flex|ndarray|wgpu] [--steps N] [--resume]
//! [--init CKPT]`

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;
use model::{CoarseModel, load_coarse};
use train::cli::{CommonArgs, finish};
use train::config::{self, CoarseConfig};
use train::inference::CoarseCheck;
use train::objective::CoarseObjective;
use train::trainer::{Run, checkpoint_path, model_from, resume_from, train};
use train::validation::Validation;

/// Train the coarse model E_c of SuperSVG.
#[derive(Parser, Debug)]
#[command(name = "train-coarse", version)]
struct Args {
    #[command(flatten)]
    common: CommonArgs,
    /// Start from this coarse checkpoint's weights instead of a random initialization
    /// (fine-tuning; its model must be the config's). A resumed run takes its own checkpoint's.
    #[arg(long)]
    init: Option<PathBuf>,
}

fn main() -> ExitCode {
    let args = Args::parse();
    finish(run(args.common, args.init))
}

fn run(
    args: CommonArgs,
    init: Option<PathBuf>,
) -> Result<train::trainer::Summary, Box<dyn std::error::Error>> {
    // Before any image is read: a stop while decoding is heard, and ends the program cleanly.
    train::trainer::catch_interrupts();
    let mut config: CoarseConfig = config::load(&args.config)?;
    if let Some(steps) = args.steps {
        config.train.steps = steps;
    }
    let dir = args.out.unwrap_or_else(|| "runs/coarse".into());
    let device = args.backend.autodiff_device()?;
    let mut objective = CoarseObjective::new(&config);
    let init = match init {
        Some(path) => {
            let (model, model_config) = load_coarse(&path, &device)?;
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
    let resume = if args.resume { Some(resume_from::<CoarseObjective>(&dir)?) } else { None };
    let path = checkpoint_path::<CoarseObjective>(&dir);
    let start = model_from(
        |c| init.clone().unwrap_or_else(|| CoarseModel::new(c, &device)),
        &config.model.0,
        resume,
        &path,
        (&device, config.train.seed),
    )?;
    objective.check = CoarseCheck::build(&config.validation, config.data.compactness, &start.model_config)?;
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
