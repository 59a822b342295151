//! Evaluating SuperSVG against other vectorizers: the peers (vtracer and potrace as
//! subprocesses, the pixel-exact superpixel mosaic), LPIPS, and rendering any SVG with resvg so
//! every method is scored by the same renderer, and rate–distortion curves ([`rate`]). Kept out of the `infer` library users link.

pub mod cli;
pub mod lpips;
pub mod peers;
pub mod rate;
pub mod spill;
