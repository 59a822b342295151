//! The whole image → SVG job as one call, [`run`]: what `infer`, `eval`, `tune` and any other
//! front end use, so that every figure they print is what a user of `infer` gets.
//!
//! SuperSVG-B is stages over one [`Scene`]: segment (the image's merge tree, cut at the
//! budget's regions) → coarse (background, fallbacks, E_c) → refine (E_r); SuperSVG-F
//! fine-tunes the scene it is handed ([`Outcome::finetuned`]); export writes the SVG from the
//! scene and measures its canvas, which is never rendered again.

use std::ops::ControlFlow;
use std::sync::Arc;
use std::time::Instant;

use burn::tensor::Device;
use common::Loaded;
use model::{OperatingPoint, PathOptimizer};
use raster::{SvgError, SvgOptions, to_svg_with};
use serde::Serialize;
use superpixel::SlicError;

use crate::coarse::{CoarseBudget, Pricing, Trade, draw_coarse};
use crate::finetune::{FinetuneOptions, Progress, finetune_with_progress};
use crate::models::Models;
use crate::paper::draw_paper;
use crate::refine::{Proposer, RefineTally, Refiner, draw_refinement, draw_refinement_traded};
use crate::scene::{Scene, StageCounts};
use crate::segmentation::{AutoBudget, Segmented, auto_budget, hierarchy, max_regions};

/// The most paths [`run`] draws: at 20 000, segmenting, fitting and the exact canvas take about
/// 10 s at 512 px; more paths than that is more regions than such an image has of
/// [`crate::segmentation::PIXELS_PER_REGION`].
pub const MAX_PATHS: usize = 20_000;

/// How many paths a job may draw.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PathBudget {
    /// At most this many (2 to [`MAX_PATHS`]); fewer only when no further path lowers the error.
    Count(usize),
    /// As many as the image needs, by [`auto_budget`]'s rule.
    Auto(AutoBudget),
}

impl std::str::FromStr for PathBudget {
    type Err = BudgetParseError;

    /// `auto`, or a number of paths from 2 to [`MAX_PATHS`] (what `--paths` takes).
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        match text.parse::<usize>() {
            _ if text == "auto" => Ok(PathBudget::Auto(AutoBudget::default())),
            Ok(paths) if (2..=MAX_PATHS).contains(&paths) => Ok(PathBudget::Count(paths)),
            _ => Err(BudgetParseError(text.to_string())),
        }
    }
}

impl std::fmt::Display for PathBudget {
    /// As it is written on the command line: `500`, `auto`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PathBudget::Count(paths) => write!(f, "{paths}"),
            PathBudget::Auto(_) => f.write_str("auto"),
        }
    }
}

/// Text that is no [`PathBudget`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0:?} is not a path budget: a number from 2 to {MAX_PATHS}, or auto")]
pub struct BudgetParseError(pub String);

/// Where a job's path budget goes (`infer --operating-point`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum BudgetSplit {
    /// The operating point stored with the models ([`Models::operating_point`]).
    #[default]
    Stored,
    /// This operating point.
    Point(OperatingPoint),
    /// The paper's inference ([`crate::paper`]): for models trained with the paper preset, to
    /// be set beside the paper's tables. A fixed budget only; no region count.
    Paper,
}

impl std::str::FromStr for BudgetSplit {
    type Err = SplitParseError;

    /// `stored`, `paper`, or `COARSE,REFINE`: the shares of [`OperatingPoint`] (`0.2,0.1`).
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let invalid = |why: String| SplitParseError(text.to_string(), why);
        match text {
            "stored" => Ok(BudgetSplit::Stored),
            "paper" => Ok(BudgetSplit::Paper),
            _ => {
                let Some((coarse, refine)) = text.split_once(',') else {
                    return Err(invalid("not stored, paper or two shares".into()));
                };
                let share = |value: &str| value.trim().parse::<f32>().map_err(|e| invalid(e.to_string()));
                let point = OperatingPoint { coarse_share: share(coarse)?, refine_share: share(refine)? };
                point.validate().map_err(|e| invalid(e.0))?;
                Ok(BudgetSplit::Point(point))
            }
        }
    }
}

impl Serialize for BudgetSplit {
    /// An operating point as its shares; the others by name (`"stored"`, `"paper"`).
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        match self {
            BudgetSplit::Stored => serializer.serialize_str("stored"),
            BudgetSplit::Point(point) => point.serialize(serializer),
            BudgetSplit::Paper => serializer.serialize_str("paper"),
        }
    }
}

/// Text that is no [`BudgetSplit`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0:?} is not an operating point ({1}): stored, paper, or COARSE,REFINE shares such as 0.2,0")]
pub struct SplitParseError(pub String, pub String);

/// Everything that decides how an image becomes an SVG.
#[derive(Clone, Debug)]
pub struct Job {
    /// How many paths.
    pub paths: PathBudget,
    /// Number of superpixels, below the path count (a fixed budget only). By default as many
    /// as the budget holds beside E_r's share, and E_c's and E_r's paths take the place of
    /// regions where they draw better than the regions would ([`crate::coarse::Trade`]); a given count
    /// is kept, and E_c and E_r draw only with what it leaves. Lowered to one per
    /// [`crate::segmentation::PIXELS_PER_REGION`] pixels, with a [`Warning`].
    pub regions: Option<usize>,
    /// How the budget is split; by default the operating point stored with the models.
    pub operating_point: BudgetSplit,
    /// SuperSVG-F: fine-tune every path against the image after B.
    pub finetune: Option<FinetuneOptions>,
    /// How the SVG is written (decimals).
    pub svg: SvgOptions,
    /// SLIC compactness (the method's 30).
    pub compactness: f32,
    /// Regions drawn along shared boundaries fitted with curves, straying at most this far
    /// (pixels of the working image) from the traced ones: larger draws with fewer curves and
    /// bytes, 0 keeps every traced corner. `None` (the default): each region's traced polygon,
    /// grown under its later neighbours, which draws photos better at equal paths, but for
    /// flat art under an automatic budget ([`AutoBudget::flat_tolerance`]).
    pub tolerance: Option<f32>,
    /// Crops per network call.
    pub batch: usize,
    /// Who proposes the refinement stage's paths: E_r, or the exact optimizer in its place.
    pub refiner: Refiner,
}

impl Default for Job {
    fn default() -> Self {
        Self {
            paths: PathBudget::Count(500),
            regions: None,
            operating_point: BudgetSplit::Stored,
            finetune: None,
            svg: SvgOptions::default(),
            compactness: 30.0,
            tolerance: None,
            batch: 32,
            refiner: Refiner::Network,
        }
    }
}

/// Why an image could not be vectorized.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum VectorizeError {
    /// The budget cannot hold the background and one region, or is above [`MAX_PATHS`].
    #[error(
        "a budget of {0} paths is out of range: at least 2 (the background and one region), at most {MAX_PATHS}"
    )]
    Budget(usize),
    /// More regions than the budget has paths for (each takes one, and so does the background).
    #[error(
        "{regions} regions do not fit a budget of {paths} paths (each region takes a path, and so does the background)"
    )]
    Regions {
        /// Regions asked for.
        regions: usize,
        /// The budget.
        paths: usize,
    },
    /// A region count was given with an automatic budget, which chooses its own.
    #[error("a number of regions needs a number of paths, not an automatic budget")]
    RegionsWithAuto,
    /// The paper's inference was asked for with an automatic budget or a region count: it
    /// cuts its own regions for a number of paths.
    #[error("the paper's operating point takes a number of paths and cuts its own regions")]
    PaperNeedsCount,
    /// The image could not be segmented.
    #[error(transparent)]
    Segmentation(#[from] SlicError),
    /// The drawing could not be written as SVG.
    #[error(transparent)]
    Svg(#[from] SvgError),
}

/// Something a job did differently from what it was asked, said to the user.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum Warning {
    /// Fewer paths than the budget: the rest lowered nothing (a flat picture needs one).
    #[error("{drawn} of {budget} paths drawn: no other path the stages tried lowered the error")]
    FewerPaths {
        /// Paths drawn.
        drawn: usize,
        /// The budget.
        budget: usize,
    },
    /// More regions were asked for than the working image has room for.
    #[error(
        "{asked} regions lowered to {used} (one region per {per} pixels of the {width}×{height} working image)",
        per = crate::segmentation::PIXELS_PER_REGION
    )]
    RegionsLowered {
        /// Asked for.
        asked: usize,
        /// Drawn.
        used: usize,
        /// Working width.
        width: u32,
        /// Working height.
        height: u32,
    },
}

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
    /// Of `coarse` and `refine`, E_c's and E_r's forward passes (cropping their regions and
    /// reading out their paths included): what the method's networks cost beside the rest.
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
    pub operating_point: BudgetSplit,
    /// What E_r proposed, kept and gained (SuperSVG-B's; fine-tuning leaves it as it was).
    pub refinement: RefineTally,
    /// Mean squared error of the drawing at the working size (RGB in [0, 1]).
    pub mse: f64,
    /// Its PSNR (dB).
    pub psnr: f64,
    /// Its SSIM ([`common::ssim`]).
    pub ssim: f64,
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
    /// The drawing: paths with their regions and stages, and its exact rendering.
    pub scene: Scene,
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
    if let PathBudget::Count(paths) = job.paths
        && !(2..=MAX_PATHS).contains(&paths)
    {
        return Err(VectorizeError::Budget(paths));
    }
    if job.operating_point == BudgetSplit::Paper {
        return run_paper(models, image, job, device, on_step);
    }
    let started = Instant::now();
    let target = &image.image;
    let (width, height) = target.dimensions();
    let point = operating_point(models, job);
    let most = max_regions(width, height);
    let mut warnings = Vec::new();
    let (paths, regions, tree, tolerance) = match job.paths {
        PathBudget::Count(paths) => {
            if let Some(regions) = job.regions.filter(|&r| r == 0 || r >= paths) {
                return Err(VectorizeError::Regions { regions, paths });
            }
            // Unless told how many, the regions fill what E_r's share leaves, and E_c and E_r buy
            // their paths from them (`coarse::Trade`).
            let asked = job.regions.unwrap_or_else(|| point.filling_regions(paths)).clamp(1, paths - 1);
            // Only a count the user gave is said to be lowered: the default fills the budget.
            if asked > most && job.regions.is_some() {
                warnings.push(Warning::RegionsLowered { asked, used: most, width, height });
            }
            let regions = asked.min(most);
            (paths, regions, hierarchy(target, regions, job.compactness)?, job.tolerance)
        }
        PathBudget::Auto(auto) => {
            if job.regions.is_some() {
                return Err(VectorizeError::RegionsWithAuto);
            }
            let choice = auto_budget(target, &point, job.compactness, &auto)?;
            let tolerance = job.tolerance.or(choice.flat.then_some(auto.flat_tolerance));
            (choice.paths, choice.regions, choice.hierarchy, tolerance)
        }
    };
    // The stages share one copy of the image and of its regions.
    let target = Arc::new(target.clone());
    let Segmented { hierarchy, segmentation, fallback } = Segmented::new(&target, tree, regions, tolerance);
    let pricing = Pricing::for_drawing(hierarchy.flat_error(segmentation.regions.len()), fallback.error);
    let mut scene = Scene::new(target, segmentation);
    let superpixels = started.elapsed().as_secs_f64();

    let clock = Instant::now();
    let trade = job.regions.is_none().then_some(Trade { hierarchy: &hierarchy, tolerance, pricing });
    let budget = CoarseBudget {
        paths: point.coarse_paths(paths),
        total: paths - point.reserved_for_refine(paths),
        trade,
    };
    let coarse_network =
        draw_coarse(&models.coarse, &models.config, &mut scene, fallback, budget, job.batch, device);
    let coarse = clock.elapsed().as_secs_f64();

    let clock = Instant::now();
    let proposer = match job.refiner {
        Refiner::Network => models.refine.as_ref().map(Proposer::Network),
        Refiner::Optimizer { steps } => {
            Some(Proposer::Optimizer(PathOptimizer { paths: models.config.refine_paths, steps }))
        }
    };
    let refinement = match proposer {
        Some(proposer) => match trade {
            Some(trade) => {
                draw_refinement_traded(proposer, &models.config, &mut scene, paths, trade, job.batch, device)
            }
            None => draw_refinement(proposer, &models.config, &mut scene, paths, job.batch, device),
        },
        None => RefineTally::default(),
    };
    let refine = clock.elapsed().as_secs_f64();

    let networks = coarse_network + refinement.network_seconds;
    let seconds =
        Seconds { decode: image.seconds, superpixels, coarse, refine, networks, ..Seconds::default() };
    let drawn = Drawn {
        auto_budget: matches!(job.paths, PathBudget::Auto(_)),
        budget: paths,
        point: BudgetSplit::Point(point),
        refinement,
        seconds,
    };
    finish(scene, image, job, drawn, warnings, on_step)
}

/// [`run_with_progress`] at the paper's operating point ([`crate::paper`]).
fn run_paper(
    models: &Models,
    image: &Loaded,
    job: &Job,
    device: &Device,
    on_step: &mut dyn FnMut(&Progress) -> ControlFlow<()>,
) -> Result<Outcome, VectorizeError> {
    let PathBudget::Count(paths) = job.paths else {
        return Err(VectorizeError::PaperNeedsCount);
    };
    if job.regions.is_some() {
        return Err(VectorizeError::PaperNeedsCount);
    }
    let clock = Instant::now();
    let (scene, refinement, networks) =
        draw_paper(models, &Arc::new(image.image.clone()), paths, job.batch, device)?;
    // Segmenting and both networks are one pass here; the stage split of the others does not
    // apply, so the time goes to `coarse`.
    let seconds = Seconds {
        decode: image.seconds,
        coarse: clock.elapsed().as_secs_f64(),
        networks,
        ..Seconds::default()
    };
    let drawn = Drawn { auto_budget: false, budget: paths, point: BudgetSplit::Paper, refinement, seconds };
    finish(scene, image, job, drawn, Vec::new(), on_step)
}

/// Exports `scene` (with a warning when a fixed budget was not filled), then fine-tunes it if
/// the job asks for SuperSVG-F.
fn finish(
    scene: Scene,
    image: &Loaded,
    job: &Job,
    drawn: Drawn,
    mut warnings: Vec<Warning>,
    on_step: &mut dyn FnMut(&Progress) -> ControlFlow<()>,
) -> Result<Outcome, VectorizeError> {
    if !drawn.auto_budget && scene.len() < drawn.budget {
        warnings.push(Warning::FewerPaths { drawn: scene.len(), budget: drawn.budget });
    }
    let outcome = export(scene, image, job, drawn, warnings)?;
    match &job.finetune {
        Some(options) => outcome.finetuned(image, job, options, on_step),
        None => Ok(outcome),
    }
}

/// The operating point a job uses: the one given, else the models' own, with no budget kept for
/// E_r when there is none (and no optimizer in its place). The paper's inference has none; it
/// reads as the stored one here.
pub fn operating_point(models: &Models, job: &Job) -> OperatingPoint {
    let mut point = match job.operating_point {
        BudgetSplit::Point(point) => point,
        BudgetSplit::Stored | BudgetSplit::Paper => models.operating_point,
    };
    if models.refine.is_none() && job.refiner == Refiner::Network {
        point.refine_share = 0.0;
    }
    point
}

/// What the report says of how a scene was drawn, besides the scene itself.
struct Drawn {
    auto_budget: bool,
    budget: usize,
    point: BudgetSplit,
    refinement: RefineTally,
    seconds: Seconds,
}

/// The outcome of `scene`: its SVG at the input's size (one group per region, so editors select
/// a region's paths together) and its measures on the scene's own canvas.
fn export(
    scene: Scene,
    image: &Loaded,
    job: &Job,
    drawn: Drawn,
    warnings: Vec<Warning>,
) -> Result<Outcome, VectorizeError> {
    let clock = Instant::now();
    let (width, height) = image.original;
    let layers: Vec<Option<u32>> = scene.paths().iter().map(|placed| placed.region).collect();
    let svg = to_svg_with(&scene.scene(), &layers, width, height, &job.svg)?;
    let canvas = scene.canvas_image();
    let mse = common::mse(&canvas, &image.image);
    let ssim = common::ssim(&canvas, &image.image);
    let export = clock.elapsed().as_secs_f64();
    let Drawn { auto_budget, budget, point, refinement, mut seconds } = drawn;
    seconds.export = export;
    seconds.total = seconds.decode
        + seconds.superpixels
        + seconds.coarse
        + seconds.refine
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
        mse,
        psnr: common::psnr_of_mse(mse),
        ssim,
        finetune_steps: None,
        svg_bytes: svg.len(),
        seconds,
    };
    Ok(Outcome { scene, svg, report, warnings })
}

impl Outcome {
    /// SuperSVG-F from this outcome: every path fine-tuned against `image` (the image the
    /// outcome was drawn from) as `options` say, then exported again. `on_step` is called after
    /// every step; breaking stops with the best drawing so far.
    pub fn finetuned(
        self,
        image: &Loaded,
        job: &Job,
        options: &FinetuneOptions,
        on_step: &mut dyn FnMut(&Progress) -> ControlFlow<()>,
    ) -> Result<Outcome, VectorizeError> {
        let Outcome { mut scene, report, warnings, .. } = self;
        let clock = Instant::now();
        let steps = finetune_with_progress(&mut scene, options, on_step);
        let seconds = Seconds { finetune: Some(clock.elapsed().as_secs_f64()), ..report.seconds };
        let drawn = Drawn {
            auto_budget: report.auto_budget,
            budget: report.budget,
            point: report.operating_point,
            refinement: report.refinement,
            seconds,
        };
        let mut outcome = export(scene, image, job, drawn, warnings)?;
        outcome.report.finetune_steps = Some(steps);
        Ok(outcome)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn budgets_read_and_write_as_on_the_command_line() {
        assert_eq!("500".parse::<PathBudget>(), Ok(PathBudget::Count(500)));
        assert_eq!("auto".parse::<PathBudget>(), Ok(PathBudget::Auto(AutoBudget::default())));
        for bad in ["1", "20001", "-3", "Auto", ""] {
            assert_eq!(bad.parse::<PathBudget>(), Err(BudgetParseError(bad.to_string())), "{bad}");
        }
        for text in ["2", "20000", "auto"] {
            assert_eq!(text.parse::<PathBudget>().unwrap().to_string(), text);
        }
    }

    #[test]
    fn operating_points_read_as_on_the_command_line() {
        assert_eq!("stored".parse::<BudgetSplit>(), Ok(BudgetSplit::Stored));
        assert_eq!("paper".parse::<BudgetSplit>(), Ok(BudgetSplit::Paper));
        let point = OperatingPoint { coarse_share: 0.2, refine_share: 0.1 };
        assert_eq!("0.2, 0.1".parse::<BudgetSplit>(), Ok(BudgetSplit::Point(point)));
        for bad in ["Paper", "0.2", "0.6,0.5", "1,0", "a,b", ""] {
            assert!(bad.parse::<BudgetSplit>().is_err(), "{bad}");
        }
        let written = serde_json::to_string(&[BudgetSplit::Paper, BudgetSplit::Point(point)]).unwrap();
        assert_eq!(written, r#"["paper",{"coarse_share":0.2,"refine_share":0.1}]"#);
    }
}
