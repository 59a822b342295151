//! The two networks of SuperSVG as burn modules, sized by [`ModelConfig`]:
//!
//! - [`CoarseModel`] (E_c): a superpixel crop to n paths with visibility;
//! - [`RefineModel`] (E_r): the crop and the current canvas to m more paths;
//!
//! their [`Checkpoint`] files, and the input contract both are fed through ([`InputSpec`],
//! [`CropBatch`]). Both return a [`raster::PathBatch`] in the crop's unit square.

mod block;
mod checkpoint;
mod coarse;
mod config;
mod decoder;
mod input;
mod operating;
mod placement;
mod prior;
mod refine;
mod vit;

pub use checkpoint::{
    Checkpoint, CheckpointError, FormatProblem, MismatchProblem, Opened, Stage, load_coarse, load_refine,
};
pub use coarse::CoarseModel;
pub use config::{InputSpec, InvalidSetting, ModelConfig, Preset, RefineAnchor};
pub use decoder::PathDecoder;
pub use input::{CropBatch, MIN_REGION_PIXELS, canvas_cells, crop_to_image};
pub use operating::OperatingPoint;
pub use placement::PathOptimizer;
pub use prior::{ANCHOR_SIDE, error_squares};
pub use refine::RefineModel;
pub use vit::VitEncoder;
