//! `train-coarse`: trains the coarse model E_c.
//!
//! `train-coarse --config configs/coarse.toml [--out DIR] [--backend flex|ndarray|wgpu] [--steps N] [--resume]
//! [--init CKPT]`

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;
use train::cli::{CommonArgs, finish, train_coarse};

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
    finish(train_coarse(&args.common, args.init))
}
