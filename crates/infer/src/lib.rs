//! SuperSVG inference: an image to SVG in one call ([`run`]) — superpixels, the coarse network
//! E_c and the refinement network E_r as stages over one [`Scene`] (SuperSVG-B), the mover E_m
//! moving what they drew where the job says ([`Moves`]), then, if asked, every path fine-tuned
//! against the image (SuperSVG-F).
//!
//! ```no_run
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let device = burn::tensor::Device::flex();
//! let models = infer::Models::bundled(true, &device)?;
//! let image = common::decode::load(std::path::Path::new("photo.jpg"), 512)?;
//! let outcome = infer::run(&models, &image, &infer::Job::default(), &device)?;
//! std::fs::write("photo.svg", &outcome.svg)?;
//! println!("{} paths, {:.2} dB", outcome.report.paths, outcome.report.psnr);
//! # Ok(())
//! # }
//! ```
//!
//! A [`Job`] says what to draw and is checked in one place ([`Job::validate`]); its budget is
//! planned once per image ([`budget`]); the stages one at a time are in [`stages`], for
//! training and tests.

pub mod budget;
#[cfg(feature = "cli")]
pub mod cli;
mod coarse;
mod fallback;
mod fills;
mod finetune;
mod job;
pub mod learned;
mod models;
mod mover;
pub mod paper;
mod pipeline;
mod recolour;
mod refine;
mod scene;
mod segmentation;

pub use finetune::{FinetuneOptions, Learned, Limit, Progress, finetune, finetune_with_progress};
pub use job::{
    AutoRule, BudgetParseError, Fills, FillsParseError, InvalidJob, Job, MAX_FINETUNE_SECS,
    MAX_FINETUNE_STEPS, MAX_OPTIMIZER_STEPS, MAX_PATHS, MAX_TOLERANCE, MIN_PATHS, Moves, MovesParseError,
    OPTIMIZER_STEPS, PathBudget, Refiner, RefinerParseError, Split, SplitParseError, VectorizeError, Warning,
};
pub use models::{
    BUILT_IN_COARSE, BUILT_IN_MOVER, BUILT_IN_REFINE, BuiltIn, Context, Identity, MODELS_ENV, ModelSource,
    Models, ModelsError, MoverNetwork, Network, OptimizerNetwork, SmallModel, bundled,
};
pub use mover::MoveTally;
pub use pipeline::{Outcome, Report, Seconds, run, run_with_progress};
pub use refine::RefineTally;
pub use scene::{Origin, Placed, Scene, StageCounts};

/// The stages of SuperSVG-B one at a time, for those who train the networks the way inference
/// uses them and for tests: segmenting, the fallback drawing, the coarse and refinement stages,
/// the mover's.
pub mod stages {
    pub use crate::coarse::draw_coarse;
    pub use crate::fallback::{FallbackDrawing, Style, fitted_path};
    pub use crate::fills::{RAMP_BYTES, REGION_BYTES, Ramps};
    pub use crate::mover::{MOVE_GRID, SIMPLIFY_PIXELS, move_outlines};
    pub use crate::refine::{Proposer, draw_refinement};
    pub use crate::scene::Scope;
    pub use crate::segmentation::{PIXELS_PER_REGION, Segmented, hierarchy, max_regions};
}
