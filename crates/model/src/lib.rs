//! The networks of SuperSVG as burn modules, E_c and E_r sized by [`ModelConfig`]:
//!
//! - [`CoarseModel`] (E_c): a superpixel crop to n paths with visibility;
//! - [`RefineModel`] (E_r): the crop and the current canvas to m more paths;
//! - [`Mover`] (E_m): every drawn outline's points moved to where the image has its edges;
//! - [`LearnedOptimizer`] (E_o): SuperSVG-F's first steps, every point moved from what the mover
//!   reads and what an optimizer reads;
//!
//! their [`Checkpoint`] and [`SmallCheckpoint`] files, and the input contract E_c and E_r are fed
//! through ([`InputSpec`], [`CropBatch`]; both return a [`raster::PathBatch`] in the crop's unit
//! square) and the mover's ([`frames`], [`profile`]).

mod block;
mod checkpoint;
mod coarse;
mod config;
mod decoder;
mod input;
mod learned;
mod mover;
mod operating;
mod placement;
mod prior;
mod refine;
mod vit;

pub use checkpoint::{
    Checkpoint, CheckpointError, FormatProblem, MOVER_STAGE, MismatchProblem, MoverCheckpoint, Opened,
    OptimizerCheckpoint, SmallCheckpoint, SmallNetwork, Stage, load_coarse, load_refine,
};
pub use coarse::CoarseModel;
pub use config::{InputSpec, InvalidSetting, ModelConfig, Preset, RefineAnchor};
pub use decoder::PathDecoder;
pub use input::{CropBatch, MIN_REGION_PIXELS, canvas_cells, crop_to_image};
pub use learned::{LearnedOptimizer, MAX_STEP, OPTIMIZER_STAGE, STATE_LEN, STEP_FEATURES, STEP_HIDDEN};
pub use mover::{
    Frame, MAX_MOVE, MOVER_HIDDEN, Mover, PROFILE_LEN, PROFILE_OFFSETS, frames, neighbours, profile,
};
pub use operating::OperatingPoint;
pub use placement::PathOptimizer;
pub use prior::{ANCHOR_SIDE, error_squares};
pub use refine::RefineModel;
pub use vit::VitEncoder;
