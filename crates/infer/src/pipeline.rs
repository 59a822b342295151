//! The whole image → SVG job as one call, [`run`]: what `infer`, `eval`, `tune` and any other
//! front end use, so that every figure they print is what a user of `infer` gets.
//!
//! SuperSVG-B is stages over one [`Scene`]: segment (the image's merge tree, cut at the
//! budget's regions) → coarse (background, fallbacks, E_c) → refine (E_r); the mover (E_m)
//! then moves what B drew, where the job says ([`Moves`]); SuperSVG-F
//! fine-tunes the scene it is handed ([`Outcome::finetuned`]); export writes the SVG from the
//! scene and measures its canvas, which is never rendered again.

use std::ops::ControlFlow;
use std::sync::Arc;
use web_time::Instant;

use burn::tensor::Device;
use common::Loaded;
use model::PathOptimizer;
use raster::{Decimals, Shape, to_svg_with};
use serde::Serialize;

use crate::budget::{BudgetPlan, Market};
use crate::coarse::draw_coarse;
use crate::fills::Ramps;
use crate::finetune::{FinetuneOptions, Learned, Progress, finetune_with_progress};
use crate::job::{InvalidJob, Job, Moves, PathBudget, Refiner, Split, VectorizeError, Warning};
use crate::models::{Context, Models};
use crate::mover::{MoveTally, move_outlines};
use crate::paper::draw_paper;
use crate::refine::{Proposer, RefineTally, draw_refinement};
use crate::scene::{Scene, StageCounts};
use crate::segmentation::Segmented;

/// Seconds per stage of one job.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Seconds {
    /// Reading the file and scaling it to the working size.
    pub decode: f64,
    /// Segmenting (and, for an automatic budget, choosing it).
    pub superpixels: f64,
    /// Background, fallbacks and E_c.
    pub coarse: f64,
    /// E_r.
    pub refine: f64,
    /// The mover, E_m: its pass, and scoring and writing the moved outlines.
    pub moves: f64,
    /// Of `coarse`, `refine` and `moves`, the networks' forward passes (cropping their regions
    /// or reading their profiles, and reading out their paths or moves, included): what the
    /// method's networks cost beside the rest.
    pub networks: f64,
    /// SuperSVG-F, when asked for.
    pub finetune: Option<f64>,
    /// Writing the SVG and measuring the drawing.
    pub export: f64,
    /// Everything.
    pub total: f64,
}

/// What a job made and how well it draws: the schema of `infer --metrics`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Report {
    /// Width of the input, which the SVG keeps.
    pub width: u32,
    /// Height of the input.
    pub height: u32,
    /// Width of the working image.
    pub working_width: u32,
    /// Height of the working image.
    pub working_height: u32,
    /// The path budget drawn with (what an automatic budget chose).
    pub budget: usize,
    /// Whether the budget was chosen automatically.
    pub auto_budget: bool,
    /// Paths in the SVG.
    pub paths: usize,
    /// Paths per stage.
    pub paths_by_stage: StageCounts,
    /// Superpixels.
    pub regions: usize,
    /// How the budget was split (an operating point, or `"paper"`).
    pub operating_point: Split,
    /// What E_r proposed, kept and gained (SuperSVG-B's; fine-tuning leaves it as it was).
    pub refinement: RefineTally,
    /// What the mover moved and gained, when it ran.
    pub moves: Option<MoveTally>,
    /// Mean squared error of the drawing at the working size (RGB in [0, 1]).
    pub mse: f64,
    /// Its PSNR (dB).
    pub psnr: f64,
    /// Its SSIM ([`common::ssim`]), when the job asked for it ([`Job::ssim`]).
    pub ssim: Option<f64>,
    /// Fine-tuning steps taken (SuperSVG-F only).
    pub finetune_steps: Option<usize>,
    /// Size of the SVG.
    pub svg_bytes: usize,
    /// Seconds per stage.
    pub seconds: Seconds,
}

/// A job's result: the drawing, its SVG, and the report.
#[derive(Clone)]
pub struct Outcome {
    /// The drawing: paths with their regions and stages, and its exact rendering, at full
    /// precision (what SuperSVG-F goes on from).
    pub scene: Scene,
    /// The drawing as the SVG writes it (its decimals, 8-bit colours: [`Shape::as_written`]),
    /// and its exact rendering: what the report measures and previews show.
    pub written: Scene,
    /// The SVG document, at the input's size, one group per region.
    pub svg: String,
    /// What was made and how well it draws.
    pub report: Report,
    /// What was done differently from what the job asked.
    pub warnings: Vec<Warning>,
}

/// Draws `image` as `job` says with `models` on `device`: SuperSVG-B, then SuperSVG-F if the job
/// asks for it.
pub fn run(models: &Models, image: &Loaded, job: &Job, device: &Device) -> Result<Outcome, VectorizeError> {
    run_with_progress(models, image, job, device, &mut |_| ControlFlow::Continue(()))
}

/// [`run`], calling `on_step` after every fine-tuning step (a progress bar; breaking stops the
/// fine-tuning with the best drawing so far).
pub fn run_with_progress(
    models: &Models,
    image: &Loaded,
    job: &Job,
    device: &Device,
    on_step: &mut dyn FnMut(&Progress) -> ControlFlow<()>,
) -> Result<Outcome, VectorizeError> {
    job.validate()?;
    let context = Context { config: &models.config, batch: job.batch, device };
    if job.operating_point == Split::Paper {
        return run_paper(models, &context, image, job, on_step);
    }
    let started = Instant::now();
    let (plan, tree, warnings) = BudgetPlan::new(job, models, &image.image)?;
    // The stages share one copy of the image and of its regions.
    let target = Arc::new(image.image.clone());
    let Segmented { hierarchy, segmentation, fallback } =
        Segmented::new(&target, tree, plan.regions, plan.style);
    let market = plan.traded.then(|| Market::for_drawing(&hierarchy, &segmentation, &fallback, plan.style));
    let mut scene = Scene::new(target, segmentation);
    let superpixels = started.elapsed().as_secs_f64();

    let clock = Instant::now();
    let coarse_network = draw_coarse(&models.coarse, &context, &mut scene, fallback, plan.coarse(market))?;
    let coarse = clock.elapsed().as_secs_f64();

    let clock = Instant::now();
    let proposer = match job.refiner {
        Refiner::Network => models.refine.as_ref().map(Proposer::Network),
        Refiner::Optimizer { steps } => {
            Some(Proposer::Optimizer(PathOptimizer { paths: models.config.refine_paths, steps }))
        }
    };
    let refinement = match proposer {
        Some(proposer) => draw_refinement(&context, proposer, &mut scene, plan.paths, market)?,
        None => RefineTally::default(),
    };
    let refine = clock.elapsed().as_secs_f64();

    let clock = Instant::now();
    let runs = match job.moves {
        Moves::Auto => plan.style.ramps != Ramps::None,
        Moves::On => true,
        Moves::Off => false,
    };
    let moved = match &models.mover {
        Some(network) if runs => Some(move_outlines(&network.network, &mut scene, image.original, device)),
        _ => None,
    };
    let moves = clock.elapsed().as_secs_f64();

    let networks =
        coarse_network + refinement.network_seconds + moved.map_or(0.0, |tally| tally.network_seconds);
    let seconds =
        Seconds { decode: image.seconds, superpixels, coarse, refine, moves, networks, ..Seconds::default() };
    let drawn = Drawn {
        auto_budget: plan.auto,
        budget: plan.paths,
        point: Split::Point(plan.point),
        refinement,
        moves: moved,
        seconds,
    };
    finish(scene, image, job, drawn, warnings, (models, device), on_step)
}

/// [`run_with_progress`] at the paper's operating point ([`crate::paper`]).
fn run_paper(
    models: &Models,
    context: &Context,
    image: &Loaded,
    job: &Job,
    on_step: &mut dyn FnMut(&Progress) -> ControlFlow<()>,
) -> Result<Outcome, VectorizeError> {
    let PathBudget::Count(paths) = job.paths else {
        return Err(InvalidJob::PaperNeedsCount.into());
    };
    let clock = Instant::now();
    let (scene, refinement, networks) = draw_paper(models, context, &Arc::new(image.image.clone()), paths)?;
    // Segmenting and both networks are one pass here; the stage split of the others does not
    // apply, so the time goes to `coarse`.
    let seconds = Seconds {
        decode: image.seconds,
        coarse: clock.elapsed().as_secs_f64(),
        networks,
        ..Seconds::default()
    };
    let drawn =
        Drawn { auto_budget: false, budget: paths, point: Split::Paper, refinement, moves: None, seconds };
    finish(scene, image, job, drawn, Vec::new(), (models, context.device), on_step)
}

/// Exports `scene` (with a warning when a fixed budget was not filled), then fine-tunes it if
/// the job asks for SuperSVG-F.
fn finish(
    scene: Scene,
    image: &Loaded,
    job: &Job,
    drawn: Drawn,
    mut warnings: Vec<Warning>,
    (models, device): (&Models, &Device),
    on_step: &mut dyn FnMut(&Progress) -> ControlFlow<()>,
) -> Result<Outcome, VectorizeError> {
    if !drawn.auto_budget && scene.len() < drawn.budget {
        warnings.push(Warning::FewerPaths { drawn: scene.len(), budget: drawn.budget });
    }
    let outcome = export(scene, image, job, drawn, warnings)?;
    match &job.finetune {
        Some(options) => {
            // F takes E_o's steps first where the models have one and the job names none.
            let learned = options.learned.clone().or_else(|| {
                let optimizer = models.optimizer.as_ref()?;
                Some(Learned {
                    network: optimizer.network.clone(),
                    steps: optimizer.steps(),
                    device: device.clone(),
                })
            });
            outcome.finetuned(image, job, &FinetuneOptions { learned, ..options.clone() }, on_step)
        }
        None => Ok(outcome),
    }
}

/// What the report says of how a scene was drawn, besides the scene itself.
struct Drawn {
    auto_budget: bool,
    budget: usize,
    point: Split,
    refinement: RefineTally,
    moves: Option<MoveTally>,
    seconds: Seconds,
}

/// The outcome of `scene`: its SVG at the input's size (one group per region, so editors select
/// a region's paths together) and its measures on the exact rendering of the shapes as the SVG
/// writes them (its decimals, 8-bit colours: [`Shape::as_written`]), so that the report
/// measures what the file shows.
fn export(
    scene: Scene,
    image: &Loaded,
    job: &Job,
    drawn: Drawn,
    warnings: Vec<Warning>,
) -> Result<Outcome, VectorizeError> {
    let clock = Instant::now();
    let (width, height) = image.original;
    let decimals = Decimals::new(job.svg.decimals);
    let shapes: Vec<Shape> =
        scene.scene().iter().map(|shape| shape.as_written([width as f32, height as f32], decimals)).collect();
    let mut written = scene.clone();
    written.set_shapes(&shapes);
    let layers: Vec<Option<u32>> = scene.paths().iter().map(|placed| placed.region).collect();
    let svg = to_svg_with(&shapes, &layers, width, height, &job.svg)?;
    let canvas = written.canvas_image();
    let mse = common::mse(&canvas, &image.image);
    let ssim = job.ssim.then(|| common::ssim(&canvas, &image.image));
    let export = clock.elapsed().as_secs_f64();
    let Drawn { auto_budget, budget, point, refinement, moves, mut seconds } = drawn;
    seconds.export = export;
    seconds.total = seconds.decode
        + seconds.superpixels
        + seconds.coarse
        + seconds.refine
        + seconds.moves
        + seconds.finetune.unwrap_or(0.0)
        + export;
    let report = Report {
        width,
        height,
        working_width: image.image.width(),
        working_height: image.image.height(),
        budget,
        auto_budget,
        paths: scene.len(),
        paths_by_stage: scene.counts(),
        regions: scene.segmentation().regions.len(),
        operating_point: point,
        refinement,
        moves,
        mse,
        psnr: common::psnr_of_mse(mse),
        ssim,
        finetune_steps: None,
        svg_bytes: svg.len(),
        seconds,
    };
    Ok(Outcome { scene, written, svg, report, warnings })
}

impl Outcome {
    /// SuperSVG-F from this outcome: every path fine-tuned against `image` (the image the
    /// outcome was drawn from) as `options` say, then exported again; never worse than this
    /// outcome by the error of what its file shows (this outcome is returned where it would be). `on_step` is called after
    /// every step; breaking stops with the best drawing so far.
    pub fn finetuned(
        self,
        image: &Loaded,
        job: &Job,
        options: &FinetuneOptions,
        on_step: &mut dyn FnMut(&Progress) -> ControlFlow<()>,
    ) -> Result<Outcome, VectorizeError> {
        let b = self.clone();
        let Outcome { mut scene, report, warnings, .. } = self;
        let clock = Instant::now();
        let steps = finetune_with_progress(&mut scene, options, on_step);
        let seconds = Seconds { finetune: Some(clock.elapsed().as_secs_f64()), ..report.seconds };
        let drawn = Drawn {
            auto_budget: report.auto_budget,
            budget: report.budget,
            point: report.operating_point,
            refinement: report.refinement,
            moves: report.moves,
            seconds,
        };
        let mut outcome = export(scene, image, job, drawn, warnings)?;
        // F keeps its best state by the drawing's own error; the file rounds it. Where the file
        // of F's best would draw worse than B's, B's is F's answer: F never draws worse.
        if outcome.report.mse > b.report.mse {
            let total = b.report.seconds.total + outcome.report.seconds.finetune.unwrap_or(0.0);
            outcome = Outcome {
                report: Report { seconds: Seconds { total, ..outcome.report.seconds }, ..b.report },
                ..b
            };
        }
        outcome.report.finetune_steps = Some(steps);
        Ok(outcome)
    }
}
