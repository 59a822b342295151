//! Training SuperSVG's two stages, shared by the `train-coarse` and `train-refine` programs:
//! configuration files, the data stream, the objectives and the resumable training loop.

pub mod cli;
pub mod config;
pub mod data;
pub mod inference;
pub mod objective;
pub mod optimizer;
mod preview;
mod report;
mod schedule;
pub mod teacher;
pub mod trainer;
pub mod validation;
