//! The networks scored the way inference uses them, on held-out images, against the same
//! paths spent on regions (what inference does without them).
//!
//! - E_r ([`RefineCheck`]): on the fallback drawing of each image (what the coarse stage hands
//!   E_r on photos), infer's own refinement stage asks it for paths on the regions drawn worst,
//!   recolours them and keeps those that lower the error, within a share of the budget. It
//!   earns that share when the PSNR its kept paths add beats what as many more regions add;
//!   the exact optimizer proposing in its place says what its role can reach.
//! - E_c ([`CoarseCheck`]): each image drawn by SuperSVG-B with E_c and no E_r (`infer::run`:
//!   its paths bought from the regions by the trade), against the fallback alone at the same
//!   budget (`infer --regions N-1`).

use std::path::PathBuf;
use std::sync::Arc;

use burn::tensor::Device;
use common::Loaded;
use image::Rgb32FImage;
use infer::stages::{FallbackDrawing, Proposer, Segmented, Style, draw_refinement, hierarchy, max_regions};
use infer::{Context, Job, MAX_PATHS, Models, Network, OPTIMIZER_STEPS, PathBudget, Scene, Split};
use model::{CoarseModel, ModelConfig, OperatingPoint, PathOptimizer, RefineModel};
use serde::Serialize;

use crate::config::ValidationConfig;
use crate::data::{DataError, ImageSet};
use crate::validation::region_count;

/// Crops per network call in the checks: inference's default batch.
const BATCH: usize = 32;

/// What a network did at inference on the checks' images.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AtInference {
    /// E_c's check.
    Coarse(CoarseScores),
    /// E_r's check.
    Refine(RefineScores),
}

/// One held-out image drawn by its regions, and what more regions would add to it.
struct Case {
    /// The fallback drawing of the image's regions.
    scene: Scene,
    /// The paths E_r may add: the share of the budget.
    extra: usize,
    /// PSNR (dB) that `extra` more regions add to the fallback drawing.
    regions_db: f64,
    /// PSNR (dB) that the exact optimizer's paths add in E_r's place, within `extra`.
    optimizer_db: f64,
}

/// The held-out images of `[validation]`, each drawn by its regions at the count the crops of
/// [`crate::validation::Validation`] are cut at, and the share of the budget E_r is given.
pub struct RefineCheck {
    cases: Vec<Case>,
    config: ModelConfig,
}

/// What E_r did on the check's images, summed (paths) or averaged over images (dB).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct RefineScores {
    /// Paths E_r proposed.
    pub proposed: usize,
    /// Paths that lowered the error and were kept.
    pub kept: usize,
    /// The PSNR (dB) the kept paths added to each image's drawing, averaged.
    pub gain_db: f64,
    /// The PSNR (dB) the same budget adds as more regions, averaged: the bar.
    pub regions_db: f64,
    /// The PSNR (dB) the exact optimizer's paths add in E_r's place with the same budget
    /// ([`Proposer::Optimizer`], [`OPTIMIZER_STEPS`] steps a crop), averaged: what gradient
    /// descent finds in E_r's role, which a trained E_r is measured against.
    pub optimizer_db: f64,
}

impl RefineScores {
    /// What E_r's share buys over spending it on regions (dB, positive when E_r earns it).
    pub fn margin_db(&self) -> f64 {
        self.gain_db - self.regions_db
    }
}

impl RefineCheck {
    /// The check of `config.images` (none without images), with `config.refine_share` of each
    /// image's paths for E_r, regions made as inference makes them at `compactness`, for a model
    /// of configuration `model`. Deterministic.
    pub fn build(
        config: &ValidationConfig,
        compactness: f32,
        model: &ModelConfig,
    ) -> Result<Option<Self>, DataError> {
        let Some((folder, images)) = held_out(config)? else { return Ok(None) };
        let mut cases = Vec::with_capacity(images.len());
        for (image, count) in images {
            let most = max_regions(image.width(), image.height());
            let count = count.clamp(1, most - 1);
            let extra = ((count as f64 * config.refine_share as f64).ceil() as usize).clamp(1, most - count);
            let tree = hierarchy(&image, count + extra, compactness)
                .map_err(|source| DataError::ValidationSegment { path: folder.clone(), source })?;
            let Segmented { hierarchy, segmentation, fallback } =
                Segmented::new(&image, tree, count, Style::default());
            let more = FallbackDrawing::new(
                &image,
                &Arc::new(hierarchy.cut(&image, count + extra)),
                Style::default(),
            );
            let regions_db = 10.0 * (fallback.error / more.error.max(f64::MIN_POSITIVE)).log10();
            let scene = Scene::drawn(image, segmentation, fallback.placed(), fallback.canvas);
            let optimizer = PathOptimizer { paths: model.refine_paths, steps: OPTIMIZER_STEPS };
            let budget = scene.len() + extra;
            let context = Context { config: model, batch: BATCH, device: &Device::flex() };
            let optimizer_db =
                draw_refinement(&context, Proposer::Optimizer(optimizer), &mut scene.clone(), budget, None)
                    .expect("the optimizer reads no checkpoint")
                    .gain_db;
            cases.push(Case { scene, extra, regions_db, optimizer_db });
        }
        Ok(Some(Self { cases, config: model.clone() }))
    }

    /// Runs inference's refinement stage with `model` (on `device`) over every image's drawing.
    pub fn score(&self, model: &RefineModel, device: &Device) -> RefineScores {
        let mut scores =
            RefineScores { proposed: 0, kept: 0, gain_db: 0.0, regions_db: 0.0, optimizer_db: 0.0 };
        let model = Network::in_memory(model.clone(), "the model in training");
        for case in &self.cases {
            // A stop cuts the scoring short; the trainer then records none of it.
            if crate::stop::interrupted() {
                break;
            }
            let mut scene = case.scene.clone();
            let budget = scene.len() + case.extra;
            let context = Context { config: &self.config, batch: BATCH, device };
            let tally = draw_refinement(&context, Proposer::Network(&model), &mut scene, budget, None)
                .expect("a network built in memory has no checkpoint to read");
            scores.proposed += tally.proposed;
            scores.kept += tally.kept;
            scores.gain_db += tally.gain_db;
            scores.regions_db += case.regions_db;
            scores.optimizer_db += case.optimizer_db;
        }
        let images = self.cases.len().max(1) as f64;
        scores.gain_db /= images;
        scores.regions_db /= images;
        scores.optimizer_db /= images;
        scores
    }
}

/// The held-out images of `[validation]` with a path budget each (the region counts of
/// `segments`, spread over the images as the crops are), and their fallback drawings' PSNR at
/// that budget.
pub struct CoarseCheck {
    images: Vec<(Loaded, usize, f64)>,
    config: ModelConfig,
    point: OperatingPoint,
    compactness: f32,
}

/// What E_c did at inference on the check's images.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct CoarseScores {
    /// E_c's paths in the drawings, summed over images.
    pub bought: usize,
    /// PSNR (dB) of SuperSVG-B without E_r, averaged over images.
    pub psnr_b: f64,
    /// PSNR (dB) of the fallback alone at the same budget, averaged: the bar.
    pub psnr_regions: f64,
}

impl CoarseScores {
    /// What E_c's paths buy over the regions they replace (dB, positive when E_c earns them).
    pub fn margin_db(&self) -> f64 {
        self.psnr_b - self.psnr_regions
    }
}

impl CoarseCheck {
    /// The check of `config.images` (none without images), E_c given `config.coarse_share` of
    /// each budget, regions made as inference makes them at `compactness`, for a model of
    /// configuration `model`. Deterministic.
    pub fn build(
        config: &ValidationConfig,
        compactness: f32,
        model: &ModelConfig,
    ) -> Result<Option<Self>, DataError> {
        let Some((folder, held)) = held_out(config)? else { return Ok(None) };
        let mut images = Vec::with_capacity(held.len());
        for (image, count) in held {
            let most = max_regions(image.width(), image.height());
            // What `infer::run` accepts: a region and the background, at most a path per region
            // the image holds room for, at most MAX_PATHS.
            let budget = count.clamp(2, (most + 1).min(MAX_PATHS));
            let tree = hierarchy(&image, budget - 1, compactness)
                .map_err(|source| DataError::ValidationSegment { path: folder.clone(), source })?;
            let regions = Segmented::new(&image, tree, budget - 1, Style::default());
            let psnr = common::psnr_of_mse(regions.fallback.mse());
            images.push((Loaded::from_image(Arc::unwrap_or_clone(image)), budget, psnr));
        }
        let point = OperatingPoint { coarse_share: config.coarse_share, refine_share: 0.0 };
        Ok(Some(Self { images, config: model.clone(), point, compactness }))
    }

    /// Draws every image with `model` (on `device`) as `infer` draws it without E_r.
    pub fn score(&self, model: &CoarseModel, device: &Device) -> CoarseScores {
        let models = Models {
            coarse: Network::in_memory(model.clone(), "the model in training"),
            refine: None,
            mover: None,
            optimizer: None,
            config: self.config.clone(),
            operating_point: self.point,
        };
        let mut scores = CoarseScores { bought: 0, psnr_b: 0.0, psnr_regions: 0.0 };
        for (image, budget, psnr_regions) in &self.images {
            // A stop cuts the scoring short; the trainer then records none of it.
            if crate::stop::interrupted() {
                break;
            }
            let job = Job {
                paths: PathBudget::Count(*budget),
                operating_point: Split::Point(self.point),
                compactness: self.compactness,
                batch: BATCH,
                ..Job::default()
            };
            // The budget was clamped into range and the compactness validated when the check
            // was built: no error is left for `run` to report.
            let outcome = infer::run(&models, image, &job, device).expect("a budget within range");
            scores.bought += outcome.report.paths_by_stage.coarse;
            scores.psnr_b += outcome.report.psnr;
            scores.psnr_regions += psnr_regions;
        }
        let images = self.images.len().max(1) as f64;
        scores.psnr_b /= images;
        scores.psnr_regions /= images;
        scores
    }
}

/// The images of `config.images` (none without a folder) at the validation size, each with its
/// region count of `config.segments` ([`region_count`]), and the folder for errors.
fn held_out(
    config: &ValidationConfig,
) -> Result<Option<(&PathBuf, Vec<(Arc<Rgb32FImage>, usize)>)>, DataError> {
    let Some(folder) = &config.images else { return Ok(None) };
    let set = ImageSet::load(folder, config.image_size)?;
    let images = (0..set.len())
        .map(|index| (Arc::new(set.get(index).clone()), region_count(config.segments, index, set.len())))
        .collect();
    Ok(Some((folder, images)))
}
