//! Superpixels for SuperSVG: SLIC segmentation (Achanta et al. 2012), per-region crops resized to
//! the model's input, and the map from a crop's unit square back to the image.
//!
//! Pure Rust on CPU buffers, parallel with rayon; shared by training (random region crops) and
//! inference (every region of an image).

mod color;
mod connectivity;
mod crop;
mod merge;
mod outline;
mod planar;
mod slic;

pub use crop::{CropOptions, CropTransform, RegionCrop, resample_area};
pub use merge::{Hierarchy, RegionFill, SegmentOptions, WARD_OVERSEGMENT, segment};
pub use planar::{Chain, Directed, PlanarMap};
pub use slic::{Region, Segmentation, SlicError, SlicOptions, slic, worst_first};
