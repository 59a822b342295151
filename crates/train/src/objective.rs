//! The losses of the two training stages.

use std::time::Instant;

use burn::module::Module;
use burn::tensor::{Device, Tensor, TensorData};
use dpw::{PathDistance, boundary_loss_of_union, dpw, multiscale_masked_l2, path_efficiency_loss};
use model::{CoarseModel, CropBatch, InputSpec, RefineModel, Stage};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use raster::{ExactBatch, PathBatch, SoftRasterOptions, Window, paint_soft, paint_soft_with_union};
use rayon::prelude::*;

use crate::config::{
    Canvas, CoarseConfig, CoarseLoss, Guidance, PathColours, Rasterizer, RefineConfig, RefineLoss,
};
use crate::data::Samples;
use crate::inference::{AtInference, CoarseCheck, RefineCheck};

/// What one step computed: the total to minimize, the terms to report, and what to preview.
pub struct StepOutput {
    /// The weighted sum of the terms.
    pub total: Tensor<1>,
    /// Each term before weighting, and each weight, by name (for logs and NaN reports).
    pub terms: Vec<(&'static str, Tensor<1>)>,
    /// The weights the terms were given at this step.
    pub weights: Vec<(&'static str, f32)>,
    /// The soft render the reconstruction loss compared with the target, `[B, 3, S, S]`.
    pub render: Tensor<4>,
    /// Every path drawn in that render, in painter's order.
    pub paths: PathBatch,
    /// Wall seconds of the step's phases (`model`, `rasterizer`, `losses`), for benchmarks
    /// and logs.
    pub phases: Vec<(&'static str, f64)>,
}

/// Wall-clock laps of a step's phases.
struct Laps {
    clock: Instant,
    phases: Vec<(&'static str, f64)>,
}

impl Laps {
    fn start() -> Self {
        Self { clock: Instant::now(), phases: Vec::new() }
    }

    /// Ends phase `name` (adding to it if it ran before) and starts the next.
    fn lap(&mut self, name: &'static str) {
        let seconds = self.clock.elapsed().as_secs_f64();
        match self.phases.iter_mut().find(|(phase, _)| *phase == name) {
            Some((_, total)) => *total += seconds,
            None => self.phases.push((name, seconds)),
        }
        self.clock = Instant::now();
    }
}

/// A training stage: its network and its objective.
pub trait Objective {
    /// The network trained.
    type Model: Module;
    /// Which checkpoint stage it writes.
    const STAGE: Stage;
    /// Losses of `model` on a batch of samples at `step`.
    fn step(&self, model: &Self::Model, samples: &Samples, step: usize) -> StepOutput;
    /// What `model` draws on `crops` at inference, where each region starts as its mean colour
    /// (paths in the crops' unit squares, with their opacity).
    fn draw(&self, model: &Self::Model, crops: &CropBatch) -> PathBatch;
    /// The soft rasterizer's options: the losses' when they read it, and the previews' soft column.
    fn raster(&self) -> &SoftRasterOptions;
    /// `model` (on `device`) scored the way inference uses it, where the objective holds such a
    /// check ([`CoarseCheck`], [`RefineCheck`]).
    fn score_at_inference(&self, model: &Self::Model, device: &Device) -> Option<AtInference>;
}

/// The coarse objective: `L2 + λ_bound·L_bound + λ_PE·L_PE`, the paths drawn over the
/// background or over each region's mean colour (`loss.canvas`).
pub struct CoarseObjective {
    /// Loss weights and schedules.
    pub loss: CoarseLoss,
    /// The soft rasterizer's options (its background is the exact one's too).
    pub raster: SoftRasterOptions,
    /// Which rasterizer the losses read.
    pub rasterizer: Rasterizer,
    /// E_c at inference on the validation images, scored with the crops when there are some.
    pub check: Option<CoarseCheck>,
}

impl CoarseObjective {
    /// The objective `config`'s `[loss]` and `[raster]` tables describe.
    pub fn new(config: &CoarseConfig) -> Self {
        Self {
            loss: config.loss.clone(),
            raster: config.raster.options(),
            rasterizer: config.raster.rasterizer,
            check: None,
        }
    }
}

impl Objective for CoarseObjective {
    type Model = CoarseModel;
    const STAGE: Stage = Stage::Coarse;

    fn draw(&self, model: &CoarseModel, crops: &CropBatch) -> PathBatch {
        model.forward(crops.pixels.clone())
    }

    fn raster(&self) -> &SoftRasterOptions {
        &self.raster
    }

    fn score_at_inference(&self, model: &CoarseModel, device: &Device) -> Option<AtInference> {
        self.check.as_ref().map(|check| AtInference::Coarse(check.score(model, device)))
    }

    fn step(&self, model: &CoarseModel, samples: &Samples, step: usize) -> StepOutput {
        let crops = &samples.crops;
        let pixels = crops.pixels.clone();
        let [_, _, size, _] = pixels.dims();
        let mut laps = Laps::start();
        let paths = model.forward(pixels.clone());
        laps.lap("model");
        let canvas = match self.loss.canvas {
            Canvas::Background => self.raster.background_canvas(&paths, size, size),
            Canvas::MeanColour => {
                let [batch, _] = paths.dims();
                crops.mean_colours().expand([batch, 3, size, size])
            }
        };
        let terms = ImageTerms { l2_levels: self.loss.l2_levels, dilation: self.loss.boundary.dilation };
        let (render, l2, bound) = terms.of(canvas, &paths, crops, self.rasterizer, &self.raster, &mut laps);
        let efficiency = path_efficiency_loss(paths.alpha());
        let (bound_weight, efficiency_weight) = (self.loss.boundary.at(step), self.loss.path_efficiency);
        let total = l2.clone() + bound.clone() * bound_weight + efficiency.clone() * efficiency_weight;
        StepOutput {
            total,
            terms: vec![("l2", l2), ("bound", bound), ("visible_paths", efficiency)],
            weights: vec![("lambda_bound", bound_weight), ("lambda_pe", efficiency_weight)],
            render,
            paths,
            phases: {
                laps.lap("losses");
                laps.phases
            },
        }
    }
}

/// The coarse-paths-guided refinement objective:
/// `L2(x, R([S₁, S'])) + λ_guide·G(S₂, S') + λ_bound·L_bound(S')`.
///
/// The frozen coarse model predicts S; its visible paths are split at a random k (leaving at
/// least m after the split when there are that many); S₁ = the first k is rendered over the
/// region's mean colour as the canvas (inference draws every region with its mean colour before
/// anything else), E_r reads that canvas masked by the input contract and adds S' over it, and
/// the guidance G ties S' to S₂ = the visible paths after the split.
///
/// Samples that carry the drawing inference hands E_r (`data.canvas = "fallback"`) use it
/// instead: that drawing is the canvas (S₁ is empty, S₂ every visible coarse path), and the L2
/// is taken over the whole box against the image, which is what inference's acceptance test
/// measures; nothing lies outside that mask, so the boundary term is 0.
///
/// With `loss.colours = "fitted"` the image terms score S' in the colours inference would give
/// it (each path's least-squares colour over what lies below it), not in E_r's own.
pub struct RefineObjective {
    /// The trained coarse model (frozen).
    pub teacher: CoarseModel,
    /// The input contract of the models (from the coarse checkpoint).
    pub input: InputSpec,
    /// Loss weights, schedules and guidance.
    pub loss: RefineLoss,
    /// The soft rasterizer's options.
    pub raster: SoftRasterOptions,
    /// Which rasterizer the losses (and the canvas of S₁) read.
    pub rasterizer: Rasterizer,
    /// Seed of the split points.
    pub seed: u64,
    /// E_r at inference on the validation images, scored with the crops when there are some.
    pub check: Option<RefineCheck>,
}

impl RefineObjective {
    /// The objective of `config` for a student of `teacher` (frozen here), whose input
    /// contract is `input`.
    pub fn new(config: &RefineConfig, teacher: CoarseModel, input: InputSpec) -> Self {
        Self {
            teacher: teacher.freeze(),
            input,
            loss: config.loss.clone(),
            raster: config.raster.options(),
            rasterizer: config.raster.rasterizer,
            seed: config.train.seed,
            check: None,
        }
    }
}

impl Objective for RefineObjective {
    type Model = RefineModel;
    const STAGE: Stage = Stage::Refine;

    fn draw(&self, model: &RefineModel, crops: &CropBatch) -> PathBatch {
        let [batch, _, size, _] = crops.pixels.dims();
        let flat = crops.mean_colours().expand([batch, 3, size, size]);
        model.forward(crops.pixels.clone(), crops.masked_canvas(flat, &self.input))
    }

    fn raster(&self) -> &SoftRasterOptions {
        &self.raster
    }

    fn score_at_inference(&self, model: &RefineModel, device: &Device) -> Option<AtInference> {
        self.check.as_ref().map(|check| AtInference::Refine(check.score(model, device)))
    }

    fn step(&self, model: &RefineModel, samples: &Samples, step: usize) -> StepOutput {
        let crops = &samples.crops;
        let pixels = crops.pixels.clone();
        let [_, _, size, _] = pixels.dims();
        let device = pixels.device();
        let mut laps = Laps::start();
        let coarse = self.teacher.forward(pixels.clone()).detach();
        laps.lap("teacher");
        let [batch, count] = coarse.dims();
        let split = match samples.drawn {
            Some(_) => Split::guide_only(&coarse),
            None => Split::draw(&coarse, model.refine_paths(), self.seed, step),
        };

        let first = coarse.with_alpha(split.first_part(&device));
        let (canvas, scored) = match &samples.drawn {
            Some(drawn) => {
                let whole = Tensor::ones([batch, 1, size, size], &device);
                (drawn.canvas.clone(), CropBatch { pixels: drawn.target.clone(), masks: whole })
            }
            None => {
                let flat = crops.mean_colours().expand([batch, 3, size, size]);
                let canvas = match self.rasterizer {
                    Rasterizer::Soft => paint_soft(flat, &first, &self.raster).detach(),
                    Rasterizer::Exact => ExactBatch::paint(&flat, &first).render(&device),
                };
                (canvas, crops.clone())
            }
        };
        laps.lap("rasterizer");
        let added = model.forward(pixels.clone(), crops.masked_canvas(canvas.clone(), &self.input));
        laps.lap("model");
        let scored_paths = match self.loss.colours {
            PathColours::Predicted => added.clone(),
            PathColours::Fitted => {
                let fitted = with_fitted_colours(&canvas, &added, &scored);
                laps.lap("rasterizer");
                fitted
            }
        };
        let terms = ImageTerms { l2_levels: self.loss.l2_levels, dilation: self.loss.boundary.dilation };
        let (render, l2, bound) =
            terms.of(canvas, &scored_paths, &scored, self.rasterizer, &self.raster, &mut laps);

        let distance = PathDistance { coords: self.loss.distance_coords, color: self.loss.distance_color };
        let distances = distance.between(&added, &coarse); // [B, m, n]
        let guidance = match self.loss.guidance {
            Guidance::Dpw => {
                let m = model.refine_paths();
                let allowed =
                    split.second_part(&device).reshape([batch, 1, count]).bool().expand([batch, m, count]);
                let masked = distances.mask_fill(allowed.bool_not(), f32::INFINITY);
                // A sample whose teacher drew nothing visible has no target: every alignment is
                // impossible, so it is left out of the mean instead of adding a huge constant.
                let has_targets = split.has_targets(&device);
                (dpw(masked, self.loss.gamma) * has_targets.clone()).sum() / has_targets.sum().clamp_min(1.0)
            }
            Guidance::L2 => {
                let pairs = split.in_order_pairs(model.refine_paths(), &device);
                (distances * pairs.clone()).sum() / pairs.sum().clamp_min(1.0)
            }
            Guidance::None => Tensor::zeros([1], &device),
        };
        let (guidance_weight, bound_weight) = (self.loss.guidance_at(step), self.loss.boundary.at(step));
        let total = l2.clone() + guidance.clone() * guidance_weight + bound.clone() * bound_weight;
        StepOutput {
            total,
            terms: vec![("l2", l2), ("guidance", guidance), ("bound", bound)],
            weights: vec![("lambda_guidance", guidance_weight), ("lambda_bound", bound_weight)],
            render,
            paths: first.then(&scored_paths),
            phases: {
                laps.lap("losses");
                laps.phases
            },
        }
    }
}

/// `paths` (`[B, P]`) in the colours that fit `crops` best over `canvas` (`[B, 3, S, S]`), each
/// sample's masked pixels weighed alone ([`Window::fit_colours`]); the colours are constants, so
/// the image terms of the result differentiate to the shapes and opacities alone.
fn with_fitted_colours(canvas: &Tensor<4>, paths: &PathBatch, crops: &CropBatch) -> PathBatch {
    let [batch, _, height, width] = canvas.dims();
    let [_, count] = paths.dims();
    let read = |tensor: &Tensor<4>| -> Vec<f32> { tensor.try_to_vec_as().expect("crops are readable") };
    let (canvas, target, masks) = (read(canvas), read(&crops.pixels), read(&crops.masks));
    let (pixels, scenes) = (height * width, paths.to_scenes());
    let colours: Vec<f32> = scenes
        .par_iter()
        .enumerate()
        .flat_map_iter(|(b, scene)| {
            let planes = 3 * pixels * b..3 * pixels * (b + 1);
            let window = Window::new(
                width as u32,
                height as u32,
                canvas[planes.clone()].to_vec(),
                target[planes].to_vec(),
            )
            .expect("a canvas and a target of 3 × S × S values");
            window
                .fit_colours(scene, Some(&masks[pixels * b..pixels * (b + 1)]))
                .into_iter()
                .flat_map(|p| p.color)
        })
        .collect();
    paths.with_colors(Tensor::from_data(TensorData::new(colours, [batch, count, 3]), &paths.device()))
}

/// The terms of a loss that read the picture: the multi-scale masked L2 of the render and the
/// boundary loss of the paths' union.
struct ImageTerms {
    /// Scales of the L2.
    l2_levels: usize,
    /// Dilation of the masks in the boundary loss.
    dilation: usize,
}

impl ImageTerms {
    /// `paths` painted over `canvas` (`[B, 3, S, S]`, not differentiated) by `rasterizer`:
    /// the render `[B, 3, S, S]`, then the L2 against `crops` and the boundary term, both
    /// differentiable with respect to the paths. Laps `rasterizer` and `losses`.
    ///
    /// The exact rasterizer's gradient comes from [`ExactBatch::gradient`]: the terms are
    /// computed by burn on the exact render and union as leaves, their derivatives by those
    /// leaves pulled back to the paths' parameters on the CPU, and each term returned as its
    /// value plus `Σ params · gradient − (the same, detached)`, which is worth nothing and
    /// differentiates to that gradient.
    fn of(
        &self,
        canvas: Tensor<4>,
        paths: &PathBatch,
        crops: &CropBatch,
        rasterizer: Rasterizer,
        options: &SoftRasterOptions,
        laps: &mut Laps,
    ) -> (Tensor<4>, Tensor<1>, Tensor<1>) {
        let (pixels, masks) = (crops.pixels.clone(), crops.masks.clone());
        let losses = |render: Tensor<4>, union: Tensor<4>| {
            let l2 = multiscale_masked_l2(render, pixels.clone(), masks.clone(), self.l2_levels);
            (l2, boundary_loss_of_union(union, masks.clone(), self.dilation))
        };
        match rasterizer {
            Rasterizer::Soft => {
                let (render, union) = paint_soft_with_union(canvas, paths, options);
                laps.lap("rasterizer");
                let (l2, bound) = losses(render.clone(), union);
                laps.lap("losses");
                (render, l2, bound)
            }
            Rasterizer::Exact => {
                let device = paths.device();
                let exact = ExactBatch::paint(&canvas, paths);
                let (render, union) =
                    (exact.render(&device).require_grad(), exact.union(&device).require_grad());
                laps.lap("rasterizer");
                let (l2, bound) = losses(render.clone(), union.clone());
                // l2 reads only the render and the boundary term only the union: one backward
                // pass gives each term's derivatives.
                let grads = (l2.clone() + bound.clone()).backward();
                let (by_render, by_union) = (render.grad(&grads), union.grad(&grads));
                laps.lap("losses");
                let carry = |value: Tensor<1>, gradient: Tensor<3>| {
                    let inner = (paths.params().clone() * gradient).sum();
                    value.detach() + (inner.clone() - inner.detach())
                };
                let l2 = carry(l2, exact.gradient(by_render.as_ref(), None, &device));
                let bound = carry(bound, exact.gradient(None, by_union.as_ref(), &device));
                laps.lap("rasterizer");
                (render.detach(), l2, bound)
            }
        }
    }
}

/// Where each sample's visible coarse paths are split into S₁ (canvas) and S₂ (guidance).
struct Split {
    /// `[B][n]`: whether the path is visible.
    visible: Vec<Vec<bool>>,
    /// `[B]`: how many visible paths go to the canvas.
    k: Vec<usize>,
}

impl Split {
    /// Draws k for every sample, uniformly among the splits that leave at least `m` visible
    /// paths after the split (k = 0 when there are fewer than m).
    fn draw(coarse: &PathBatch, m: usize, seed: u64, step: usize) -> Self {
        let Self { visible, .. } = Self::guide_only(coarse);
        // A seed of its own, so splits are not correlated with the data stream of the same step.
        let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_add(0x9e37_79b9_7f4a_7c15));
        rng.set_stream(step as u64);
        let k = visible
            .iter()
            .map(|row| {
                let shown = row.iter().filter(|&&v| v).count();
                rng.random_range(0..=shown.saturating_sub(m))
            })
            .collect();
        Self { visible, k }
    }

    /// The split with k = 0 for every sample: nothing to the canvas, every visible path to
    /// the guidance (when the canvas is a drawing of its own).
    fn guide_only(coarse: &PathBatch) -> Self {
        let [batch, count] = coarse.dims();
        let alpha: Vec<f32> = coarse.alpha().try_to_vec_as().expect("visibility is readable");
        let visible = alpha
            .chunks(count.max(1))
            .take(batch)
            .map(|row| row.iter().map(|&a| a > raster::VISIBLE_ALPHA).collect())
            .collect();
        Self { visible, k: vec![0; batch] }
    }

    /// `[B, n, 1]`: 1 for the first k visible paths of each sample.
    fn first_part(&self, device: &Device) -> Tensor<3> {
        self.indicator(device, |rank, k| rank < k)
    }

    /// `[B, n]` flattened as `[B, n, 1]`: 1 for the visible paths after the split.
    fn second_part(&self, device: &Device) -> Tensor<3> {
        self.indicator(device, |rank, k| rank >= k)
    }

    /// `[B]`: 1 for samples with at least one visible path after the split.
    fn has_targets(&self, device: &Device) -> Tensor<1> {
        let values: Vec<f32> =
            self.visible.iter().map(|row| if row.iter().any(|&v| v) { 1.0 } else { 0.0 }).collect();
        let batch = values.len();
        Tensor::from_data(TensorData::new(values, [batch]), device)
    }

    /// `[B, m, n]`: 1 where prediction i faces the i-th visible path after the split.
    fn in_order_pairs(&self, m: usize, device: &Device) -> Tensor<3> {
        let (batch, count) = (self.visible.len(), self.visible.first().map_or(0, Vec::len));
        let mut pairs = vec![0.0f32; batch * m * count];
        for (b, row) in self.visible.iter().enumerate() {
            let after: Vec<usize> =
                row.iter().enumerate().filter(|(_, v)| **v).map(|(j, _)| j).skip(self.k[b]).collect();
            for (i, &j) in after.iter().take(m).enumerate() {
                pairs[(b * m + i) * count + j] = 1.0;
            }
        }
        Tensor::from_data(TensorData::new(pairs, [batch, m, count]), device)
    }

    /// `[B, n, 1]` indicator of visible paths whose rank among the visible ones satisfies `keep`.
    fn indicator(&self, device: &Device, keep: impl Fn(usize, usize) -> bool) -> Tensor<3> {
        let (batch, count) = (self.visible.len(), self.visible.first().map_or(0, Vec::len));
        let mut values = Vec::with_capacity(batch * count);
        for (b, row) in self.visible.iter().enumerate() {
            let mut rank = 0;
            for &visible in row {
                values.push(if visible && keep(rank, self.k[b]) { 1.0 } else { 0.0 });
                rank += usize::from(visible);
            }
        }
        Tensor::from_data(TensorData::new(values, [batch, count, 1]), device)
    }
}
