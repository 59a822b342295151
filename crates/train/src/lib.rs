//! Training SuperSVG's networks, shared by the `train-coarse` and `train-refine` programs:
//! configuration files ([`config`]), the data stream ([`DataSource`], [`Loader`]), the
//! objectives ([`CoarseObjective`], [`RefineObjective`]), the resumable training loop
//! ([`train`]) and the scores of a model on held-out images ([`Validation`], [`CoarseCheck`],
//! [`RefineCheck`]); the mover's teacher and regression ([`train_mover`], `train-mover`). The
//! programs are [`cli`]'s flags and one call each.

pub mod cli;
pub mod config;
mod data;
mod inference;
mod learned;
mod mover;
mod objective;
mod optimizer;
mod preview;
mod report;
mod schedule;
mod stop;
mod teacher;
mod trainer;
mod validation;

pub use data::{
    Batch, DataError, DataSource, DrawnBox, DrawnBoxes, ImageSet, Loader, Samples, synthetic_scene,
};
pub use inference::{AtInference, CoarseCheck, CoarseScores, RefineCheck, RefineScores};
pub use learned::{
    Case, Drawings, OptimizerConfig, OptimizerError, OptimizerScore, OptimizerState, OptimizerSummary,
    OptimizerTraining, Rollout, Scoring, optimizer_checkpoint, rollout, train_optimizer,
};
pub use mover::{
    Begin, MoverCheck, MoverConfig, MoverData, MoverError, MoverScore, MoverState, MoverSummary,
    MoverTraining, MoverValidation, Room, Sample, Teacher, mover_checkpoint, teach, train_mover,
};
pub use objective::{CoarseObjective, Objective, RefineObjective, StepOutput};
pub use optimizer::adamw;
pub use stop::{catch_interrupts, interrupted};
pub use trainer::{
    ResumeProblem, Run, Start, Summary, TrainError, TrainingState, checkpoint_path, model_from, resume_from,
    train,
};
pub use validation::{Scores, Validation};
