//! `train-mover`: trains the mover E_m on its teacher's moves of SuperSVG-B's drawings.
//!
//! `train-mover --config configs/mover.toml [--out DIR] [--resume | --overwrite]`

use std::path::PathBuf;
use std::process::ExitCode;

use burn::tensor::Device;
use clap::Parser;
use train::{Begin, MoverConfig, MoverError, train_mover};

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
    let result = MoverConfig::load(&args.config)
        .and_then(|config| train_mover(&config, &args.out, begin, &Device::flex().autodiff()));
    match result {
        Ok(summary) => {
            let last = summary.state.held_out.last().copied().unwrap_or(f64::NAN);
            eprintln!(
                "done: {} steps in {:.0} s, held-out {last:.4} px² (moving nothing {:.4}); checkpoint {}",
                summary.state.step,
                summary.state.seconds,
                summary.state.still,
                summary.checkpoint.display()
            );
            ExitCode::SUCCESS
        }
        Err(err) => {
            eprintln!("error: {err}");
            ExitCode::from(if matches!(err, MoverError::Interrupted { .. }) { 130 } else { 1 })
        }
    }
}
