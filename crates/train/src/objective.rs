//! The losses of the two training stages.

use std::time::Instant;

use burn::module::Module;
use burn::tensor::{Device, Tensor, TensorData};
use dpw::{PathDistance, boundary_loss_of_union, dpw, multiscale_masked_l2, path_efficiency_loss};
use model::{CoarseModel, CropBatch, InputSpec, PathOptimizer, RefineModel, Stage};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use raster::{ExactBatch, PARAMS, PathBatch, SoftRasterOptions, Window, paint_soft, paint_soft_with_union};
use rayon::prelude::*;

use crate::config::{
    Canvas, CoarseConfig, CoarseLoss, Guidance, PathColours, Rasterizer, Reconstruction, RefineConfig,
    RefineLoss, Teacher,
};
use crate::data::Samples;
use crate::inference::{AtInference, CoarseCheck, RefineCheck};
use crate::teacher::teach;

/// What one step computed: the total to minimize, the terms to report, and what to preview.
pub struct StepOutput {
    /// The weighted sum of the terms.
    pub total: Tensor<1>,
    /// Each term before weighting, by name, and figures reported beside them (E_r's
    /// `removed` and `teacher_removed`), for logs and NaN reports.
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
/// it (each path's least-squares colour over what lies below it), not in E_r's own. With
/// `loss.teacher = "optimizer"` the guidance ties S' to the paths the exact optimizer places on
/// that canvas ([`model::PathOptimizer`]) instead of to S₂.
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
        let [batch, _] = coarse.dims();
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
        // What the guidance pulls towards: E_c's paths after the split, or the optimizer's.
        let (guide, split) = match self.loss.teacher {
            Teacher::Coarse => (coarse, split),
            Teacher::Optimizer => {
                let optimizer = PathOptimizer { paths: model.refine_paths(), steps: self.loss.teacher_steps };
                let taught = teach(optimizer, &canvas, &scored.pixels);
                laps.lap("teacher");
                let split = Split::guide_only(&taught);
                (taught, split)
            }
        };
        // On inference's drawing, how much of each box's error E_r's paths take away, and
        // the optimizer's where it teaches: the gap between the two is what E_r has to learn.
        let mut shares = Vec::new();
        if samples.drawn.is_some() {
            let removed = |paths: &PathBatch| {
                let render = ExactBatch::paint(&canvas, paths).render(&device);
                removed_share(&canvas, &render, &scored.pixels)
            };
            shares.push(("removed", removed(&scored_paths.detach())));
            if self.loss.teacher == Teacher::Optimizer {
                shares.push(("teacher_removed", removed(&guide)));
            }
            laps.lap("rasterizer");
        }
        let accepted = (self.loss.reconstruction == Reconstruction::Accepted).then(|| {
            let gain = accepted_gain(
                &canvas,
                &added,
                &scored,
                self.loss.colours,
                self.loss.refused_weight,
                self.rasterizer,
                &self.raster,
            );
            laps.lap("rasterizer");
            gain
        });
        let terms = ImageTerms { l2_levels: self.loss.l2_levels, dilation: self.loss.boundary.dilation };
        let (render, l2, bound) =
            terms.of(canvas, &scored_paths, &scored, self.rasterizer, &self.raster, &mut laps);
        // With the acceptance test as the image term, the joint L2 is only reported.
        let (image, mut terms) = match accepted {
            Some(gain) => (gain.clone().neg(), vec![("l2", l2), ("accepted_gain", gain)]),
            None => (l2.clone(), vec![("l2", l2)]),
        };

        let [_, count] = guide.dims();
        let distance = PathDistance { coords: self.loss.distance_coords, color: self.loss.distance_color };
        let distances = distance.between(&added, &guide); // [B, m, n]
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
        let total = image + guidance.clone() * guidance_weight + bound.clone() * bound_weight;
        terms.extend([("guidance", guidance), ("bound", bound)]);
        terms.extend(shares);
        StepOutput {
            total,
            terms,
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

/// Inference's acceptance test as a loss term: each of `paths` (`[B, m]`) painted alone over
/// `canvas` (`[B, 3, S, S]`), in its fitted colour where `colours` says so, and the squared
/// error it takes away from the box against `crops` (a mean over the box's values) summed over
/// the paths that take some away, a mean over samples (`[1]`). A path that would be refused
/// adds what it adds to the error times `refused` (0: nothing and no gradient, as at inference;
/// above 0, a pull towards where it would be kept); to be maximized.
fn accepted_gain(
    canvas: &Tensor<4>,
    paths: &PathBatch,
    crops: &CropBatch,
    colours: PathColours,
    refused: f32,
    rasterizer: Rasterizer,
    options: &SoftRasterOptions,
) -> Tensor<1> {
    let [batch, m] = paths.dims();
    let [_, _, size, _] = canvas.dims();
    let device = paths.device();
    // Every path a sample of its own, over its sample's canvas and image.
    let each = |tensor: &Tensor<4>, channels: usize| {
        tensor.clone().unsqueeze_dim::<5>(1).expand([batch, m, channels, size, size]).reshape([
            batch * m,
            channels,
            size,
            size,
        ])
    };
    let (canvases, alone) =
        (each(canvas, 3), CropBatch { pixels: each(&crops.pixels, 3), masks: each(&crops.masks, 1) });
    let single = PathBatch::new(paths.params().clone().reshape([batch * m, 1, PARAMS]));
    let single = match colours {
        PathColours::Predicted => single,
        PathColours::Fitted => with_fitted_colours(&canvases, &single, &alone),
    };
    let error = |drawing: Tensor<4>| {
        (drawing - alone.pixels.clone()).square().reshape([batch * m, 3 * size * size]).mean_dim(1)
    };
    let before = error(canvases.clone()).detach();
    let gain = |render: Tensor<4>| {
        let each = before.clone() - error(render);
        (each.clone().clamp_min(0.0) + each.clamp_max(0.0) * refused).sum() / batch as f32
    };
    match rasterizer {
        Rasterizer::Soft => gain(paint_soft(canvases, &single, options)),
        Rasterizer::Exact => {
            let exact = ExactBatch::paint(&canvases, &single);
            let render = exact.render(&device).require_grad();
            let value = gain(render.clone());
            let by_render = render.grad(&value.clone().backward());
            let gradient = exact.gradient(by_render.as_ref(), None, &device).reshape([batch, m, PARAMS]);
            // Worth nothing, and differentiates to the gradient (as `ImageTerms::of` carries it).
            let inner = (single.params().clone().reshape([batch, m, PARAMS]) * gradient).sum();
            value.detach() + (inner.clone() - inner.detach())
        }
    }
}

/// The share of the squared error of `canvas` against `target` (`[B, 3, S, S]`) that `render`
/// takes away, the mean over samples (`[1]`, not differentiated): 1 where it draws the image,
/// 0 where it changes nothing, below 0 where it makes it worse. Reported, not minimized.
fn removed_share(canvas: &Tensor<4>, render: &Tensor<4>, target: &Tensor<4>) -> Tensor<1> {
    let [batch, channels, height, width] = canvas.dims();
    let error = |drawing: &Tensor<4>| {
        (drawing.clone().detach() - target.clone())
            .square()
            .reshape([batch, channels * height * width])
            .sum_dim(1)
    };
    let (before, after) = (error(canvas), error(render));
    (after / before.clamp_min(1e-12)).neg().add_scalar(1.0).mean()
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

#[cfg(test)]
mod tests {
    use burn::tensor::Device;
    use raster::Path;

    use super::*;

    /// The acceptance term counts what each path alone takes away from the box: a path that
    /// makes the box worse adds nothing and gets no gradient, one that helps adds its gain (on
    /// both rasterizers, in its own colour or the fitted one); with a weight on refused paths,
    /// the one that hurts costs that share of its harm and is pulled towards helping.
    #[test]
    fn accepted_gain_counts_only_the_paths_that_help() {
        let device = Device::flex().autodiff();
        let size = 16;
        let canvas = Tensor::<4>::full([1, 3, size, size], 0.5, &device);
        // The image: the grey with a red square where the first path lies.
        let square = |x: f32, y: f32, color| {
            Path::quadrilateral([[x, y], [x + 0.25, y], [x + 0.25, y + 0.25], [x, y + 0.25]], color, 1.0)
        };
        let helps = square(0.25, 0.25, [0.9, 0.1, 0.1]);
        let hurts = square(0.625, 0.625, [0.0, 0.0, 1.0]);
        let pixels = raster::Window::new(
            size as u32,
            size as u32,
            vec![0.5; 3 * size * size],
            vec![0.5; 3 * size * size],
        )
        .unwrap()
        .render(&[Path { color: [1.0, 0.0, 0.0], ..helps }]);
        let target = Tensor::<4>::from_data(TensorData::new(pixels, [1, 3, size, size]), &device);
        let crops = CropBatch { pixels: target.clone(), masks: Tensor::ones([1, 1, size, size], &device) };
        let options = SoftRasterOptions::default();
        for rasterizer in [Rasterizer::Exact, Rasterizer::Soft] {
            let gain = |paths: &PathBatch, colours, refused| {
                accepted_gain(&canvas, paths, &crops, colours, refused, rasterizer, &options)
            };
            let alone = |scene: Vec<Path>, refused| {
                gain(&PathBatch::from_scenes(&[scene], &device), PathColours::Predicted, refused)
                    .into_scalar::<f32>()
            };
            let params = PathBatch::from_scenes(&[vec![helps, hurts]], &device).into_params().require_grad();
            let paths = PathBatch::new(params.clone());
            let both = gain(&paths, PathColours::Predicted, 0.0);
            let first = alone(vec![helps], 0.0);
            assert!(
                first > 0.0 && (both.clone().into_scalar::<f32>() - first).abs() < 1e-6 * first.max(1.0),
                "{rasterizer:?}"
            );
            assert_eq!(alone(vec![hurts], 0.0), 0.0);
            let gradient: Vec<f32> = params.grad(&both.backward()).unwrap().try_to_vec_as().unwrap();
            assert!(gradient[..PARAMS].iter().any(|g| *g != 0.0), "{rasterizer:?}: the helpful path moves");
            assert!(gradient[PARAMS..].iter().all(|g| *g == 0.0), "{rasterizer:?}: the refused one does not");
            // Weighted: the refused path costs a tenth of its harm, and moves.
            let harm = alone(vec![hurts], 1.0);
            assert!(harm < 0.0 && (alone(vec![hurts], 0.1) - 0.1 * harm).abs() < 1e-6, "{rasterizer:?}");
            let weighted = gain(&paths, PathColours::Predicted, 0.1);
            let gradient: Vec<f32> = params.grad(&weighted.backward()).unwrap().try_to_vec_as().unwrap();
            assert!(
                gradient[PARAMS..].iter().any(|g| *g != 0.0),
                "{rasterizer:?}: the weighted refused path moves"
            );
            // Fitted: the helpful path in the image's red takes away more than in its own.
            let fitted = gain(&paths, PathColours::Fitted, 0.0);
            assert!(fitted.into_scalar::<f32>() > first, "{rasterizer:?}");
        }
    }
}
