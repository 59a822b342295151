//! Training the mover (E_m, [`model::Mover`]): its teacher, the samples the teacher makes, and
//! the resumable regression on them (`train-mover`).
//!
//! The teacher is the best one batched pass can do: for every outline of SuperSVG-B's drawing
//! (the background aside), its points moved by the exact optimizer (Adam on
//! [`raster::Window`], F's step size) against the outline's box with the rest of the drawing
//! held. Each point's move along its normal is the mover's target; its profile
//! ([`model::profile`]) the input. The samples of each image are made once and stored in the
//! run's folder, so a resumed run reads them back.

use std::path::{Path, PathBuf};
use std::time::Instant;

use burn::module::Module;
use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer};
use burn::tensor::{Device, Tensor, TensorData};
use common::PixelBox;
use common::decode::load;
use common::fingerprint::Fnv;
use common::outputs::{OutputError, check_not_input, create_folder, lock_folder};
use common::say;
use common::write::write_atomic;
use image::Rgb32FImage;
use infer::stages::move_outlines;
use infer::{FinetuneOptions, Job, Models, Moves, Origin, PathBudget, Scene, run};
use model::{MAX_MOVE, Mover, MoverCheckpoint, PROFILE_LEN, frames, profile};
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use raster::{Fill, FlatAdam, Outline, Window};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::stop::{catch_interrupts, heard, interrupted};

/// `train-mover`'s configuration (`configs/mover.toml`); unknown keys are refused.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MoverConfig {
    /// The drawings the teacher moves.
    pub data: MoverData,
    /// The teacher's optimizer.
    pub teacher: Teacher,
    /// The regression.
    pub train: MoverTraining,
    /// Held-out images each epoch's mover is scored on as inference runs it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub validation: Option<MoverValidation>,
}

/// Images the mover is scored on as inference runs it ([`MoverCheck`]): SuperSVG-B's drawings
/// of each at `data.paths`, moved, the move kept where it lowers the error.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MoverValidation {
    /// Image files, relative to the working folder; none of `data.images`.
    pub images: Vec<PathBuf>,
}

/// The drawings the teacher moves: SuperSVG-B's (defaults, the mover off) of each image at
/// each budget.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MoverData {
    /// Image files, relative to the working folder.
    pub images: Vec<PathBuf>,
    /// Path budgets.
    pub paths: Vec<usize>,
    /// Long side of the working image, as `infer --size`.
    pub size: u32,
}

/// How the teacher finds each outline's move.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Teacher {
    /// Adam steps on an outline's points (the best state is kept).
    pub steps: usize,
    /// Pixels around what an outline can change that its box also scores.
    pub pad: u32,
}

/// The regression of the teacher's moves.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MoverTraining {
    /// Passes over the samples.
    pub epochs: usize,
    /// Samples a step.
    pub batch: usize,
    /// Adam's learning rate.
    pub learning_rate: f64,
    /// Seeds the held-out split, the order of the samples and the initial weights.
    pub seed: u64,
    /// The share of the samples held out to score each epoch.
    pub held_out: f64,
}

/// Why a mover could not be trained; each names the file or setting.
#[derive(Debug, thiserror::Error)]
pub enum MoverError {
    /// The configuration file could not be read or holds an unknown key or a bad value.
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
    /// An image of `data.images` or `[validation]` is missing, or a held-out image is one of
    /// the training images.
    #[error("{0}")]
    Images(String),
    /// A samples file or the run's folder could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The reason.
        source: std::io::Error,
    },
    /// A samples file is not a whole number of samples, or holds a NaN or an infinity.
    #[error(
        "{0}: not a samples file, or one with a NaN or an infinity (damaged?): delete it and the run makes it again"
    )]
    Samples(PathBuf),
    /// The teacher made no sample: nothing in `data.images` to move.
    #[error("the teacher found no point to move in data.images (flat pictures?): nothing to train on")]
    NoSamples,
    /// A loss or a held-out error became NaN or infinite.
    #[error(
        "the loss became {value} at step {step} (train.learning_rate = {learning_rate}); stopped, {}",
        kept(.checkpoint)
    )]
    NonFinite {
        /// The loss.
        value: f64,
        /// The step it happened at (1-based).
        step: usize,
        /// The learning rate the run used.
        learning_rate: f64,
        /// The checkpoint left in place, when one was written (or resumed from).
        checkpoint: Option<PathBuf>,
    },
    /// The output folder cannot be used (a file in its place, another run writing to it) or an
    /// output would land on an input.
    #[error(transparent)]
    Output(#[from] OutputError),
    /// The checkpoint could not be written or read back.
    #[error(transparent)]
    Checkpoint(#[from] model::CheckpointError),
    /// The optimizer state could not be stored or restored.
    #[error("{path}: optimizer state: {problem}")]
    Optimizer {
        /// The checkpoint.
        path: PathBuf,
        /// burn's reason.
        problem: String,
    },
    /// A finished or stopped run's folder, not resumed or overwritten.
    #[error("{0} exists: pass --resume to continue it or --overwrite to start afresh")]
    Exists(PathBuf),
    /// A stop (Ctrl-C, SIGTERM) cut the drawing of the `[validation]` images short.
    #[error("interrupted while drawing the validation images")]
    Stopped,
    /// The run was stopped (Ctrl-C, SIGTERM) before training began: the teacher's samples made
    /// so far are kept, and running the same command again goes on from there.
    #[error(
        "interrupted before training began ({made} of {total} drawings' samples stored in {}); \
         run the same command again to go on from there",
        .folder.display()
    )]
    InterruptedBefore {
        /// Drawings whose samples are stored.
        made: usize,
        /// Drawings the run needs.
        total: usize,
        /// Where they are.
        folder: PathBuf,
    },
    /// The run was stopped (Ctrl-C, SIGTERM); the checkpoint holds what was done.
    #[error("interrupted in epoch {epoch}, after step {step}; --resume continues from {}", .checkpoint.display())]
    Interrupted {
        /// The epoch it stopped in, from 1 (0 while the teacher's samples were being made).
        epoch: usize,
        /// Steps done.
        step: usize,
        /// The checkpoint written.
        checkpoint: PathBuf,
    },
}

/// The most Adam steps the teacher takes on an outline.
pub const MAX_TEACHER_STEPS: usize = 10_000;
/// The widest pad around an outline's box (pixels).
pub const MAX_TEACHER_PAD: u32 = 256;
/// The most epochs of a run.
pub const MAX_EPOCHS: usize = 100_000;
/// The most samples a step.
pub const MAX_BATCH: usize = 1 << 16;

impl MoverConfig {
    /// The configuration in `path`, checked: every value within its range.
    pub fn load(path: &Path) -> Result<Self, MoverError> {
        let problem = |problem: String| MoverError::Config { path: path.to_path_buf(), problem };
        let text = std::fs::read_to_string(path).map_err(|e| problem(e.to_string()))?;
        let config: Self = toml::from_str(&text).map_err(|e| problem(e.to_string()))?;
        config.check().map_err(problem)?;
        Ok(config)
    }

    /// Every image there, and no `[validation]` image one of `data.images` by its contents,
    /// whatever its name: what a run checks before any work.
    pub fn check_images(&self) -> Result<(), MoverError> {
        let problem = MoverError::Images;
        let held = self.validation.as_ref().map_or(&[][..], |v| &v.images[..]);
        let read = |key: &str, image: &PathBuf| {
            std::fs::read(image).map_err(|err| problem(format!("{key}: {}: {err}", image.display())))
        };
        let mut seen = std::collections::HashMap::new();
        for image in &self.data.images {
            seen.insert(fingerprint(&read("data.images", image)?), image);
        }
        for image in held {
            if let Some(twin) = seen.get(&fingerprint(&read("validation.images", image)?)) {
                return Err(problem(format!(
                    "validation.images: {} is the image {} of data.images (held-out images must be others)",
                    image.display(),
                    twin.display()
                )));
            }
        }
        Ok(())
    }

    /// The first value out of range.
    fn check(&self) -> Result<(), String> {
        let (data, teacher, train) = (&self.data, &self.teacher, &self.train);
        let checks = [
            (data.images.is_empty(), "data.images is empty".to_string()),
            (
                data.paths.iter().any(|&p| !(infer::MIN_PATHS..=infer::MAX_PATHS).contains(&p)),
                format!("data.paths: each from {} to {}", infer::MIN_PATHS, infer::MAX_PATHS),
            ),
            (data.paths.is_empty(), "data.paths is empty".into()),
            (!common::WORKING_SIZES.contains(&data.size), "data.size: 16 to 8192".into()),
            (
                !(1..=MAX_TEACHER_STEPS).contains(&teacher.steps),
                format!("teacher.steps: 1 to {MAX_TEACHER_STEPS}"),
            ),
            (teacher.pad > MAX_TEACHER_PAD, format!("teacher.pad: at most {MAX_TEACHER_PAD}")),
            (!(1..=MAX_BATCH).contains(&train.batch), format!("train.batch: 1 to {MAX_BATCH}")),
            (!(1..=MAX_EPOCHS).contains(&train.epochs), format!("train.epochs: 1 to {MAX_EPOCHS}")),
            (
                !(train.learning_rate > 0.0 && train.learning_rate <= 1.0),
                "train.learning_rate: above 0, at most 1".into(),
            ),
            (!(0.0..0.5).contains(&train.held_out), "train.held_out: from 0 to below 0.5".into()),
            (
                self.validation.as_ref().is_some_and(|v| v.images.is_empty()),
                "validation.images is empty".into(),
            ),
        ];
        match checks.into_iter().find(|(bad, _)| *bad) {
            Some((_, what)) => Err(what),
            None => Ok(()),
        }
    }
}

/// The fingerprint of a file's bytes.
fn fingerprint(bytes: &[u8]) -> String {
    let mut hash = Fnv::new();
    hash.feed(bytes);
    hash.finish()
}

/// The end of a [`MoverError::NonFinite`] message.
fn kept(checkpoint: &Option<PathBuf>) -> String {
    match checkpoint {
        Some(path) => format!("the last good checkpoint is kept at {}", path.display()),
        None => "before any checkpoint was written".to_string(),
    }
}

/// The state a mover checkpoint stores for resuming: where the run is and how it scored.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct MoverState {
    /// Steps done.
    pub step: usize,
    /// Seconds of regression so far (the teacher's not counted).
    pub seconds: f64,
    /// The held-out squared error of each finished epoch's moves, px².
    pub held_out: Vec<f64>,
    /// The held-out squared error of moving nothing, px².
    pub still: f64,
    /// Each finished epoch's scores on `[validation]`'s images as inference runs the mover,
    /// one a budget (none without `[validation]`).
    #[serde(default)]
    pub at_inference: Vec<Vec<MoverScore>>,
    /// The configuration, as run.
    pub config: MoverConfig,
}

/// One sample: a point's profile and the teacher's move along its normal, in pixels.
pub type Sample = [f32; PROFILE_LEN + 1];

/// The teacher's samples of `scene` (SuperSVG-B's drawing): each point of each outline but the
/// background, its profile and its optimum move along the normal within [`MAX_MOVE`]. A stop
/// ([`interrupted`]) cuts the optimization short, so the caller discards what it returns then.
pub fn teach(scene: &Scene, teacher: &Teacher, rates: &FinetuneOptions) -> Vec<Sample> {
    let target = scene.target();
    let canvas = scene.canvas_image();
    let size = target.dimensions();
    let outlines: Vec<Outline> =
        (scene.scene().iter()).map(|shape| shape.to_outline().expect("a drawn path is finite")).collect();
    let room = Room::of(target, teacher.pad);
    let boxes: Vec<Option<PixelBox>> = outlines.iter().map(|o| room.pixel_box(o)).collect();
    (0..outlines.len())
        .into_par_iter()
        .filter(|&i| scene.paths()[i].origin != Origin::Background)
        .flat_map_iter(|i| {
            let moved = room.optimum(&outlines, &boxes, i, teacher.steps, false, rates).points();
            let frames = frames(&outlines[i], size);
            let (target, canvas) = (&target, &canvas);
            frames.into_iter().zip(moved).filter(|(frame, _)| frame.normal != [0.0; 2]).map(
                move |(frame, q)| {
                    let (w, h) = (size.0 as f32, size.1 as f32);
                    let (dx, dy) = (q[0] * w - frame.at[0], q[1] * h - frame.at[1]);
                    let distance = (dx * frame.normal[0] + dy * frame.normal[1]).clamp(-MAX_MOVE, MAX_MOVE);
                    let mut sample = [0.0; PROFILE_LEN + 1];
                    sample[..PROFILE_LEN].copy_from_slice(&profile(target, canvas, &frame));
                    sample[PROFILE_LEN] = distance;
                    sample
                },
            )
        })
        .collect()
}

/// An image as the exact renderer scores a box of it: where the teacher moves a drawing's
/// outlines one at a time, each against its own box with the rest of the drawing held.
pub struct Room {
    width: u32,
    height: u32,
    /// Pixels around what an outline can change that its box also scores.
    pad: u32,
    /// The image, planar RGB `[3][height][width]`.
    target: Vec<f32>,
}

impl Room {
    /// The room of `image`, boxes grown by `pad` pixels.
    pub fn of(image: &Rgb32FImage, pad: u32) -> Self {
        let (width, height) = image.dimensions();
        let target = (0..3).flat_map(|c| image.pixels().map(move |p| p.0[c])).collect();
        Self { width, height, pad, target }
    }

    /// The pixels `outline` can change, grown by the pad within the image: the box its move is
    /// scored over. `None` when it has no finite point.
    pub fn pixel_box(&self, outline: &Outline) -> Option<PixelBox> {
        let bbox = raster::Filled::pixel_box(outline, self.width, self.height)?;
        Some(bbox.padded(self.pad, self.width, self.height))
    }

    /// Outline `i` of `outlines` moved to its optimum over its box (`boxes`: each outline's
    /// [`Room::pixel_box`]) with every other outline held: its points, and with `paint` its
    /// flat colour and opacity too (a ramp keeps its stops and ends), by `steps` Adam steps at
    /// F's step sizes, the best state kept. An outline without a box stays as it is.
    pub fn optimum(
        &self,
        outlines: &[Outline],
        boxes: &[Option<PixelBox>],
        i: usize,
        steps: usize,
        paint: bool,
        rates: &FinetuneOptions,
    ) -> Outline {
        let Some(bbox) = boxes[i] else { return outlines[i].clone() };
        let (cw, ch) = (bbox.width() as usize, bbox.height() as usize);
        let (sx, sy) = (self.width as f32 / cw as f32, self.height as f32 / ch as f32);
        let (ox, oy) = (bbox.x0() as f32 / cw as f32, bbox.y0() as f32 / ch as f32);
        let to_box = |o: &Outline| mapped(o, |p| [p[0] * sx - ox, p[1] * sy - oy]);
        let meeting = |range: std::ops::Range<usize>| -> Vec<Outline> {
            (range.filter(|&k| boxes[k].is_some_and(|other| other.intersection(&bbox).is_some())))
                .map(|k| to_box(&outlines[k]))
                .collect()
        };
        let below = meeting(0..i);
        let mut scene = vec![to_box(&outlines[i])];
        scene.extend(meeting(i + 1..outlines.len()));
        let mut target = Vec::with_capacity(3 * cw * ch);
        let (width, height) = (self.width as usize, self.height as usize);
        for c in 0..3 {
            for y in bbox.rows() {
                let row = (c * height + y as usize) * width;
                target.extend_from_slice(&self.target[row + bbox.x0() as usize..row + bbox.x1() as usize]);
            }
        }
        let white =
            Window::new(cw as u32, ch as u32, vec![1.0; target.len()], target.clone()).expect("a box");
        let window = Window::new(cw as u32, ch as u32, white.render_outlines(&below), target).expect("a box");
        // Parameters: the points (x, y), then RGB and opacity; a pixel's step as F takes it.
        let solid = match scene[0].fill {
            Fill::Solid(color) => Some(color),
            Fill::Linear(_) => None,
        };
        let mut params: Vec<f32> = scene[0].points().into_iter().flatten().collect();
        let n = params.len();
        params.extend(solid.unwrap_or_default());
        params.push(scene[0].alpha);
        let mut step: Vec<f32> =
            (0..n).map(|k| rates.lr_outline_points * if k % 2 == 0 { sx } else { sy }).collect();
        step.extend([if paint && solid.is_some() { rates.lr_colors } else { 0.0 }; 4]);
        let set = |scene: &mut Vec<Outline>, params: &[f32]| {
            let points: Vec<[f32; 2]> = params[..n].chunks_exact(2).map(|p| [p[0], p[1]]).collect();
            let mut outline = scene[0].with_points(&points);
            if solid.is_some() {
                outline.fill = Fill::Solid([params[n], params[n + 1], params[n + 2]]);
            }
            outline.alpha = params[n + 3];
            scene[0] = outline;
        };
        // Adam keeps every value in [0, 1]: the points within the box, colour and opacity.
        let mut adam = FlatAdam::new(params.len());
        let mut best = (f64::INFINITY, params.clone());
        for _ in 0..steps {
            // A stop cuts the teacher short; its caller then keeps nothing of this outline's.
            if interrupted() {
                break;
            }
            set(&mut scene, &params);
            let (loss, gradients) = window.l2_gradient_outlines(&scene);
            if loss < best.0 {
                best = (loss, params.clone());
            }
            let g = &gradients[0];
            let mut flat: Vec<f32> = g.points.iter().flatten().copied().collect();
            flat.extend(g.color);
            flat.push(g.alpha);
            adam.step(&step, &mut params, &flat);
        }
        set(&mut scene, &params);
        if window.l2_outlines(&scene) < best.0 {
            best.1 = params;
        }
        set(&mut scene, &best.1);
        mapped(&scene[0], |p| [(p[0] + ox) / sx, (p[1] + oy) / sy])
    }
}

/// `outline` with its points and a ramp's ends mapped by `f` (its fill and opacity kept).
fn mapped(outline: &Outline, f: impl Fn([f32; 2]) -> [f32; 2]) -> Outline {
    let points: Vec<[f32; 2]> = outline.points().into_iter().map(&f).collect();
    let mut moved = outline.with_points(&points);
    if let Fill::Linear(mut ramp) = outline.fill {
        (ramp.start, ramp.end) = (f(ramp.start), f(ramp.end));
        moved.fill = Fill::Linear(ramp);
    }
    moved
}

/// Where a run keeps its checkpoint.
pub fn mover_checkpoint(dir: &Path) -> PathBuf {
    dir.join("mover.ckpt")
}

/// The teacher's samples of every image at every budget of `config`, each drawing's made once
/// and kept in `DIR/samples/` under a name that holds the fingerprint of what made them (the
/// image's bytes, the budget, the size, the teacher and B's networks), so a resumed or repeated
/// run reads back exactly what it would make, and a changed setting makes them again.
fn samples(config: &MoverConfig, dir: &Path, device: &Device) -> Result<Vec<Sample>, MoverError> {
    let folder = dir.join("samples");
    create_folder(&folder)?;
    // B as `infer` draws it, without a mover (the one trained here moves what this draws).
    let models = without_mover(device)?;
    let rates = FinetuneOptions::default();
    let total = config.data.images.len() * config.data.paths.len();
    let stopped = |made| MoverError::InterruptedBefore { made, total, folder: folder.clone() };
    let mut all = Vec::new();
    let mut made_so_far = 0;
    say!("teacher: the samples of {total} drawings, made or read back in {}", folder.display());
    for (index, image) in config.data.images.iter().enumerate() {
        let bytes = std::fs::read(image).map_err(|source| MoverError::Io { path: image.clone(), source })?;
        for &paths in &config.data.paths {
            if interrupted() {
                return Err(stopped(made_so_far));
            }
            let stem = image.file_stem().map_or_else(String::new, |s| s.to_string_lossy().into_owned());
            let key = samples_key(&bytes, paths, config, &models);
            let file = folder.join(format!("{index:03}-{stem}-{paths}-{key}.f32"));
            if file.exists() {
                all.extend(read_samples(&file)?);
                made_so_far += 1;
                continue;
            }
            let started = Instant::now();
            let (drawn, _) = draw_b(&models, image, paths, config.data.size, device)?;
            let made = teach(&drawn, &config.teacher, &rates);
            if interrupted() {
                return Err(stopped(made_so_far));
            }
            if made.iter().flatten().any(|v| !v.is_finite()) {
                let problem = "the teacher's moves hold a NaN or an infinity".to_string();
                return Err(MoverError::Image { path: image.clone(), problem });
            }
            let bytes: Vec<u8> = made.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
            write_atomic(&file, &bytes).map_err(|source| MoverError::Io { path: file.clone(), source })?;
            made_so_far += 1;
            say!(
                "{} at {paths} paths: {} points in {:.1} s",
                image.display(),
                made.len(),
                started.elapsed().as_secs_f64()
            );
            all.extend(made);
        }
    }
    if all.is_empty() {
        return Err(MoverError::NoSamples);
    }
    Ok(all)
}

/// The fingerprint of what makes one drawing's samples: the image's bytes, the budget, the
/// working size, the teacher's settings and B's networks.
fn samples_key(image: &[u8], paths: usize, config: &MoverConfig, models: &Models) -> String {
    let mut hash = Fnv::new();
    hash.feed_part(image);
    let refine = models.refine.as_ref().map_or("", |network| &network.identity.checksum);
    let settings = format!(
        "paths {paths} size {} steps {} pad {} coarse {} refine {refine}",
        config.data.size, config.teacher.steps, config.teacher.pad, models.coarse.identity.checksum
    );
    hash.feed_part(settings.as_bytes());
    hash.finish()
}

/// SuperSVG-B's models without the mover: the bundled E_c and E_r.
fn without_mover(device: &Device) -> Result<Models, MoverError> {
    let bundled = |built_in| {
        infer::bundled(built_in)
            .map_err(|e| MoverError::Config { path: PathBuf::from(built_in.name), problem: e.to_string() })
    };
    let (coarse, refine) = (bundled(&infer::BUILT_IN_COARSE)?, bundled(&infer::BUILT_IN_REFINE)?);
    Ok(Models::from_sources(&coarse, Some(&refine), device)?)
}

/// SuperSVG-B's drawing of `image` at `paths` paths and working size `size` (defaults, the
/// mover off), and the image's own size, which the SVG keeps.
fn draw_b(
    models: &Models,
    image: &Path,
    paths: usize,
    size: u32,
    device: &Device,
) -> Result<(Scene, (u32, u32)), MoverError> {
    let failed = |problem: String| MoverError::Image { path: image.to_path_buf(), problem };
    let loaded = load(image, size).map_err(|e| failed(e.to_string()))?;
    let job = Job { paths: PathBudget::Count(paths), moves: Moves::Off, ..Job::default() };
    let drawn = run(models, &loaded, &job, device).map_err(|e| failed(e.to_string()))?;
    Ok((drawn.scene, loaded.original))
}

/// SuperSVG-B's drawings of `[validation]`'s images at each budget, which a mover is scored on
/// the way inference runs it ([`infer::stages::move_outlines`]): so runs are compared on what
/// users get, not on the teacher's error alone.
pub struct MoverCheck {
    cases: Vec<(usize, Scene, (u32, u32))>,
}

/// A mover's score at one budget of a [`MoverCheck`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MoverScore {
    /// The budget, in paths.
    pub paths: usize,
    /// The mean PSNR gain (dB) of the kept moves over SuperSVG-B's drawings, a rejected move
    /// counting 0: what inference gains.
    pub gain_db: f64,
    /// Drawings whose move was kept, of `images`.
    pub kept: usize,
    /// Drawings scored.
    pub images: usize,
}

impl MoverCheck {
    /// Draws each of `images` at each of `data.paths` paths, at `data.size`, on `device`.
    pub fn build(images: &[PathBuf], data: &MoverData, device: &Device) -> Result<Self, MoverError> {
        let models = without_mover(device)?;
        let mut cases = Vec::with_capacity(images.len() * data.paths.len());
        for image in images {
            for &paths in &data.paths {
                if interrupted() {
                    return Err(MoverError::Stopped);
                }
                let (scene, original) = draw_b(&models, image, paths, data.size, device)?;
                cases.push((paths, scene, original));
            }
        }
        Ok(Self { cases })
    }

    /// `mover`'s scores (run on `device`), one per budget in the configuration's order (cut
    /// short by a stop, [`interrupted`], which a caller then does not record).
    pub fn score(&self, mover: &Mover, device: &Device) -> Vec<MoverScore> {
        let mut scores: Vec<MoverScore> = Vec::new();
        for (paths, scene, original) in &self.cases {
            if interrupted() {
                break;
            }
            let tally = move_outlines(mover, &mut scene.clone(), *original, device);
            let score = match scores.iter_mut().find(|score| score.paths == *paths) {
                Some(score) => score,
                None => {
                    scores.push(MoverScore { paths: *paths, gain_db: 0.0, kept: 0, images: 0 });
                    scores.last_mut().expect("just pushed")
                }
            };
            score.gain_db += tally.gain_db;
            score.kept += usize::from(tally.kept);
            score.images += 1;
        }
        for score in &mut scores {
            score.gain_db /= score.images as f64;
        }
        scores
    }
}

/// The samples [`samples`] stored in `file`: whole, and every value finite.
fn read_samples(file: &Path) -> Result<Vec<Sample>, MoverError> {
    let bytes = std::fs::read(file).map_err(|source| MoverError::Io { path: file.to_path_buf(), source })?;
    let width = 4 * (PROFILE_LEN + 1);
    if bytes.len() % width != 0 {
        return Err(MoverError::Samples(file.to_path_buf()));
    }
    let samples: Vec<Sample> = bytes
        .chunks_exact(width)
        .map(|row| {
            std::array::from_fn(|k| f32::from_le_bytes(row[4 * k..4 * k + 4].try_into().expect("4 bytes")))
        })
        .collect();
    match samples.iter().flatten().all(|v| v.is_finite()) {
        true => Ok(samples),
        false => Err(MoverError::Samples(file.to_path_buf())),
    }
}

/// How a mover run starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Begin {
    /// Afresh; a folder that holds a checkpoint is refused.
    Fresh,
    /// Afresh, replacing the folder's checkpoint (its samples are kept).
    Overwrite,
    /// From the folder's checkpoint.
    Resume,
}

/// What a finished run reports.
#[derive(Clone, Debug)]
pub struct MoverSummary {
    /// Its state at the end.
    pub state: MoverState,
    /// The checkpoint.
    pub checkpoint: PathBuf,
}

/// Trains a mover as `config` says in `dir` on `device` (an autodiff device): the teacher's
/// samples first (kept in `dir`), then `train.epochs` of Adam on the squared error of the
/// predicted moves, a checkpoint after each epoch and when stopped.
pub fn train_mover(
    config: &MoverConfig,
    dir: &Path,
    begin: Begin,
    device: &Device,
) -> Result<MoverSummary, MoverError> {
    catch_interrupts();
    config.check_images()?;
    create_folder(dir)?;
    // One run a folder: a second would replace the first's checkpoint under it.
    let _lock = lock_folder(dir)?;
    let checkpoint = mover_checkpoint(dir);
    let images = config.data.images.iter().chain(config.validation.iter().flat_map(|v| &v.images));
    check_not_input(&checkpoint, &images.collect::<Vec<_>>())?;
    if begin == Begin::Fresh && checkpoint.exists() {
        return Err(MoverError::Exists(checkpoint));
    }
    let resumed = match begin {
        Begin::Resume => Some(MoverCheckpoint::load(&checkpoint)?),
        _ => None,
    };
    let inner = device.clone().inner();
    let mut samples = samples(config, dir, &inner)?;
    let check = match &config.validation {
        Some(validation) => {
            Some(MoverCheck::build(&validation.images, &config.data, &inner).map_err(|err| match err {
                MoverError::Stopped => {
                    let total = config.data.images.len() * config.data.paths.len();
                    MoverError::InterruptedBefore { made: total, total, folder: dir.join("samples") }
                }
                err => err,
            })?)
        }
        None => None,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(config.train.seed);
    samples.shuffle(&mut rng);
    let held = ((samples.len() as f64 * config.train.held_out) as usize).min(samples.len());
    let (held, learn) = samples.split_at(held);
    let optimizer_error = |problem: String| MoverError::Optimizer { path: checkpoint.clone(), problem };
    let mut optimizer: ModuleOptimizer = AdamConfig::new().init();
    let (mut mover, mut state) = match resumed {
        Some(file) => {
            let mover = file.build(device, &checkpoint)?;
            let bytes = file.optimizer.clone().ok_or_else(|| optimizer_error("none stored".into()))?;
            optimizer = optimizer.from_bytes(bytes).map_err(|e| optimizer_error(e.to_string()))?;
            let state: MoverState = serde_json::from_str(file.training.as_deref().unwrap_or(""))
                .map_err(|e| optimizer_error(format!("trainer state: {e}")))?;
            // The run goes on as the configuration now says (more epochs, say).
            (mover, MoverState { config: config.clone(), ..state })
        }
        None => {
            device.seed(config.train.seed);
            let still = mean_square(held, std::iter::repeat(0.0));
            (
                Mover::new(device),
                MoverState {
                    step: 0,
                    seconds: 0.0,
                    held_out: Vec::new(),
                    still,
                    at_inference: Vec::new(),
                    config: config.clone(),
                },
            )
        }
    };
    let save = |mover: &Mover, optimizer: &ModuleOptimizer, state: &MoverState| -> Result<(), MoverError> {
        let mut file = MoverCheckpoint::of_model(mover);
        file.optimizer = Some(optimizer.into_bytes().map_err(|e| optimizer_error(e.to_string()))?);
        file.training = Some(serde_json::to_string(state).expect("the state serializes"));
        Ok(file.save(&checkpoint)?)
    };
    let batches = learn.len().div_ceil(config.train.batch);
    // The checkpoint a failure leaves in place: the one resumed from, then the latest written.
    let mut kept = (begin == Begin::Resume).then(|| checkpoint.clone());
    let non_finite = |value: f64, step: usize, kept: &Option<PathBuf>| MoverError::NonFinite {
        value,
        step,
        learning_rate: config.train.learning_rate,
        checkpoint: kept.clone(),
    };
    say!(
        "{} samples, {} held out; moving nothing errs {:.4} px² there",
        learn.len(),
        held.len(),
        state.still
    );
    while state.step < batches * config.train.epochs {
        let epoch = state.step / batches;
        let mut order: Vec<usize> = (0..learn.len()).collect();
        order.shuffle(&mut ChaCha8Rng::seed_from_u64(config.train.seed.wrapping_add(1 + epoch as u64)));
        let started = Instant::now();
        for batch in order.chunks(config.train.batch).skip(state.step % batches) {
            if interrupted() {
                heard();
                state.seconds += started.elapsed().as_secs_f64();
                save(&mover, &optimizer, &state)?;
                return Err(MoverError::Interrupted { epoch: epoch + 1, step: state.step, checkpoint });
            }
            let rows: Vec<&Sample> = batch.iter().map(|&k| &learn[k]).collect();
            let (inputs, targets) = tensors(&rows, device);
            let loss = (mover.forward(inputs) - targets).powi_scalar(2).mean();
            let value = f64::from(loss.clone().into_scalar::<f32>());
            if !value.is_finite() {
                return Err(non_finite(value, state.step + 1, &kept));
            }
            let grads = GradientsParams::from_grads(loss.backward(), &mover);
            mover = optimizer.step(config.train.learning_rate, mover, grads);
            state.step += 1;
        }
        state.seconds += started.elapsed().as_secs_f64();
        let scored = mover.valid();
        let error = mean_square_of(&scored, held, &inner);
        // The last step's update can leave weights no loss has seen yet: the held-out error has.
        if !error.is_finite() {
            return Err(non_finite(error, state.step, &kept));
        }
        state.held_out.push(error);
        say!(
            "epoch {}: held-out {error:.4} px² (still {:.4}), {:.0} s",
            epoch + 1,
            state.still,
            state.seconds
        );
        if let Some(check) = &check {
            let scores = check.score(&scored, &inner);
            // Cut short by a stop: not a score; the next step saves and ends.
            if interrupted() {
                continue;
            }
            for score in &scores {
                say!(
                    "  at inference, {} paths: {:+.3} dB, kept on {} of {} images",
                    score.paths,
                    score.gain_db,
                    score.kept,
                    score.images
                );
            }
            state.at_inference.push(scores);
        }
        save(&mover, &optimizer, &state)?;
        kept = Some(checkpoint.clone());
    }
    Ok(MoverSummary { state, checkpoint })
}

/// The profiles and targets of `rows` as tensors on `device`.
fn tensors(rows: &[&Sample], device: &Device) -> (Tensor<2>, Tensor<1>) {
    let inputs: Vec<f32> = rows.iter().flat_map(|row| row[..PROFILE_LEN].iter().copied()).collect();
    let targets: Vec<f32> = rows.iter().map(|row| row[PROFILE_LEN]).collect();
    (
        Tensor::from_data(TensorData::new(inputs, [rows.len(), PROFILE_LEN]), device),
        Tensor::from_data(TensorData::new(targets, [rows.len()]), device),
    )
}

/// The mean squared error of `moves` (one a sample) on `samples`, px².
fn mean_square(samples: &[Sample], moves: impl Iterator<Item = f32>) -> f64 {
    let sum: f64 = samples.iter().zip(moves).map(|(s, m)| f64::from((m - s[PROFILE_LEN]).powi(2))).sum();
    sum / samples.len().max(1) as f64
}

/// The mean squared error of `mover`'s moves (as inference clamps them) on `samples`, px².
fn mean_square_of(mover: &Mover, samples: &[Sample], device: &Device) -> f64 {
    let mut predicted = Vec::with_capacity(samples.len());
    for chunk in samples.chunks(65_536) {
        let profiles: Vec<f32> = chunk.iter().flat_map(|row| row[..PROFILE_LEN].iter().copied()).collect();
        predicted.extend(mover.moves(profiles, device));
    }
    mean_square(samples, predicted.into_iter())
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use image::{Rgb, Rgb32FImage};
    use infer::Placed;
    use raster::Path as RasterPath;
    use superpixel::Segmentation;

    use super::*;

    /// The check scores a mover as inference runs it: on the bundled example at a small size,
    /// the bundled mover's score is the gain `infer --moves on` reports for the same drawing.
    #[test]
    fn the_check_scores_a_mover_as_inference_runs_it() {
        let device = Device::flex();
        let image = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../assets/astronaut.jpg");
        let data = MoverData { images: vec![], paths: vec![60, 120], size: 96 };
        let check = MoverCheck::build(std::slice::from_ref(&image), &data, &device).unwrap();
        let mover = MoverCheckpoint::from_bytes(infer::BUILT_IN_MOVER.bytes, Path::new("mover.ckpt"))
            .unwrap()
            .build(&device, Path::new("mover.ckpt"))
            .unwrap();
        let scores = check.score(&mover, &device);
        assert_eq!(scores.iter().map(|s| (s.paths, s.images)).collect::<Vec<_>>(), [(60, 1), (120, 1)]);
        let models = Models::bundled(true, &device).unwrap();
        let loaded = load(&image, data.size).unwrap();
        for score in &scores {
            let job = Job { paths: PathBudget::Count(score.paths), moves: Moves::On, ..Job::default() };
            let moves = run(&models, &loaded, &job, &device).unwrap().report.moves.unwrap();
            assert_eq!((score.gain_db, score.kept), (moves.gain_db, usize::from(moves.kept)), "{score:?}");
        }
        assert!(scores.iter().any(|s| s.kept == 1 && s.gain_db > 0.0), "{scores:?}");
    }

    /// A dark square drawn 2 px inside the one in the image: the teacher moves every corner
    /// outward, toward the image's edge, and makes one sample a corner (the background is not
    /// its to move).
    #[test]
    fn the_teacher_moves_a_shrunk_square_out_to_its_edge() {
        let size = 256u32;
        let (lo, hi) = (96.0, 160.0);
        let inside = |v: u32| (lo..hi).contains(&(v as f32 + 0.5));
        let target = Rgb32FImage::from_fn(size, size, |x, y| {
            if inside(x) && inside(y) { Rgb([0.1, 0.2, 0.3]) } else { Rgb([0.9; 3]) }
        });
        let segmentation = Segmentation::flat_areas(&target, 4).unwrap();
        let mut scene = Scene::new(Arc::new(target), Arc::new(segmentation));
        let unit = |v: f32| v / size as f32;
        let background =
            RasterPath::quadrilateral([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]], [0.9; 3], 1.0);
        let (a, b) = (unit(lo + 2.0), unit(hi - 2.0));
        let square = Outline::polygon(&[[a, a], [b, a], [b, b], [a, b]], [0.1, 0.2, 0.3], 1.0).unwrap();
        assert!(scene.push(Placed { shape: background.into(), region: None, origin: Origin::Background }));
        assert!(scene.push(Placed {
            shape: square.clone().into(),
            region: Some(1),
            origin: Origin::Fallback
        }));
        let samples = teach(&scene, &Teacher { steps: 60, pad: 5 }, &FinetuneOptions::default());
        assert_eq!(samples.len(), 4);
        let centre = (lo + hi) / 2.0;
        for (sample, frame) in samples.iter().zip(frames(&square, (size, size))) {
            let moved = frame.moved(sample[PROFILE_LEN], (size, size)).map(|v| v * size as f32);
            let out = (moved[0] - centre).abs().min((moved[1] - centre).abs());
            assert!(
                out > (hi - lo) / 2.0 - 2.0 + 0.5,
                "{frame:?} moved {} px to {moved:?}",
                sample[PROFILE_LEN]
            );
        }
    }
}
