//! Training configuration files (TOML): unknown keys and bad values are rejected by name.

use std::path::{Path, PathBuf};

use model::{InvalidSetting, ModelConfig, Preset, RefineAnchor};
use raster::SoftRasterOptions;
use serde::de::Error as _;
use serde::{Deserialize, Deserializer, Serialize};

/// Everything `train-coarse` reads from its config file.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CoarseConfig {
    /// Architecture: `preset = "cpu" | "paper"` plus any field of [`ModelConfig`] to override.
    #[serde(default)]
    pub model: ModelSection,
    /// Where samples come from.
    pub data: DataConfig,
    /// Optimizer, schedule, checkpoints.
    pub train: OptimConfig,
    /// Loss weights.
    #[serde(default)]
    pub loss: CoarseLoss,
    /// Soft rasterizer used in the losses.
    #[serde(default)]
    pub raster: RasterConfig,
    /// Held-out crops scored during training.
    #[serde(default)]
    pub validation: ValidationConfig,
}

/// Everything `train-refine` reads from its config file. The architecture comes from the coarse
/// checkpoint it starts from.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RefineConfig {
    /// E_r's own settings on top of the coarse checkpoint's model.
    #[serde(default)]
    pub model: RefineModelSettings,
    /// Where samples come from.
    pub data: DataConfig,
    /// Optimizer, schedule, checkpoints.
    pub train: OptimConfig,
    /// Loss weights and the guidance by the coarse paths.
    #[serde(default)]
    pub loss: RefineLoss,
    /// Soft rasterizer used in the losses.
    #[serde(default)]
    pub raster: RasterConfig,
    /// Held-out crops scored during training.
    #[serde(default)]
    pub validation: ValidationConfig,
}

/// The `[model]` table of a refine config: the networks are the coarse checkpoint's (`--init`),
/// so only what E_r alone reads can be set here.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RefineModelSettings {
    /// Where E_r's paths start before its head moves them.
    pub refine_anchor: RefineAnchor,
}

impl RefineModelSettings {
    /// `coarse`, the coarse checkpoint's model, with these settings: E_r's model.
    pub fn apply(&self, coarse: &ModelConfig) -> ModelConfig {
        ModelConfig { refine_anchor: self.refine_anchor, ..coarse.clone() }
    }
}

/// The `[model]` table: a preset and overrides, resolved into a validated [`ModelConfig`].
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(transparent)]
pub struct ModelSection(pub ModelConfig);

impl Default for ModelSection {
    fn default() -> Self {
        Self(ModelConfig::preset(Preset::Cpu))
    }
}

impl<'de> Deserialize<'de> for ModelSection {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let mut table = toml::Table::deserialize(deserializer)?;
        let preset = match table.remove("preset") {
            None => Preset::Cpu,
            Some(value) => {
                Preset::deserialize(value).map_err(|err| D::Error::custom(format!("model.preset: {err}")))?
            }
        };
        let mut merged = toml::Table::try_from(ModelConfig::preset(preset)).map_err(D::Error::custom)?;
        merged.extend(table);
        let config =
            ModelConfig::deserialize(merged).map_err(|err| D::Error::custom(format!("model: {err}")))?;
        config.validate().map_err(D::Error::custom)?;
        Ok(Self(config))
    }
}

/// Which regions of a segmented scene a training batch takes (`data.pick`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RegionPick {
    /// Any, at random.
    #[default]
    Random,
    /// Those a fill of their mean colour gets most wrong: the regions inference gives E_c
    /// (the operating point's `coarse_share` goes to the regions the flat drawing errs most on).
    Worst,
}

/// How a scene is split into the regions samples are cut from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RegionRecipe {
    /// SLIC at `compactness`, asked for `oversegment` × the count and merged by colour above
    /// `min_compactness` (`superpixel::SegmentOptions`): what the shipped models trained on.
    #[default]
    Slic,
    /// Inference's regions (`superpixel::SegmentOptions::ward`): Ward's merges of a fine,
    /// unsmoothed SLIC at `compactness`, so E_c trains on the regions it is asked to draw.
    /// `oversegment` and `min_compactness` are not read.
    Ward,
}

/// What each training sample carries besides its crop (`data.canvas`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SampleCanvas {
    /// The crop alone.
    #[default]
    None,
    /// The drawing inference hands E_r, made by inference's own code (`infer`'s merge tree and
    /// fallback drawing: every region's polygon in its mean colour over the background path),
    /// cut under the crop's box, with the image under the same box: E_r learns to add to what
    /// it is given at inference, scored as inference's acceptance test scores it (the error in
    /// the box). Regions are inference's regions at `compactness` (`recipe`, `oversegment` and
    /// `min_compactness` are not read), and `pick = "worst"` ranks them by that drawing's error,
    /// as inference gives E_r the regions drawn worst. `train-refine` only.
    Fallback,
}

/// The `[data]` table.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DataConfig {
    /// A folder of training images (searched recursively), relative to the working directory.
    pub images: Option<PathBuf>,
    /// Use the built-in generator of random vector scenes.
    pub synthetic: bool,
    /// Fraction of samples drawn from the generator when both sources are on.
    pub synthetic_weight: f32,
    /// Range (inclusive) of region counts drawn per scene: with `image_size` at inference's
    /// working size, the counts inference uses make the regions inference cuts.
    pub segments: [usize; 2],
    /// SLIC compactness (the method uses 30).
    pub compactness: f32,
    /// How regions are made.
    pub recipe: RegionRecipe,
    /// SLIC is asked for this many times the count, merged by colour down to it, as inference's
    /// operating point does (`superpixel::segment`); 1 is plain SLIC.
    pub oversegment: f32,
    /// The least isoperimetric quotient of a merged region, as in the operating point.
    pub min_compactness: f32,
    /// Regions sampled from each segmented scene before the next (segmenting is the costly
    /// part of a sample).
    pub regions_per_scene: usize,
    /// Which of a scene's regions become samples.
    pub pick: RegionPick,
    /// Segment a random window of this side (pixels) of each scene, with the share of the
    /// region count its area is: the regions are as large as on the whole scene, for a fraction
    /// of the segmenting. 0 segments whole scenes.
    pub window: u32,
    /// Images are scaled to this long side before SLIC (and generated scenes made this big).
    pub image_size: u32,
    /// Threads preparing batches.
    pub workers: usize,
    /// Batches prepared ahead of the model.
    pub prefetch: usize,
    /// Use batch 0 at every step (overfitting one batch: a sanity check, and the smoke tests).
    pub fixed_batch: bool,
    /// What each sample carries besides its crop.
    pub canvas: SampleCanvas,
}

impl Default for DataConfig {
    fn default() -> Self {
        Self {
            images: None,
            synthetic: true,
            synthetic_weight: 0.5,
            segments: [8, 48],
            compactness: 30.0,
            recipe: RegionRecipe::Slic,
            oversegment: 1.0,
            min_compactness: 0.0,
            regions_per_scene: 4,
            pick: RegionPick::Random,
            window: 0,
            image_size: 256,
            workers: 1,
            prefetch: 4,
            fixed_batch: false,
            canvas: SampleCanvas::None,
        }
    }
}

/// The `[train]` table: AdamW with linear warm-up and cosine decay, and bookkeeping.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OptimConfig {
    /// Seed of the initialization, the data order and every random choice.
    pub seed: u64,
    /// Total optimizer steps.
    pub steps: usize,
    /// Samples per step.
    pub batch_size: usize,
    /// Peak learning rate.
    pub lr: f64,
    /// Learning rate at the end of the cosine decay.
    pub min_lr: f64,
    /// Steps of linear warm-up from 0 to `lr`.
    pub warmup_steps: usize,
    /// AdamW weight decay (not applied to norms and biases).
    pub weight_decay: f32,
    /// AdamW β1, β2.
    pub betas: [f32; 2],
    /// Clip the gradient's global norm to this value; 0 disables clipping.
    pub grad_clip: f32,
    /// Steps between checkpoints (one is always written at the end).
    pub checkpoint_every: usize,
    /// Steps between lines of `metrics.jsonl`.
    pub log_every: usize,
}

impl Default for OptimConfig {
    fn default() -> Self {
        Self {
            seed: 0,
            steps: 10_000,
            batch_size: 16,
            lr: 5e-4,
            min_lr: 1e-5,
            warmup_steps: 500,
            weight_decay: 0.05,
            betas: [0.9, 0.95],
            grad_clip: 1.0,
            checkpoint_every: 500,
            log_every: 10,
        }
    }
}

/// How λ_bound changes: from `start`, minus `decay_per_epoch` every `epoch_steps`, down to `end`
/// (the reference: 0.045 → 0.01 by 0.005 per epoch).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BoundaryWeight {
    /// λ_bound at step 0.
    pub start: f32,
    /// Lowest λ_bound.
    pub end: f32,
    /// Decrease per epoch.
    pub decay_per_epoch: f32,
    /// Steps that count as an epoch (the data stream is endless).
    pub epoch_steps: usize,
    /// Dilation of the mask in pixels ([`dpw::BOUNDARY_DILATION`] by default).
    pub dilation: usize,
}

impl Default for BoundaryWeight {
    fn default() -> Self {
        Self {
            start: 0.045,
            end: 0.01,
            decay_per_epoch: 0.005,
            epoch_steps: 1000,
            dilation: dpw::BOUNDARY_DILATION,
        }
    }
}

impl BoundaryWeight {
    /// λ_bound at `step`.
    pub fn at(&self, step: usize) -> f32 {
        let epochs = (step / self.epoch_steps.max(1)) as f32;
        (self.start - epochs * self.decay_per_epoch).max(self.end)
    }
}

/// What E_c's paths are drawn over in training.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Canvas {
    /// The rasterizer's background colour (the method).
    Background,
    /// Each region's mean colour: what inference draws the region with (its fallback path)
    /// before E_c's paths, so the model learns what to add to it.
    MeanColour,
}

/// The `[loss]` table of the coarse stage.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CoarseLoss {
    /// What the paths are drawn over.
    pub canvas: Canvas,
    /// Scales of the normalized L2 (1 = full resolution only; more widen the basin).
    pub l2_levels: usize,
    /// λ_PE on the number of visible paths (a sum over paths).
    pub path_efficiency: f32,
    /// λ_bound and its schedule.
    pub boundary: BoundaryWeight,
}

impl Default for CoarseLoss {
    fn default() -> Self {
        Self {
            canvas: Canvas::Background,
            l2_levels: 3,
            path_efficiency: 1e-5,
            boundary: BoundaryWeight::default(),
        }
    }
}

/// How the refinement model's paths are tied to the coarse model's leftover paths.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Guidance {
    /// Dynamic Path Warping (the method).
    Dpw,
    /// Plain L2 in parameter space against the next m coarse paths, one to one (ablation).
    L2,
    /// No guidance, reconstruction only (ablation).
    None,
}

/// The colours E_r's paths are scored in (`loss.colours`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PathColours {
    /// The colours E_r predicts.
    #[default]
    Predicted,
    /// Each path in the colour that fits the target best over what lies below it
    /// (`raster::Window::fit_colours`). Inference refits every colour E_r proposes
    /// (`infer::Scene::fit_colour`) and keeps only the shape and opacity, so this loss scores
    /// those alone; E_r's own colours then learn from the guidance only.
    Fitted,
}

/// What E_r's image term measures (`loss.reconstruction`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Reconstruction {
    /// The multi-scale L2 of all of E_r's paths drawn together over the canvas.
    #[default]
    Joint,
    /// Inference's acceptance test: each path alone over the canvas, and the error it takes
    /// away from the box counted only where it takes some away (a path that would be refused
    /// costs nothing, as at inference). Needs `data.canvas = "fallback"`, whose boxes are all
    /// image.
    Accepted,
}

/// What E_r's guidance pulls its paths towards (`loss.teacher`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Teacher {
    /// The frozen E_c's visible paths after the split: the paper's coarse-paths guidance.
    #[default]
    Coarse,
    /// The paths the exact optimizer places on the sample's canvas against its image
    /// ([`model::PathOptimizer`], `loss.teacher_steps` Adam steps): seeded where the
    /// canvas errs most. Needs `data.canvas = "fallback"`, whose boxes are all image.
    Optimizer,
}

/// The `[loss]` table of the refinement stage.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RefineLoss {
    /// Scales of the normalized L2.
    pub l2_levels: usize,
    /// Which guidance term is used.
    pub guidance: Guidance,
    /// λ of the guidance term at step 0; it decays linearly to 0.
    pub guidance_start: f32,
    /// Steps over which λ decays to 0 (the paper: 10 K).
    pub guidance_decay_steps: usize,
    /// Soft-min temperature γ of DPW (0.01 in the reference).
    pub gamma: f32,
    /// Weight of coordinates in the path distance.
    pub distance_coords: f32,
    /// Weight of colours in the path distance.
    pub distance_color: f32,
    /// λ_bound and its schedule.
    pub boundary: BoundaryWeight,
    /// The colours the image terms score E_r's paths in.
    pub colours: PathColours,
    /// What the image term measures.
    pub reconstruction: Reconstruction,
    /// With `reconstruction = "accepted"`, the share of its harm a path that would be refused
    /// costs: 0 is inference's test (a refused path costs nothing and learns nothing), above 0
    /// pulls refused paths towards where they would be kept.
    pub refused_weight: f32,
    /// The paths the guidance pulls E_r's towards.
    pub teacher: Teacher,
    /// Adam steps of the optimizer teacher on each sample.
    pub teacher_steps: usize,
}

impl Default for RefineLoss {
    fn default() -> Self {
        Self {
            l2_levels: 3,
            guidance: Guidance::Dpw,
            guidance_start: 1e-3,
            guidance_decay_steps: 10_000,
            gamma: 0.01,
            distance_coords: 1.0,
            distance_color: 1.0,
            boundary: BoundaryWeight::default(),
            colours: PathColours::Predicted,
            reconstruction: Reconstruction::Joint,
            refused_weight: 0.0,
            teacher: Teacher::Coarse,
            teacher_steps: 100,
        }
    }
}

impl RefineLoss {
    /// λ of the guidance term at `step`.
    pub fn guidance_at(&self, step: usize) -> f32 {
        let remaining = 1.0 - step as f32 / self.guidance_decay_steps.max(1) as f32;
        self.guidance_start * remaining.max(0.0)
    }
}

/// Which rasterizer the training losses read.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Rasterizer {
    /// The soft rasterizer in burn tensor ops, differentiated by autodiff: runs on every
    /// backend, costs paths × pixels in the graph.
    #[default]
    Soft,
    /// `raster::ExactBatch`: tiny-skia's coverage on the CPU, the gradient by edge sampling;
    /// the render the SVG will have, for the cost of each path's own pixels.
    Exact,
}

/// The `[raster]` table: the rasterizer of the losses.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RasterConfig {
    /// Soft (autodiff) or exact (edge sampling).
    pub rasterizer: Rasterizer,
    /// Straight edges per cubic segment (soft rasterizer; previews).
    pub segments_per_curve: usize,
    /// Bands per pixel row (soft rasterizer; previews).
    pub subrows: usize,
    /// Colour under the paths in training renders.
    pub background: [f32; 3],
}

impl Default for RasterConfig {
    fn default() -> Self {
        let soft = SoftRasterOptions::default();
        Self {
            rasterizer: Rasterizer::Soft,
            segments_per_curve: soft.segments_per_curve,
            subrows: soft.subrows,
            background: soft.background,
        }
    }
}

impl RasterConfig {
    /// The rasterizer options these settings describe.
    pub fn options(&self) -> SoftRasterOptions {
        SoftRasterOptions {
            segments_per_curve: self.segments_per_curve,
            subrows: self.subrows,
            background: self.background,
        }
    }
}

/// A config file that could not be used; the message names the file and, where it is one key's
/// fault, the key.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {problem}")]
pub struct ConfigError {
    /// The config file.
    pub path: PathBuf,
    /// What is wrong.
    pub problem: ConfigProblem,
}

/// What is wrong with a config file.
#[derive(Debug, thiserror::Error)]
pub enum ConfigProblem {
    /// The file could not be read.
    #[error(transparent)]
    Read(#[from] std::io::Error),
    /// Not TOML, an unknown key, or a value of the wrong type (toml names the line).
    #[error(transparent)]
    Parse(#[from] toml::de::Error),
    /// A value out of its range.
    #[error(transparent)]
    Invalid(#[from] InvalidSetting),
}

/// Reads and validates a config file.
pub fn load<T: for<'de> Deserialize<'de> + Validate>(path: &Path) -> Result<T, ConfigError> {
    let error = |problem| ConfigError { path: path.to_path_buf(), problem };
    let text = std::fs::read_to_string(path).map_err(|err| error(err.into()))?;
    parse(&text).map_err(error)
}

/// Parses and validates a config file's text.
fn parse<T: for<'de> Deserialize<'de> + Validate>(text: &str) -> Result<T, ConfigProblem> {
    let config: T = toml::from_str(text)?;
    config.validate()?;
    Ok(config)
}

/// Checks of values that parse but make no sense; messages name the key.
pub trait Validate {
    /// `Err("table.key …")` for the first bad value.
    fn validate(&self) -> Result<(), InvalidSetting>;
}

impl Validate for CoarseConfig {
    fn validate(&self) -> Result<(), InvalidSetting> {
        self.data.validate()?;
        self.train.validate()?;
        self.raster.validate()?;
        self.validation.validate()?;
        check(self.loss.l2_levels >= 1, "loss.l2_levels must be at least 1")?;
        check(self.loss.path_efficiency >= 0.0, "loss.path_efficiency must not be negative")?;
        check(
            self.data.canvas == SampleCanvas::None,
            "data.canvas is E_r's (train-refine): E_c draws each region on its own",
        )?;
        self.loss.boundary.validate()
    }
}

impl Validate for RefineConfig {
    fn validate(&self) -> Result<(), InvalidSetting> {
        self.data.validate()?;
        self.train.validate()?;
        self.raster.validate()?;
        self.validation.validate()?;
        check(self.loss.l2_levels >= 1, "loss.l2_levels must be at least 1")?;
        check(self.loss.guidance_start >= 0.0, "loss.guidance_start must not be negative")?;
        check(self.loss.gamma >= 0.0 && self.loss.gamma.is_finite(), "loss.gamma must be zero or positive")?;
        check(self.loss.distance_coords >= 0.0, "loss.distance_coords must not be negative")?;
        check(self.loss.distance_color >= 0.0, "loss.distance_color must not be negative")?;
        check(
            self.loss.teacher == Teacher::Coarse || self.data.canvas == SampleCanvas::Fallback,
            "loss.teacher = \"optimizer\" needs data.canvas = \"fallback\" (a drawing and the image under each box)",
        )?;
        check(self.loss.teacher_steps >= 1, "loss.teacher_steps must be positive")?;
        check((0.0..=1.0).contains(&self.loss.refused_weight), "loss.refused_weight must be within [0, 1]")?;
        check(
            self.loss.reconstruction == Reconstruction::Joint || self.data.canvas == SampleCanvas::Fallback,
            "loss.reconstruction = \"accepted\" needs data.canvas = \"fallback\" (a drawing and the image under each box)",
        )?;
        self.loss.boundary.validate()
    }
}

impl DataConfig {
    /// How scenes are split into regions.
    pub fn segment_options(&self) -> superpixel::SegmentOptions {
        match self.recipe {
            RegionRecipe::Slic => superpixel::SegmentOptions {
                compactness: self.compactness,
                oversegment: self.oversegment,
                min_compactness: self.min_compactness,
                ..Default::default()
            },
            RegionRecipe::Ward => superpixel::SegmentOptions::ward(self.compactness),
        }
    }

    fn validate(&self) -> Result<(), InvalidSetting> {
        check(
            self.images.is_some() || self.synthetic,
            "data: set data.images, data.synthetic = true, or both",
        )?;
        check((0.0..=1.0).contains(&self.synthetic_weight), "data.synthetic_weight must be within [0, 1]")?;
        check(
            self.segments[0] >= 1
                && self.segments[0] <= self.segments[1]
                && self.segments[1] <= limits::REGIONS,
            &format!("data.segments must be [low, high] with 1 ≤ low ≤ high ≤ {}", limits::REGIONS),
        )?;
        check(self.compactness > 0.0 && self.compactness.is_finite(), "data.compactness must be positive")?;
        check(
            self.oversegment.is_finite() && self.oversegment >= 1.0,
            "data.oversegment must be at least 1",
        )?;
        check((0.0..=1.0).contains(&self.min_compactness), "data.min_compactness must be within [0, 1]")?;
        within("data.regions_per_scene", self.regions_per_scene, 1, limits::REGIONS)?;
        let sizes = common::WORKING_SIZES;
        within("data.image_size", self.image_size as usize, *sizes.start() as usize, *sizes.end() as usize)?;
        within("data.workers", self.workers, 1, limits::WORKERS)?;
        within("data.prefetch", self.prefetch, 1, limits::PREFETCH)
    }
}

impl OptimConfig {
    fn validate(&self) -> Result<(), InvalidSetting> {
        check(self.steps >= 1, "train.steps must be positive")?;
        within("train.batch_size", self.batch_size, 1, limits::BATCH)?;
        check(self.lr > 0.0 && self.lr.is_finite(), "train.lr must be positive")?;
        check(self.min_lr >= 0.0 && self.min_lr <= self.lr, "train.min_lr must be within [0, train.lr]")?;
        check(self.weight_decay >= 0.0, "train.weight_decay must not be negative")?;
        check(self.betas.iter().all(|b| (0.0..1.0).contains(b)), "train.betas must be within [0, 1)")?;
        check(self.grad_clip >= 0.0, "train.grad_clip must not be negative")?;
        check(self.checkpoint_every >= 1, "train.checkpoint_every must be positive")?;
        check(self.log_every >= 1, "train.log_every must be positive")
    }
}

impl RasterConfig {
    fn validate(&self) -> Result<(), InvalidSetting> {
        within("raster.segments_per_curve", self.segments_per_curve, 1, limits::SUBDIVISIONS)?;
        within("raster.subrows", self.subrows, 1, limits::SUBDIVISIONS)?;
        check(
            self.background.iter().all(|c| (0.0..=1.0).contains(c)),
            "raster.background must be RGB within [0, 1]",
        )
    }
}

impl BoundaryWeight {
    fn validate(&self) -> Result<(), InvalidSetting> {
        check(self.start >= 0.0 && self.end >= 0.0, "loss.boundary.start and end must not be negative")?;
        check(self.decay_per_epoch >= 0.0, "loss.boundary.decay_per_epoch must not be negative")?;
        check(self.epoch_steps >= 1, "loss.boundary.epoch_steps must be positive")
    }
}

fn check(ok: bool, message: &str) -> Result<(), InvalidSetting> {
    if ok { Ok(()) } else { Err(InvalidSetting(message.to_string())) }
}

/// Refuses `value` of the setting `name` outside `low..=high`, naming both.
fn within(name: &str, value: usize, low: usize, high: usize) -> Result<(), InvalidSetting> {
    check((low..=high).contains(&value), &format!("{name} must be from {low} to {high}"))
}

/// Upper bounds of the sizes and counts a config sets: far above what trains on this hardware,
/// low enough that a typo (`batch_size = 1e11`) is refused by name before training starts
/// instead of aborting on an allocation or growing for minutes.
mod limits {
    /// Samples in a batch.
    pub const BATCH: usize = 4096;
    /// Regions of a scene (`data.segments`, `regions_per_scene`, `validation.segments`).
    pub const REGIONS: usize = 20_000;
    /// Data-loading threads.
    pub const WORKERS: usize = 256;
    /// Batches kept ready per worker.
    pub const PREFETCH: usize = 1024;
    /// `raster.segments_per_curve` and `raster.subrows`.
    pub const SUBDIVISIONS: usize = 256;
    /// Validation crops.
    pub const CROPS: usize = 100_000;
}

/// The `[validation]` table.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ValidationConfig {
    /// A folder of held-out images (never in the training data), relative to the working
    /// directory.
    pub images: Option<PathBuf>,
    /// Crops in the set, taken evenly from the images.
    pub crops: usize,
    /// Region counts of the images' segmentations, spread geometrically over the images from
    /// the first to the second. Regions are made as inference makes them
    /// (`superpixel::SegmentOptions::ward`), whatever the training data uses, so runs with
    /// different `[data]` are scored on the same crops.
    pub segments: [usize; 2],
    /// Steps between scores (and previews of the validation crops).
    pub every: usize,
    /// Images are scaled to this long side before segmenting: inference's working size, so the
    /// crops are the regions inference cuts whatever resolution training uses.
    pub image_size: u32,
    /// E_r runs are also scored the way inference uses E_r ([`crate::inference::RefineCheck`]):
    /// each image drawn by its regions (at the counts of `segments`), E_r given this share of
    /// the paths on top, against the same paths spent on more regions.
    pub refine_share: f32,
    /// E_c runs are also scored the way inference uses E_c ([`crate::inference::CoarseCheck`]):
    /// each image drawn by SuperSVG-B without E_r, E_c given this share of the budget (the
    /// stored operating point's), against the regions alone at the same budget.
    pub coarse_share: f32,
}

impl Default for ValidationConfig {
    fn default() -> Self {
        Self {
            images: None,
            crops: 64,
            segments: [250, 2000],
            every: 250,
            image_size: 512,
            refine_share: 0.1,
            coarse_share: 0.2,
        }
    }
}

impl ValidationConfig {
    /// Checks the values; the message names the key.
    pub fn validate(&self) -> Result<(), InvalidSetting> {
        let invalid = |message: &str| Err(InvalidSetting(message.into()));
        if self.every == 0 {
            return invalid("validation.every must be positive");
        }
        within("validation.crops", self.crops, 1, limits::CROPS)?;
        let sizes = common::WORKING_SIZES;
        within(
            "validation.image_size",
            self.image_size as usize,
            *sizes.start() as usize,
            *sizes.end() as usize,
        )?;
        if self.segments[0] == 0 || self.segments[0] > self.segments[1] || self.segments[1] > limits::REGIONS
        {
            return invalid(&format!(
                "validation.segments must be [low, high] with 1 ≤ low ≤ high ≤ {}",
                limits::REGIONS
            ));
        }
        // Each leaves the regions a share of the budget, as an operating point must.
        if !(self.refine_share > 0.0 && self.refine_share < 1.0) {
            return invalid("validation.refine_share must be within (0, 1)");
        }
        if !(self.coarse_share > 0.0 && self.coarse_share < 1.0) {
            return invalid("validation.coarse_share must be within (0, 1)");
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The message of the error [`parse`] gives for `text`.
    fn problem<T: for<'de> Deserialize<'de> + Validate + std::fmt::Debug>(text: &str) -> String {
        parse::<T>(text).unwrap_err().to_string()
    }

    #[test]
    fn every_shipped_config_loads() {
        let folder = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs");
        let mut seen = 0;
        for entry in std::fs::read_dir(&folder).unwrap() {
            let path = entry.unwrap().path();
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            if name.ends_with("refine.toml") {
                load::<RefineConfig>(&path).unwrap();
            } else if name.ends_with("coarse.toml") {
                load::<CoarseConfig>(&path).unwrap();
            } else if name == "mover.toml" {
                crate::MoverConfig::load(&path).unwrap();
            } else if name == "optimizer.toml" {
                crate::OptimizerConfig::load(&path).unwrap();
            } else {
                panic!(
                    "{name}: configs/ holds *coarse.toml, *refine.toml, mover.toml and optimizer.toml only"
                );
            }
            seen += 1;
        }
        assert!(seen >= 4, "only {seen} configs in {}", folder.display());
    }

    #[test]
    fn preset_with_overrides() {
        let config: CoarseConfig =
            parse("[model]\npreset = \"paper\"\npaths = 64\n[data]\n[train]\n").unwrap();
        assert_eq!(config.model.0.paths, 64);
        assert_eq!(config.model.0.embed_dim, 384);
        let config: CoarseConfig = parse("[data]\n[train]\n").unwrap();
        assert_eq!(config.model.0, ModelConfig::preset(Preset::Cpu));
        assert_eq!(config.raster.rasterizer, Rasterizer::Soft);
        let config: CoarseConfig = parse("[data]\n[train]\n[raster]\nrasterizer = \"exact\"\n").unwrap();
        assert_eq!(config.raster.rasterizer, Rasterizer::Exact);
    }

    #[test]
    fn unknown_keys_and_bad_values_are_named() {
        let err = problem::<CoarseConfig>("[model]\nembed = 3\n[data]\n[train]\n");
        assert!(err.contains("embed"), "{err}");
        let err = problem::<CoarseConfig>("[data]\nimagez = \"x\"\n[train]\n");
        assert!(err.contains("imagez"), "{err}");
        let err = problem::<CoarseConfig>("[data]\n[train]\nbatch_size = 0\n");
        assert_eq!(err, "train.batch_size must be from 1 to 4096");
        // Absurd sizes are refused by name before anything is allocated.
        for (table, key, name) in [
            ("train", "batch_size = 100000000000", "train.batch_size"),
            ("data", "image_size = 200000", "data.image_size"),
            ("data", "prefetch = 1000000000", "data.prefetch"),
            ("data", "workers = 100000", "data.workers"),
            ("data", "segments = [10, 1000000]", "data.segments"),
            ("data", "compactness = inf", "data.compactness"),
            ("raster", "segments_per_curve = 1000000", "raster.segments_per_curve"),
            ("raster", "subrows = 100000", "raster.subrows"),
            ("model", "paths = 1000000", "model.paths"),
            ("model", "input_size = 65536", "model.input_size"),
            ("validation", "crops = 10000000", "validation.crops"),
        ] {
            let text = match table {
                "data" => format!("[data]\n{key}\n[train]\n"),
                "train" => format!("[data]\n[train]\n{key}\n"),
                _ => format!("[data]\n[train]\n[{table}]\n{key}\n"),
            };
            let err = problem::<CoarseConfig>(&text);
            assert!(err.contains(&format!("{name} must be")), "{key}: {err}");
        }
        let err = problem::<RefineConfig>("[data]\n[train]\n[loss]\nguidance = \"dtw\"\n");
        assert!(err.contains("dtw"), "{err}");
        let err = problem::<CoarseConfig>("[data]\n[train]\n[raster]\nrasterizer = \"fast\"\n");
        assert!(err.contains("fast") && err.contains("exact"), "{err}");
        let err = problem::<CoarseConfig>("[model]\npatch_size = 7\n[data]\n[train]\n");
        assert!(err.contains("model.input_size"), "{err}");
        let err = problem::<CoarseConfig>("[data]\nrecipe = \"watershed\"\n[train]\n");
        assert!(err.contains("watershed") && err.contains("ward"), "{err}");
        let err = problem::<CoarseConfig>("[data]\ncanvas = \"fallback\"\n[train]\n");
        assert!(err.starts_with("data.canvas is E_r's"), "{err}");
        let refine = parse::<RefineConfig>("[data]\ncanvas = \"fallback\"\n[train]\n").unwrap();
        assert_eq!(refine.data.canvas, SampleCanvas::Fallback);
        let err = problem::<RefineConfig>("[data]\n[train]\n[loss]\nteacher = \"optimizer\"\n");
        assert!(err.starts_with("loss.teacher = \"optimizer\" needs data.canvas"), "{err}");
        let taught = "[data]\ncanvas = \"fallback\"\n[train]\n[loss]\nteacher = \"optimizer\"\n";
        assert_eq!(parse::<RefineConfig>(taught).unwrap().loss.teacher, Teacher::Optimizer);
        let err = problem::<RefineConfig>("[data]\n[train]\n[loss]\nreconstruction = \"accepted\"\n");
        assert!(err.starts_with("loss.reconstruction = \"accepted\" needs data.canvas"), "{err}");
        let err = problem::<RefineConfig>("[data]\n[train]\n[loss]\nrefused_weight = 2.0\n");
        assert_eq!(err, "loss.refused_weight must be within [0, 1]");
        let err = problem::<RefineConfig>("[data]\n[train]\n[validation]\nrefine_share = 0.0\n");
        assert_eq!(err, "validation.refine_share must be within (0, 1)");
    }

    #[test]
    fn the_ward_recipe_makes_inferences_regions() {
        let config =
            parse::<CoarseConfig>("[data]\nrecipe = \"ward\"\ncompactness = 20.0\n[train]\n").unwrap();
        assert_eq!(config.data.segment_options(), superpixel::SegmentOptions::ward(20.0));
        let plain = parse::<CoarseConfig>("[data]\noversegment = 3.0\n[train]\n").unwrap();
        assert_eq!(plain.data.recipe, RegionRecipe::Slic, "SLIC unless told");
        assert_eq!(plain.data.segment_options().oversegment, 3.0);
        assert_ne!(plain.data.segment_options(), superpixel::SegmentOptions::ward(30.0));
    }

    #[test]
    fn schedules() {
        let boundary = BoundaryWeight::default();
        assert_eq!(boundary.at(0), 0.045);
        assert!((boundary.at(2500) - 0.035).abs() < 1e-6);
        assert_eq!(boundary.at(1_000_000), 0.01);
        let loss = RefineLoss { guidance_start: 1e-3, guidance_decay_steps: 100, ..Default::default() };
        assert_eq!(loss.guidance_at(0), 1e-3);
        assert!((loss.guidance_at(50) - 5e-4).abs() < 1e-9);
        assert_eq!(loss.guidance_at(200), 0.0);
    }
}
