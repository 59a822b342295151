//! SuperSVG inference: images to SVG with the trained networks (SuperSVG-B) as stages over one
//! [`scene::Scene`] (segment → coarse → refine), optional fine-tuning of every path against the
//! image (SuperSVG-F), and quality measures.

pub mod coarse;
pub mod decode;
pub mod fallback;
pub mod finetune;
pub mod metrics;
pub mod models;
pub mod pipeline;
pub mod refine;
pub mod scene;
pub mod write;
