//! Scores a coarse checkpoint on a config's validation crops, so runs trained with different
//! `[data]` or models are compared on the same crops.
//!
//! `cargo run --release -p train --example validate -- --config configs/coarse.toml CKPT...`
//! prints one JSON line per checkpoint: its path and the validation scores (`psnr_flat`,
//! `psnr_drawn`, `psnr_kept`, `spill`, `visible`, `kept`).

use std::path::PathBuf;

use clap::Parser;
use model::{CropBatch, load_coarse};
use train::config::{self, CoarseConfig};
use train::objective::{CoarseObjective, Objective};
use train::validation::Validation;

/// Score coarse checkpoints on the validation set of a config.
#[derive(Parser, Debug)]
struct Args {
    /// The TOML config whose [validation] and [loss] to use.
    #[arg(long)]
    config: PathBuf,
    /// Coarse checkpoints.
    #[arg(required = true)]
    checkpoints: Vec<PathBuf>,
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = Args::parse();
    let config: CoarseConfig = config::load(&args.config)?;
    let device = burn::tensor::Device::flex();
    let objective = CoarseObjective::new(&config);
    for path in &args.checkpoints {
        let (model, model_config) = load_coarse(path, &device)?;
        let set = Validation::build(
            &config.validation,
            &config.data,
            &model_config,
            config.loss.boundary.dilation,
        )?
        .ok_or("the config has no [validation] images")?;
        let crops = CropBatch::new(set.crops(), &device);
        let scores = set.score(&objective.draw(&model, &crops).to_scenes());
        let mut line = serde_json::to_value(scores)?;
        line["checkpoint"] = path.display().to_string().into();
        println!("{line}");
    }
    Ok(())
}
