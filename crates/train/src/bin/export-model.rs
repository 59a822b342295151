//! `export-model`: turns a training checkpoint into the file `infer` ships with.
//!
//! `export-model runs/coarse/coarse.ckpt models/coarse.ckpt [--dtype f16|f32]`
//!
//! Drops the optimizer state and stores the weights in half precision by default; the model
//! configuration, stage and the trainer's record (steps, seconds, final losses) are kept. A
//! mover's file (`train-mover`'s) and a learned optimizer's (`train-optimizer`'s) are exported
//! the same way.

use std::path::PathBuf;
use std::process::ExitCode;

use burn::tensor::DType;
use clap::{Parser, ValueEnum};
use model::{
    Checkpoint, CheckpointError, MOVER_STAGE, MoverCheckpoint, OPTIMIZER_STAGE, OptimizerCheckpoint,
};

/// Export a training checkpoint for inference.
#[derive(Parser, Debug)]
#[command(name = "export-model", version)]
struct Args {
    /// A checkpoint written by train-coarse, train-refine, train-mover or train-optimizer.
    input: PathBuf,
    /// Where to write the inference checkpoint (atomically; never over the input).
    output: PathBuf,
    /// Precision of the stored weights.
    #[arg(long, value_enum, default_value = "f16")]
    dtype: Precision,
}

/// Storage precision of exported weights.
#[derive(Clone, Copy, Debug, ValueEnum)]
enum Precision {
    F16,
    F32,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let dtype = match args.dtype {
        Precision::F16 => DType::F16,
        Precision::F32 => DType::F32,
    };
    // Before reading anything: an export over its own input would leave a run that cannot resume.
    if let Err(err) = common::outputs::check_output(&args.output, &[&args.input]) {
        common::say!("export-model: {err}");
        return ExitCode::FAILURE;
    }
    // A mover's file, else E_o's, else E_c's or E_r's (a damaged file, or no checkpoint, is said
    // as the first reader finds it).
    let exported = match MoverCheckpoint::load(&args.input) {
        Err(CheckpointError::WrongStage { .. }) => match OptimizerCheckpoint::load(&args.input) {
            Err(CheckpointError::WrongStage { .. }) => Checkpoint::load(&args.input)
                .and_then(|checkpoint| checkpoint.for_inference(dtype, &args.input))
                .and_then(|checkpoint| checkpoint.save(&args.output).map(|()| checkpoint.stage.name())),
            read => read
                .and_then(|file| file.for_inference(dtype, &args.input))
                .and_then(|file| file.save(&args.output).map(|()| OPTIMIZER_STAGE)),
        },
        read => read
            .and_then(|file| file.for_inference(dtype, &args.input))
            .and_then(|file| file.save(&args.output).map(|()| MOVER_STAGE)),
    };
    match exported {
        Ok(stage) => {
            let bytes = std::fs::metadata(&args.output).map(|m| m.len()).unwrap_or(0);
            // Written either way: a reader that went away changes nothing.
            common::say::out(format_args!(
                "{}: {stage} model, {:.3} MB",
                args.output.display(),
                bytes as f64 / 1e6
            ));
            ExitCode::SUCCESS
        }
        Err(err) => {
            common::say!("export-model: {}", common::say::chain(&err));
            ExitCode::FAILURE
        }
    }
}
