//! Rendering for supersvg: the path layout every crate shares, the differentiable soft
//! rasterizer used for training, the exact tiny-skia renderer used for pictures and metrics, SVG
//! export, the paints shapes are filled with ([`Fill`]: a colour or a [`Ramp`]), and the choice of
//! compute backend.

mod adam;
mod decimals;
pub mod device;
mod exact;
mod exact_batch;
mod fill;
mod fit;
mod geometry;
mod gradient;
mod path;
mod shape;
mod shapes;
mod soft;
mod svg;

pub use adam::{Adam, FlatAdam, PathAdam};
pub use common::Ramp;
pub use decimals::{Decimals, MAX_DECIMALS};
pub use device::{Backend, BackendError};
pub use exact::{coverage_exact, coverage_exact_window, paint_exact, render_exact, skia_outline};
pub use exact_batch::ExactBatch;
pub use fill::{Fill, RAMP_COORDS, RAMP_PARAMS, ramp_from_params, ramp_params};
pub use fit::{fit_curve, fit_outline};
pub use geometry::{bernstein, cubic_point};
pub use gradient::{ShapeGradient, Window};
pub use path::{COORDS, PARAMS, PARAMS_OPAQUE, POINTS, Path, PathBatch, SEGMENTS, VISIBLE_ALPHA};
pub use shape::{Contour, Filled, Outline, Segment, Shape};
pub use shapes::{random_blob, random_scene};
pub use soft::{
    SoftRasterOptions, coverage_soft, paint_soft, paint_soft_with_union, render_soft, render_soft_with_union,
};
pub use svg::{SvgError, SvgOptions, to_svg, to_svg_with};
