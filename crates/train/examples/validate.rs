//! Scores checkpoints on a config's validation set, so runs trained with different `[data]` or
//! models are compared on the same images.
//!
//! `cargo run --release -p train --example validate -- --config configs/coarse.toml CKPT...`
//! prints one JSON line per checkpoint: its path and its scores. A coarse checkpoint is scored
//! on the validation crops (`psnr_flat`, `psnr_drawn`, `psnr_kept`, `spill`, `visible`, `kept`)
//! and at inference (`at_inference`: each image drawn by B without E_r with
//! `validation.coarse_share` for E_c, `psnr_b`, E_c's paths `bought`, and `psnr_regions`, the
//! fallback alone at the same budget); a refinement checkpoint (with a refine config such as `configs/refine.toml`) the way
//! inference uses it, on the images' fallback drawings with `validation.refine_share` of the
//! paths (`proposed`, `kept`, `gain_db`, `regions_db`: what the same paths add as regions, and
//! `optimizer_db`: what the exact optimizer's paths add in E_r's place). A mover's file (with
//! `configs/mover.toml`) is scored as inference runs it, on `[validation]`'s images drawn by B
//! at each of `data.paths`: `at_inference`, a budget each (`paths`, `gain_db`: the mean PSNR gain
//! over B, a rejected move counting 0, `kept` of `images`).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::Parser;
use model::{Checkpoint, CheckpointError, CropBatch, MoverCheckpoint, Stage, load_coarse, load_refine};
use train::config::{self, CoarseConfig, RefineConfig};
use train::{CoarseCheck, RefineCheck};
use train::{CoarseObjective, Objective};
use train::{MoverCheck, MoverConfig, Validation};

/// Score checkpoints on the validation set of a config.
#[derive(Parser, Debug)]
struct Args {
    /// The TOML config whose [validation] (and, for E_c, [loss]) to use: a coarse config for
    /// coarse checkpoints, a refine config for refinement ones, a mover config for movers.
    #[arg(long)]
    config: PathBuf,
    /// Checkpoints, all of one kind.
    #[arg(required = true)]
    checkpoints: Vec<PathBuf>,
}

fn main() -> ExitCode {
    match validate(&Args::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            common::say!("error: {}", common::say::chain(err.as_ref()));
            ExitCode::FAILURE
        }
    }
}

/// What a checkpoint file holds, for scoring it the way its kind is used.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    Mover,
    Network(Stage),
}

impl Kind {
    /// The kind of the checkpoint at `path`, read and verified.
    fn of(path: &Path) -> Result<Self, CheckpointError> {
        match MoverCheckpoint::load(path) {
            Ok(_) => Ok(Kind::Mover),
            Err(CheckpointError::WrongStage { .. }) => Ok(Kind::Network(Checkpoint::load(path)?.stage)),
            Err(err) => Err(err),
        }
    }

    fn name(self) -> &'static str {
        match self {
            Kind::Mover => "a mover's file",
            Kind::Network(stage) => match stage {
                Stage::Coarse => "a coarse checkpoint",
                Stage::Refine => "a refinement checkpoint",
            },
        }
    }
}

fn validate(args: &Args) -> Result<(), Box<dyn std::error::Error>> {
    let device = burn::tensor::Device::flex();
    let first = Kind::of(&args.checkpoints[0])?;
    for path in &args.checkpoints[1..] {
        let kind = Kind::of(path)?;
        if kind != first {
            return Err(format!(
                "{} is {} and {} {}: give checkpoints of one kind",
                args.checkpoints[0].display(),
                first.name(),
                path.display(),
                kind.name()
            )
            .into());
        }
    }
    let stage = match first {
        Kind::Mover => return validate_movers(args, &device),
        Kind::Network(stage) => stage,
    };
    match stage {
        Stage::Coarse => {
            let config: CoarseConfig = config::load(&args.config)?;
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
                let check = CoarseCheck::build(&config.validation, config.data.compactness, &model_config)?
                    .ok_or("the config has no [validation] images")?;
                let mut line = serde_json::to_value(scores)?;
                line["at_inference"] = serde_json::to_value(check.score(&model, &device))?;
                print(path, line);
            }
        }
        Stage::Refine => {
            let config: RefineConfig = config::load(&args.config)?;
            for path in &args.checkpoints {
                let (model, model_config) = load_refine(path, &device)?;
                let check = RefineCheck::build(&config.validation, config.data.compactness, &model_config)?
                    .ok_or("the config has no [validation] images")?;
                print(path, serde_json::to_value(check.score(&model, &device))?);
            }
        }
    }
    Ok(())
}

/// Scores mover checkpoints on the mover config's `[validation]` images.
fn validate_movers(args: &Args, device: &burn::tensor::Device) -> Result<(), Box<dyn std::error::Error>> {
    let config = MoverConfig::load(&args.config)?;
    let validation = config.validation.as_ref().ok_or("the config has no [validation] images")?;
    let check = MoverCheck::build(&validation.images, &config.data, device)?;
    for path in &args.checkpoints {
        let mover = MoverCheckpoint::load(path)?.build(device, path)?;
        print(path, serde_json::json!({ "at_inference": check.score(&mover, device) }));
    }
    Ok(())
}

/// One line on stdout: the scores with the checkpoint's path.
fn print(path: &Path, mut line: serde_json::Value) {
    line["checkpoint"] = path.display().to_string().into();
    common::say::out(format_args!("{line}"));
}
