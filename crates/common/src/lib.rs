//! The primitives every supersvg crate shares, each defined once: rectangles that cannot be
//! inverted ([`Rect`]: pixel boxes and unit-square bounds), the area of a polygon, linear colour ramps and the pixel statistics that fit them ([`Ramp`], [`Moments`]), reading an image at the working
//! resolution from a file, bytes or pixels ([`decode`]), opening an input without blocking on a
//! pipe ([`readable`]), stable fingerprints of bytes ([`fingerprint`]), listing a folder of inputs ([`folder`]), quality measures ([`metrics`]:
//! MSE, PSNR, SSIM, GMSD), writing files so that no partial or hijacked file is ever left ([`write`])
//! and never over an input ([`outputs`]), messages that never panic ([`say`]), line charts as
//! SVG ([`chart`]), the command-line programs' progress bar ([`progress`], behind the `progress`
//! feature) and their tests' helpers ([`testing`], behind the `testing` feature).

pub mod chart;
pub mod decode;
pub mod fingerprint;
pub mod folder;
pub mod metrics;
pub mod outputs;
mod polygon;
#[cfg(feature = "progress")]
pub mod progress;
mod ramp;
pub mod readable;
mod rect;
pub mod say;
#[cfg(feature = "testing")]
pub mod testing;
pub mod write;

pub use decode::{Cancel, DecodeError, DecodeProblem, LoadOptions, Loaded, PixelLayout, WORKING_SIZES};
pub use metrics::{gmsd, mse, psnr, psnr_of_mse, ssim};
pub use polygon::signed_area;
pub use ramp::{LinearFit, Moments, Ramp};
pub use rect::{Bounds, PixelBox, Rect};
