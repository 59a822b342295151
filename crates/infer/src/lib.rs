//! SuperSVG inference: images to SVG with the trained networks (SuperSVG-B), optional
//! fine-tuning of every path against the image (SuperSVG-F), quality measures, and the
//! evaluation against other vectorizers.

pub mod decode;
pub mod finetune;
pub mod lpips;
pub mod metrics;
pub mod models;
pub mod peers;
pub mod pipeline;
pub mod write;
