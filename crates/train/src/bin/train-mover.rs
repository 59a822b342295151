//! `train-mover`: trains the mover E_m on its teacher's moves of SuperSVG-B's drawings.
//!
//! `train-mover --config configs/mover.toml [--out DIR] [--resume | --overwrite]`

use std::path::PathBuf;
use std::process::ExitCode;

use burn::tensor::Device;
use clap::Parser;
use common::say;
use train::{Begin, MoverConfig, MoverError, mover_checkpoint, train_mover};

/// Train the mover E_m of SuperSVG.
#[derive(Parser, Debug)]
#[command(name = "train-mover", version)]
struct Args {
    /// The TOML config file.
    #[arg(long)]
    config: PathBuf,
    /// Output folder: the teacher's samples and mover.ckpt.
    #[arg(long, default_value = "runs/mover")]
    out: PathBuf,
    /// Continue from the checkpoint in the output folder.
    #[arg(long, conflicts_with = "overwrite")]
    resume: bool,
    /// Start afresh where the output folder already holds a checkpoint, replacing it (the
    /// teacher's samples are kept).
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
    let checkpoint = mover_checkpoint(&args.out);
    let result = common::outputs::check_not_input(&checkpoint, &[&args.config])
        .map_err(MoverError::from)
        .and_then(|()| MoverConfig::load(&args.config))
        .and_then(|config| train_mover(&config, &args.out, begin, &Device::flex().autodiff()));
    match result {
        Ok(summary) => {
            let last = summary.state.held_out.last().copied().unwrap_or(f64::NAN);
            say!(
                "done: {} steps in {:.0} s, held-out {last:.4} px² (moving nothing {:.4}); checkpoint {}",
                summary.state.step,
                summary.state.seconds,
                summary.state.still,
                summary.checkpoint.display()
            );
            ExitCode::SUCCESS
        }
        Err(err) => {
            say!("error: {}", common::say::chain(&err));
            let stopped = matches!(
                err,
                MoverError::Interrupted { .. } | MoverError::InterruptedBefore { .. } | MoverError::Stopped
            );
            ExitCode::from(if stopped { 130 } else { 1 })
        }
    }
}
