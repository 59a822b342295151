//! The command line both training programs share.

use std::path::PathBuf;

use clap::Args;
use raster::Backend;

use crate::data::DataError;
use crate::trainer::{Summary, TrainError};

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
    /// Total steps, overriding `train.steps` of the config.
    #[arg(long)]
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
            eprintln!(
                "done: {} steps, final loss {:.5}, {:.0} s of training; checkpoint {}",
                summary.steps,
                summary.final_loss,
                summary.seconds,
                summary.checkpoint.display()
            );
            ExitCode::SUCCESS
        }
        Err(err) => {
            eprintln!("error: {err}");
            let interrupted =
                err.downcast_ref::<TrainError>().is_some_and(|e| {
                    matches!(e, TrainError::Interrupted { .. } | TrainError::Data(DataError::Interrupted(_)))
                }) || err.downcast_ref::<DataError>().is_some_and(|e| matches!(e, DataError::Interrupted(_)));
            ExitCode::from(if interrupted { 130 } else { 1 })
        }
    }
}
