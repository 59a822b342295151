//! `train-refine`: trains the refinement model E_r, guided by a trained coarse model.
//!
//! `train-refine --config configs/refine.toml --init DIR/coarse.ckpt [--weights E_R.ckpt] [--out DIR] [--backend …] [--steps N] [--resume]`

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;
use train::cli::{CommonArgs, finish, train_refine};

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
    finish(train_refine(&args.common, args.init, args.weights))
}
