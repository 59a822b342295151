//! The training objectives of SuperSVG as burn tensor ops, differentiable on every backend.
//!
//! - [`masked_l2`] / [`multiscale_masked_l2`]: reconstruction error inside a superpixel mask.
//! - [`boundary_loss`]: area of the paths outside the (dilated) mask.
//! - [`visibility`] and [`path_efficiency_loss`]: the straight-through visibility β and the number
//!   of visible paths.
//! - [`dpw`]: Dynamic Path Warping, the alignment loss between predicted and pseudo-ground-truth
//!   path sequences, and [`soft_dtw`] for comparison.

mod boundary;
mod efficiency;
mod reconstruction;
mod scan;
mod warping;

pub use boundary::{BOUNDARY_DILATION, BoundaryOptions, boundary_loss, boundary_loss_of_union, dilate};
pub use efficiency::{path_efficiency_loss, visibility};
pub use reconstruction::{masked_l2, multiscale_masked_l2};
pub use warping::{PathDistance, dpw, pairwise_sq_distance, soft_dtw};
