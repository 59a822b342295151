//! supersvg: image vectorization (raster → SVG) with the SuperSVG method, in pure Rust on burn.
//!
//! This crate gathers the workspace's crates under one name and hosts the cross-crate tests in
//! `tests/`. Each stage has its own crate:
//!
//! - [`common`]: pixel boxes, image decoding, quality measures, atomic writes, progress bars;
//! - [`raster`]: the path layout, the differentiable soft rasterizer, the exact renderer, SVG;
//! - [`dpw`]: the training objectives (normalized L2, boundary, path efficiency, DPW);
//! - [`superpixel`]: SLIC, region crops and paste-back;
//! - [`model`]: the coarse and refinement networks, the mover, and their checkpoints;
//! - [`train`]: `train-coarse`, `train-refine` and `train-mover`;
//! - [`infer`]: `infer` and the one call behind it ([`infer::run`]): the inference stages over
//!   one scene, fine-tuning, the report.

pub use {common, dpw, infer, model, raster, superpixel, train};
