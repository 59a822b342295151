//! Training the learned optimizer (E_o, [`model::LearnedOptimizer`]): `train-optimizer`.
//!
//! As learned optimizers are trained: unrolled through its steps (truncated back-propagation:
//! rollouts of a few steps, their length growing as training goes), the loss the error of the
//! drawing after each step, relative to the drawing's error before the first. The drawings are
//! SuperSVG-B's of training images, as F starts from them. The meta-gradient is first order:
//! what a step reads (the drawing's profiles and gradient) is taken as given, and a move made at
//! one step counts in every later step's error through the gradient there (the point stays
//! moved), so one exact gradient a step is all a rollout needs beside E_o's own backward pass.
//! Validation is what users get: F (E_o's steps, then Adam) for a fixed time on held-out
//! images against F with Adam alone for as long.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use burn::grad_clipping::GradientClippingConfig;
use burn::module::Module;
use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer};
use burn::tensor::{Device, Tensor, TensorData};
use common::decode::load;
use common::outputs::{OutputError, check_not_input, create_folder, lock_folder};
use common::say;
use image::Rgb32FImage;
use infer::learned::{LearnedSteps, along_normals};
use infer::{FinetuneOptions, Job, Learned, Limit, Models, Origin, PathBudget, Scene, finetune, run};
use model::{Frame, LearnedOptimizer, MoverCheckpoint, OptimizerCheckpoint, STEP_FEATURES};
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use raster::{Outline, Window};
use serde::{Deserialize, Serialize};

use crate::mover::Begin;
use crate::stop::{catch_interrupts, heard, interrupted};

/// `train-optimizer`'s configuration (`configs/optimizer.toml`); unknown keys are refused.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OptimizerConfig {
    /// The drawings E_o learns to improve.
    pub data: Drawings,
    /// The rollouts.
    pub rollout: Rollout,
    /// The meta-optimization.
    pub train: OptimizerTraining,
    /// Held-out drawings E_o is scored on as F runs it.
    pub validation: Drawings,
    /// How F is scored on `validation`.
    pub scoring: Scoring,
}

/// Images drawn by SuperSVG-B (the bundled models, defaults) at each budget and working size.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Drawings {
    /// Image files, relative to the working folder.
    pub images: Vec<PathBuf>,
    /// Budgets, as `--paths` takes them (`500`, `auto`).
    pub paths: Vec<String>,
    /// Long side of the working image.
    pub size: u32,
}

/// The rollouts: their length grows from one step to `steps`, one more every `grow` updates.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Rollout {
    /// E_o's steps in F, and the longest rollout.
    pub steps: usize,
    /// Updates between one rollout length and the next.
    pub grow: usize,
}

/// The meta-optimization: Adam on E_o's weights.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OptimizerTraining {
    /// Updates (one rollout each).
    pub updates: usize,
    /// Adam's learning rate.
    pub learning_rate: f64,
    /// Seeds the order of the drawings and the initial weights.
    pub seed: u64,
    /// The profile layers start as the bundled mover's.
    pub from_mover: bool,
    /// Updates between checkpoints and scores.
    pub every: usize,
}

/// How a run is scored: F for `seconds` on each validation drawing, with E_o and without.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scoring {
    /// F's time on each drawing.
    pub seconds: f64,
}

/// The longest rollout.
pub const MAX_ROLLOUT: usize = 64;
/// The most updates of a run.
pub const MAX_UPDATES: usize = 10_000_000;

/// Why E_o could not be trained; each names the file or setting.
#[derive(Debug, thiserror::Error)]
pub enum OptimizerError {
    /// The configuration is unreadable or holds an unknown key or a bad value.
    #[error("{path}: {problem}")]
    Config {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        problem: String,
    },
    /// An image could not be read or drawn.
    #[error("{path}: {problem}")]
    Image {
        /// The image.
        path: PathBuf,
        /// What went wrong.
        problem: String,
    },
    /// A checkpoint could not be written or read back.
    #[error(transparent)]
    Checkpoint(#[from] model::CheckpointError),
    /// The optimizer's or the trainer's state could not be stored or restored.
    #[error("{path}: {problem}")]
    State {
        /// The checkpoint.
        path: PathBuf,
        /// What went wrong.
        problem: String,
    },
    /// The output folder cannot be used.
    #[error(transparent)]
    Output(#[from] OutputError),
    /// A finished or stopped run's folder, not resumed or overwritten.
    #[error("{0} exists: pass --resume to continue it or --overwrite to start afresh")]
    Exists(PathBuf),
    /// The meta-loss became NaN or infinite.
    #[error("the loss became {value} at update {update}; stopped, the last checkpoint kept")]
    NonFinite {
        /// The loss.
        value: f64,
        /// The update (1-based).
        update: usize,
    },
    /// Stopped (Ctrl-C, SIGTERM) before the first update: nothing to save.
    #[error("interrupted before training began; run the same command again")]
    InterruptedBefore,
    /// Stopped (Ctrl-C, SIGTERM); the checkpoint holds what was done.
    #[error("interrupted after update {update}; --resume continues from {}", .checkpoint.display())]
    Interrupted {
        /// Updates done.
        update: usize,
        /// The checkpoint written.
        checkpoint: PathBuf,
    },
}

impl OptimizerConfig {
    /// The configuration in `path`, checked.
    pub fn load(path: &Path) -> Result<Self, OptimizerError> {
        let problem = |problem: String| OptimizerError::Config { path: path.to_path_buf(), problem };
        let text = std::fs::read_to_string(path).map_err(|e| problem(e.to_string()))?;
        let config: Self = toml::from_str(&text).map_err(|e| problem(e.to_string()))?;
        config.check().map_err(problem)?;
        Ok(config)
    }

    fn check(&self) -> Result<(), String> {
        for (key, drawings) in [("data", &self.data), ("validation", &self.validation)] {
            if drawings.images.is_empty() || drawings.paths.is_empty() {
                return Err(format!("{key}: images and paths must not be empty"));
            }
            if let Some(bad) = drawings.paths.iter().find(|p| p.parse::<PathBudget>().is_err()) {
                return Err(format!("{key}.paths: {bad:?} is no budget"));
            }
            if !common::WORKING_SIZES.contains(&drawings.size) {
                return Err(format!("{key}.size: 16 to 8192"));
            }
        }
        let checks = [
            (!(1..=MAX_ROLLOUT).contains(&self.rollout.steps), format!("rollout.steps: 1 to {MAX_ROLLOUT}")),
            (self.rollout.grow == 0, "rollout.grow: at least 1".into()),
            (!(1..=MAX_UPDATES).contains(&self.train.updates), format!("train.updates: 1 to {MAX_UPDATES}")),
            (
                !(self.train.learning_rate > 0.0 && self.train.learning_rate <= 1.0),
                "train.learning_rate: above 0, at most 1".into(),
            ),
            (self.train.every == 0, "train.every: at least 1".into()),
            (
                !(self.scoring.seconds > 0.0 && self.scoring.seconds <= 60.0),
                "scoring.seconds: above 0, at most 60".into(),
            ),
        ];
        match checks.into_iter().find(|(bad, _)| *bad) {
            Some((_, what)) => Err(what),
            None => Ok(()),
        }
    }
}

/// What a checkpoint stores for resuming: where the run is and how it scored.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct OptimizerState {
    /// Updates done.
    pub update: usize,
    /// Seconds of training so far (drawing the data not counted).
    pub seconds: f64,
    /// The mean meta-loss of the updates since the last score, one a score.
    pub losses: Vec<f64>,
    /// Each score after so many updates.
    pub scores: Vec<OptimizerScore>,
    /// The configuration, as run.
    pub config: OptimizerConfig,
}

/// F on the validation drawings with E_o's steps first and with Adam alone, each drawing run
/// both ways one after the other: F stops by the clock, so the two share whatever else the
/// machine was doing.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct OptimizerScore {
    /// Updates done.
    pub update: usize,
    /// Mean PSNR (dB) of F with E_o.
    pub with: f64,
    /// Mean PSNR (dB) of F with Adam alone.
    pub without: f64,
}

/// One drawing to learn on or score with: B's drawing of an image, its outlines as F moves them,
/// which move (all but the background), and the window that scores them.
pub struct Case {
    /// The image.
    pub name: String,
    /// B's drawing.
    pub scene: Scene,
    /// Its shapes as outlines, as drawn.
    pub outlines: Vec<Outline>,
    /// Whether each moves.
    pub movable: Vec<bool>,
    /// The image over a white canvas.
    pub window: Window,
}

impl Case {
    /// The drawing of `image` by `models` at `paths` (as `--paths` takes it) at `size`.
    fn draw(
        models: &Models,
        image: &Path,
        paths: &str,
        size: u32,
        device: &Device,
    ) -> Result<Self, OptimizerError> {
        let failed = |problem: String| OptimizerError::Image { path: image.to_path_buf(), problem };
        let loaded = load(image, size).map_err(|e| failed(e.to_string()))?;
        let budget = paths.parse::<PathBudget>().map_err(|e| failed(e.to_string()))?;
        let drawn = run(models, &loaded, &Job { paths: budget, ..Job::default() }, device)
            .map_err(|e| failed(e.to_string()))?;
        let scene = drawn.scene;
        let outlines: Vec<Outline> =
            scene.scene().iter().map(|shape| shape.to_outline().expect("a drawn shape is finite")).collect();
        let movable = scene.paths().iter().map(|placed| placed.origin != Origin::Background).collect();
        let window = white_window(scene.target()).expect("a drawn image is not empty");
        let name = format!("{} at {paths}", image.display());
        Ok(Self { name, scene, outlines, movable, window })
    }

    /// Every image of `drawings` at each of its budgets.
    pub fn all_of(
        drawings: &Drawings,
        models: &Models,
        device: &Device,
    ) -> Result<Vec<Self>, OptimizerError> {
        Self::all(drawings, models, device)
    }

    fn all(drawings: &Drawings, models: &Models, device: &Device) -> Result<Vec<Self>, OptimizerError> {
        let mut cases = Vec::new();
        for image in &drawings.images {
            for paths in &drawings.paths {
                if interrupted() {
                    return Err(OptimizerError::InterruptedBefore);
                }
                cases.push(Self::draw(models, image, paths, drawings.size, device)?);
            }
        }
        Ok(cases)
    }
}

/// The window of `image` over white: what F scores a drawing against.
fn white_window(image: &Rgb32FImage) -> Option<Window> {
    let (width, height) = image.dimensions();
    let target: Vec<f32> = (0..3).flat_map(|c| image.pixels().map(move |p| p.0[c])).collect();
    Window::new(width, height, vec![1.0; target.len()], target)
}

/// One rollout of `steps` of `network`'s steps from `case`'s drawing: the log of the error after
/// each step over the error before the first (their mean is the meta-loss), and the gradient of
/// the first-order meta-loss by the network's weights.
pub fn rollout(
    network: &LearnedOptimizer,
    case: &Case,
    steps: usize,
    device: &Device,
) -> (Vec<f64>, GradientsParams) {
    let target = case.scene.target();
    let size = target.dimensions();
    let mut runner = LearnedSteps::new(case.movable.clone(), steps);
    let mut outlines = case.outlines.clone();
    // Each step's moves (in the graph) and the frames they moved along.
    let mut moves: Vec<(Tensor<1>, Vec<Frame>)> = Vec::with_capacity(steps);
    // Each state after the first: its error and its gradient by every point (per pixel).
    let mut states: Vec<(f64, Vec<[f32; 2]>)> = Vec::with_capacity(steps);
    let mut first = f64::NAN;
    for k in 0..steps {
        let input = runner.features(&outlines, &case.window, target);
        if k == 0 {
            first = input.loss;
        } else {
            states.push((input.loss, input.gradient.clone()));
        }
        let rows = input.features.len() / STEP_FEATURES;
        let features =
            Tensor::from_data(TensorData::new(input.features.clone(), [rows, STEP_FEATURES]), device);
        let moved = network.forward(features);
        let values: Vec<f32> = moved.clone().inner().into_data().try_into_vec().expect("f32 moves");
        outlines = runner.apply(&outlines, &input, &values, target);
        moves.push((moved, input.frames.into_iter().flatten().collect()));
    }
    let (loss, _, last) = runner.gradient(&outlines, &case.window, size);
    states.push((loss, last));
    // The meta-loss is the mean over the steps of the log of the error after the step over the
    // error before the first: a step that ruins a drawing weighs no more than one that halves
    // its error. A move made at step j stays in every later state: its coefficient is the sum
    // of their gradients along the normal it moved along, each over its state's error.
    let mut surrogate: Option<Tensor<1>> = None;
    for (j, (moved, frames)) in moves.into_iter().enumerate() {
        let mut coefficients = vec![0.0f32; frames.len()];
        for (error, gradient) in &states[j..] {
            let scale = 1.0 / (error * steps as f64);
            for (c, g) in coefficients.iter_mut().zip(along_normals(std::slice::from_ref(&frames), gradient))
            {
                *c += (f64::from(g) * scale) as f32;
            }
        }
        let count = coefficients.len();
        let term = (moved * Tensor::from_data(TensorData::new(coefficients, [count]), device)).sum();
        surrogate = Some(match surrogate {
            None => term,
            Some(sum) => sum + term,
        });
    }
    let surrogate = surrogate.expect("at least one step");
    let logs = states.iter().map(|(error, _)| (error / first).ln()).collect();
    (logs, GradientsParams::from_grads(surrogate.backward(), network))
}

/// Where a run keeps its checkpoint.
pub fn optimizer_checkpoint(dir: &Path) -> PathBuf {
    dir.join("optimizer.ckpt")
}

/// What a finished run reports.
#[derive(Clone, Debug)]
pub struct OptimizerSummary {
    /// Its state at the end.
    pub state: OptimizerState,
    /// The checkpoint.
    pub checkpoint: PathBuf,
}

/// F for `seconds` on every validation drawing, with `network`'s `steps` first and with Adam
/// alone, paired drawing by drawing; `None` when interrupted.
fn score(
    cases: &[Case],
    (network, steps): (&LearnedOptimizer, usize),
    (update, seconds): (usize, f64),
    device: &Device,
) -> Option<OptimizerScore> {
    let learned = Learned { network: Arc::new(network.clone()), steps, device: device.clone() };
    let (mut with, mut without) = (0.0, 0.0);
    for case in cases {
        for (learned, sum) in [(Some(learned.clone()), &mut with), (None, &mut without)] {
            if interrupted() {
                return None;
            }
            let options =
                FinetuneOptions { limit: Limit::Seconds(seconds), learned, ..FinetuneOptions::default() };
            let mut scene = case.scene.clone();
            finetune(&mut scene, &options);
            *sum += common::psnr(&scene.canvas_image(), case.scene.target());
        }
    }
    let n = cases.len().max(1) as f64;
    Some(OptimizerScore { update, with: with / n, without: without / n })
}

/// Trains E_o as `config` says in `dir` on `device` (an autodiff device).
pub fn train_optimizer(
    config: &OptimizerConfig,
    dir: &Path,
    begin: Begin,
    device: &Device,
) -> Result<OptimizerSummary, OptimizerError> {
    catch_interrupts();
    create_folder(dir)?;
    let _lock = lock_folder(dir)?;
    let checkpoint = optimizer_checkpoint(dir);
    let images: Vec<&PathBuf> = config.data.images.iter().chain(&config.validation.images).collect();
    check_not_input(&checkpoint, &images)?;
    if begin == Begin::Fresh && checkpoint.exists() {
        return Err(OptimizerError::Exists(checkpoint));
    }
    let state_error = |problem: String| OptimizerError::State { path: checkpoint.clone(), problem };
    let resumed = match begin {
        Begin::Resume => Some(OptimizerCheckpoint::load(&checkpoint)?),
        _ => None,
    };
    let inner = device.clone().inner();
    let models = Models::bundled(true, &inner).map_err(|e| state_error(e.to_string()))?;
    say!(
        "drawing {} training and {} validation images",
        config.data.images.len(),
        config.validation.images.len()
    );
    let cases = Case::all(&config.data, &models, &inner)?;
    let held = Case::all(&config.validation, &models, &inner)?;
    // Clipped: one rollout on a drawing E_o ruins must not throw the weights away.
    let clipping = || GradientClippingConfig::Norm(1.0).init();
    let mut optimizer: ModuleOptimizer =
        ModuleOptimizer::from(AdamConfig::new().init()).with_grad_clipping(clipping());
    let (mut network, mut state) = match resumed {
        Some(file) => {
            let network = file.build(device, &checkpoint)?;
            let bytes =
                file.optimizer.clone().ok_or_else(|| state_error("no optimizer state stored".into()))?;
            optimizer = optimizer.from_bytes(bytes).map_err(|e| state_error(e.to_string()))?;
            let state: OptimizerState = serde_json::from_str(file.training.as_deref().unwrap_or(""))
                .map_err(|e| state_error(format!("trainer state: {e}")))?;
            (network, OptimizerState { config: config.clone(), ..state })
        }
        None => {
            device.seed(config.train.seed);
            let network = match config.train.from_mover {
                true => {
                    let mover = MoverCheckpoint::from_bytes(
                        infer::BUILT_IN_MOVER.bytes,
                        Path::new("built-in mover.ckpt"),
                    )?
                    .build(device, Path::new("built-in mover.ckpt"))?;
                    LearnedOptimizer::from_mover(&mover, device)
                }
                false => LearnedOptimizer::new(device),
            }
            // It starts by moving nothing: the first rollouts measure the drawing as B left it.
            .silenced();
            let state = OptimizerState {
                update: 0,
                seconds: 0.0,
                losses: Vec::new(),
                scores: Vec::new(),
                config: config.clone(),
            };
            (network, state)
        }
    };
    let save = |network: &LearnedOptimizer,
                optimizer: &ModuleOptimizer,
                state: &OptimizerState|
     -> Result<(), OptimizerError> {
        let mut file = OptimizerCheckpoint::of_model(network);
        file.optimizer = Some(optimizer.into_bytes().map_err(|e| state_error(e.to_string()))?);
        file.training = Some(serde_json::to_string(state).expect("the state serializes"));
        Ok(file.save(&checkpoint)?)
    };
    let mut losses = Vec::new();
    while state.update < config.train.updates {
        let epoch = state.update / cases.len().max(1);
        let mut order: Vec<usize> = (0..cases.len()).collect();
        order.shuffle(&mut ChaCha8Rng::seed_from_u64(config.train.seed.wrapping_add(1 + epoch as u64)));
        let case = &cases[order[state.update % cases.len()]];
        if interrupted() {
            heard();
            save(&network, &optimizer, &state)?;
            return Err(OptimizerError::Interrupted { update: state.update, checkpoint });
        }
        let steps = (1 + state.update / config.rollout.grow).min(config.rollout.steps);
        let started = Instant::now();
        let (errors, grads) = rollout(&network, case, steps, device);
        let loss = errors.iter().sum::<f64>() / errors.len() as f64;
        if !loss.is_finite() {
            return Err(OptimizerError::NonFinite { value: loss, update: state.update + 1 });
        }
        network = optimizer.step(config.train.learning_rate, network, grads);
        state.update += 1;
        state.seconds += started.elapsed().as_secs_f64();
        losses.push(loss);
        if state.update % config.train.every == 0 || state.update == config.train.updates {
            let mean = losses.iter().sum::<f64>() / losses.len().max(1) as f64;
            state.losses.push(mean);
            losses.clear();
            let scored = (&network.valid(), config.rollout.steps);
            if let Some(score) = score(&held, scored, (state.update, config.scoring.seconds), &inner) {
                state.scores.push(score);
                say!(
                    "update {} ({steps} steps a rollout): mean log error ratio {mean:+.4}; F for {} s with E_o {:.3} dB, Adam alone {:.3} ({:+.3}); {:.0} s",
                    state.update,
                    config.scoring.seconds,
                    score.with,
                    score.without,
                    score.with - score.without,
                    state.seconds
                );
            }
            save(&network, &optimizer, &state)?;
        }
    }
    Ok(OptimizerSummary { state, checkpoint })
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use image::Rgb;
    use infer::Placed;
    use superpixel::Segmentation;

    use super::*;

    /// A dark square on white drawn one pixel too small, alone on a white canvas: one shape,
    /// whose refitted colour is the least-squares optimum, so the error's derivative by a move
    /// is the gradient along the move at the moved state (the envelope of the refit).
    fn square_case() -> Case {
        let size = 128u32;
        let (lo, hi) = (24.0, 104.0);
        let inside = |v: u32| (lo..hi).contains(&(v as f32 + 0.5));
        let target = Rgb32FImage::from_fn(size, size, |x, y| {
            if inside(x) && inside(y) { Rgb([0.2, 0.3, 0.4]) } else { Rgb([1.0; 3]) }
        });
        let segmentation = Segmentation::flat_areas(&target, 4).unwrap();
        let mut scene = Scene::new(Arc::new(target), Arc::new(segmentation));
        let unit = |v: f32| v / size as f32;
        let (a, b) = (unit(lo + 1.3), unit(hi - 0.7));
        let square = Outline::polygon(&[[a, a], [b, a], [b, b], [a, b]], [0.25, 0.3, 0.45], 1.0).unwrap();
        assert!(scene.push(Placed {
            shape: square.clone().into(),
            region: Some(1),
            origin: Origin::Fallback
        }));
        let window = white_window(scene.target()).unwrap();
        Case { name: "square".into(), scene, outlines: vec![square], movable: vec![true], window }
    }

    /// The first-order meta-gradient of a one-step rollout is the derivative of the error after
    /// the step by each point's move, against finite differences of the error itself (the move,
    /// the refit and the render done again).
    #[test]
    fn the_unrolled_gradient_matches_finite_differences() {
        let case = square_case();
        let target = case.scene.target();
        let mut runner = LearnedSteps::new(case.movable.clone(), 1);
        let input = runner.features(&case.outlines, &case.window, target);
        let moves = vec![0.4f32, -0.3, 0.25, -0.2];
        let error_after = |moves: &[f32]| {
            let mut runner = LearnedSteps::new(case.movable.clone(), 1);
            let input = runner.features(&case.outlines, &case.window, target);
            let moved = runner.apply(&case.outlines, &input, moves, target);
            case.window.l2_outlines(&moved)
        };
        let moved = runner.apply(&case.outlines, &input, &moves, target);
        let (_, _, gradient) = runner.gradient(&moved, &case.window, target.dimensions());
        let analytic = along_normals(&input.frames, &gradient);
        let h = 0.25;
        let mut seen = Vec::new();
        for i in 0..moves.len() {
            let shifted = |delta: f32| {
                let mut m = moves.clone();
                m[i] += delta;
                error_after(&m)
            };
            let numeric = (shifted(h) - shifted(-h)) / (2.0 * f64::from(h));
            seen.push((analytic[i], numeric));
        }
        // The window's gradient samples the outline (raster's own check holds it to the same
        // agreement): the direction and the size of the derivatives, over the points.
        let dot: f64 = seen.iter().map(|&(a, n)| f64::from(a) * n).sum();
        let norm =
            |pick: &dyn Fn(&(f32, f64)) -> f64| seen.iter().map(|p| pick(p).powi(2)).sum::<f64>().sqrt();
        let (analytic, numeric) = (norm(&|p| f64::from(p.0)), norm(&|p| p.1));
        assert!(dot / (analytic * numeric) > 0.95 && (0.8..1.25).contains(&(analytic / numeric)), "{seen:?}");
    }

    /// A step of an E_o that moves nothing changes nothing: the outlines and their fills stay.
    #[test]
    fn a_silent_step_changes_nothing() {
        let case = square_case();
        let device = Device::flex();
        let silent = LearnedOptimizer::new(&device).still();
        let mut runner = LearnedSteps::new(case.movable.clone(), 3);
        let (after, _) = runner.step(&silent, &case.outlines, &case.window, case.scene.target(), &device);
        assert_eq!(after, case.outlines);
    }
}
