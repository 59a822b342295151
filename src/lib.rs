//! supersvg: image vectorization (raster → SVG) with the SuperSVG method, in pure Rust on burn.
//!
//! This crate gathers the workspace's crates under one name and hosts the cross-crate tests in
//! `tests/`.
//!
//! - [`raster`]: the path layout, the differentiable soft rasterizer, the exact renderer, SVG.

pub use raster;
