//! SuperSVG inference: an image to SVG in one call ([`run`]) — superpixels, the coarse network
//! E_c and the refinement network E_r as stages over one [`scene::Scene`] (SuperSVG-B), then,
//! if asked, every path fine-tuned against the image (SuperSVG-F).
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

pub mod coarse;
pub mod fallback;
pub mod finetune;
pub mod models;
pub mod paper;
pub mod pipeline;
pub mod refine;
pub mod scene;
pub mod segmentation;

pub use models::Models;
pub use pipeline::{
    BudgetParseError, BudgetSplit, Job, MAX_PATHS, Outcome, PathBudget, Report, Seconds, VectorizeError,
    Warning, run, run_with_progress,
};
pub use segmentation::AutoBudget;
