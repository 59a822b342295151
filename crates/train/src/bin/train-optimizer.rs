//! `train-optimizer`: trains the learned optimizer E_o, SuperSVG-F's first steps.
//!
//! `train-optimizer --config configs/optimizer.toml [--out DIR] [--resume | --overwrite]`

use std::path::PathBuf;
use std::process::ExitCode;

use burn::tensor::Device;
use clap::Parser;
use common::say;
use train::{Begin, OptimizerConfig, OptimizerError, optimizer_checkpoint, train_optimizer};

/// Train the learned optimizer E_o of SuperSVG-F.
#[derive(Parser, Debug)]
#[command(name = "train-optimizer", version)]
struct Args {
    /// The TOML config file.
    #[arg(long)]
    config: PathBuf,
    /// Output folder: optimizer.ckpt.
    #[arg(long, default_value = "runs/optimizer")]
    out: PathBuf,
    /// Continue from the checkpoint in the output folder.
    #[arg(long, conflicts_with = "overwrite")]
    resume: bool,
    /// Start afresh where the output folder already holds a checkpoint, replacing it.
    #[arg(long)]
    overwrite: bool,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let begin = match (args.resume, args.overwrite) {
        (true, _) => Begin::Resume,
        (_, true) => Begin::Overwrite,
        _ => Begin::Fresh,
    };
    let result = common::outputs::check_not_input(&optimizer_checkpoint(&args.out), &[&args.config])
        .map_err(OptimizerError::from)
        .and_then(|()| OptimizerConfig::load(&args.config))
        .and_then(|config| train_optimizer(&config, &args.out, begin, &Device::flex().autodiff()));
    match result {
        Ok(summary) => {
            say!(
                "done: {} updates in {:.0} s; checkpoint {}",
                summary.state.update,
                summary.state.seconds,
                summary.checkpoint.display()
            );
            ExitCode::SUCCESS
        }
        Err(err) => {
            say!("error: {}", common::say::chain(&err));
            let stopped =
                matches!(err, OptimizerError::Interrupted { .. } | OptimizerError::InterruptedBefore);
            ExitCode::from(if stopped { 130 } else { 1 })
        }
    }
}
