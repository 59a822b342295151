//! The refinement stage: E_r adds paths to the regions drawn worst, and a path stays only if it
//! lowers the error of the box it was drawn in. It fills what the budget leaves or, by default,
//! also buys paths with regions where they pay ([`crate::budget::Market`]). The paths are E_r's,
//! or the exact optimizer's in its place ([`Proposer`]): what a trained E_r could add at best.

use web_time::Instant;

use model::{CheckpointError, CropBatch, PathOptimizer, RefineModel, canvas_cells, crop_to_image};
use raster::{Path, Shape};
use serde::Serialize;
use superpixel::{RegionCrop, worst_first};

use crate::budget::{Market, Prices};
use crate::models::{Context, Network};
use crate::scene::{Origin, Placed, Scene, Scope};

/// What E_r did in a drawing: how many paths it proposed, how many lowered the error and were
/// kept, and by how much they lowered it. What an E_r checkpoint is worth to inference (`eval`
/// reports it per method; `--refine CKPT` scores another).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct RefineTally {
    /// Paths E_r proposed.
    pub proposed: usize,
    /// Paths kept.
    pub kept: usize,
    /// How much they raised the drawing's PSNR (dB, whole image): 10·log₁₀ of the squared
    /// error before over after.
    pub gain_db: f64,
    /// Seconds E_r's forward passes took (cropping the regions and reading out the paths
    /// included; the optimizer's, in its place); reported with the job's times, not here.
    #[serde(skip)]
    pub network_seconds: f64,
}

/// Who proposes the refinement stage's paths for a region's crop.
#[derive(Clone, Copy)]
pub enum Proposer<'a> {
    /// E_r: one forward pass over the (target, canvas) crops, the method's. It is read
    /// ([`Network::get`]) the first time a round has a region to propose for.
    Network(&'a Network<RefineModel>),
    /// The exact optimizer in E_r's place ([`PathOptimizer`]): as many paths a crop as E_r
    /// proposes, seeded where the canvas errs most and moved against the image's box, unmasked.
    /// What gradient descent finds in E_r's role, for judging a trained E_r against
    /// (`infer --refiner optimizer`).
    Optimizer(PathOptimizer),
}

impl Proposer<'_> {
    /// The paths proposed for each of `crops` (in each crop's unit square) over `scene`'s
    /// drawing.
    fn propose(
        &self,
        context: &Context,
        scene: &Scene,
        crops: &[&RegionCrop],
    ) -> Result<Vec<Vec<Path>>, CheckpointError> {
        let device = context.device;
        let canvas = canvas_cells(&scene.canvas_image(), crops.iter().copied(), device);
        Ok(match self {
            Proposer::Network(refine) => {
                let refine = refine.get()?;
                let targets = CropBatch::new(crops.iter().copied(), device);
                let canvas = targets.masked_canvas(canvas, &context.config.input);
                refine.forward(targets.pixels, canvas).to_scenes()
            }
            Proposer::Optimizer(optimizer) => {
                let target = canvas_cells(scene.target(), crops.iter().copied(), device);
                optimizer.place_batch(&canvas, &target)
            }
        })
    }
}

/// Rounds of `proposer` until `scene` holds `budget` paths or no region is left to improve:
/// each round ranks the regions by squared error, has `proposer` propose paths for the worst
/// (as many as the remaining budget can use, `context.batch` at most), and tries each proposed
/// path over the current drawing in its least-squares colour ([`Scene::fit_colour`]), keeping
/// those that lower the squared error of their box. A region none of whose proposals helped
/// is not proposed for again; the budget goes to the next-worst ones.
///
/// With a `market`, E_r's paths are also bought with regions, as E_c's are: the paths the
/// budget leaves room for are free; past those each path kept takes the place of a region of
/// `scene`'s segmentation (a cut of the market's merge tree), merged away where merging costs
/// least. E_r proposes for the regions drawn worst, `FIRST_PROBE` in the first round (or as
/// many as the free paths need) and twice as many in each after, up to `context.batch`, until
/// it has filled the free paths and a round buys paths (worth their regions) for fewer than
/// half of the regions it asked about; it never buys more than half the regions (the drawing
/// stays the regions'). The `k` paths that took away the most error are kept, for the `k` at
/// which their gain less the cost of the merges that free their paths is largest; when that
/// needs merges the scene is drawn again on the coarser cut (fallback, E_c's paths, then as
/// many of E_r's as it leaves room for on top, largest gain first, each recoloured and judged
/// again), and kept only if it beats the drawing with the free paths alone.
///
/// Fails only where E_r's weights cannot be read, the first time a round proposes.
pub fn draw_refinement(
    context: &Context,
    proposer: Proposer<'_>,
    scene: &mut Scene,
    budget: usize,
    market: Option<Market<'_>>,
) -> Result<RefineTally, CheckpointError> {
    match market {
        None => fill(context, proposer, scene, budget),
        Some(market) => trade(context, proposer, scene, budget, market),
    }
}

/// [`draw_refinement`] without a market: E_r fills what the budget leaves.
fn fill(
    context: &Context,
    proposer: Proposer<'_>,
    scene: &mut Scene,
    budget: usize,
) -> Result<RefineTally, CheckpointError> {
    let before = scene.total_error();
    let mut rounds = Rounds::new(scene);
    let refine_paths = context.config.refine_paths;
    while scene.len() < budget {
        let regions = (budget - scene.len()).div_ceil(refine_paths).min(context.batch.max(1));
        if rounds.next(context, proposer, scene, regions, budget)? == 0 {
            break;
        }
    }
    Ok(rounds.tally(scene, before))
}

/// [`draw_refinement`] with E_r's paths bought through `market`.
fn trade(
    context: &Context,
    proposer: Proposer<'_>,
    scene: &mut Scene,
    budget: usize,
    market: Market<'_>,
) -> Result<RefineTally, CheckpointError> {
    let before = scene.total_error();
    let start = scene.len();
    let free = budget.saturating_sub(start);
    let (target, fine) = (scene.target().clone(), scene.segmentation().clone());
    let regions = fine.regions.len();
    let most_merges = (regions / 2).min(regions.saturating_sub(market.hierarchy.fewest_regions()));
    // Priced once E_r keeps more paths than are free.
    let mut prices: Option<Prices> = None;
    let mut worth = |gains: &[f64]| {
        if gains.len() <= free {
            return gains.len();
        }
        let prices = prices.get_or_insert_with(|| Prices::new(&target, &fine, market, most_merges));
        prices.buy(gains, free)
    };
    let mut rounds = Rounds::new(scene);
    let mut bought = 0;
    // The first round asks about as many regions as the free paths need, or FIRST_PROBE, and
    // each round after twice as many as the one before, up to the batch: where E_r buys
    // nothing that probe is all it costs.
    let batch = context.batch.max(1);
    let mut count = free.div_ceil(context.config.refine_paths).max(FIRST_PROBE).min(batch);
    loop {
        let asked = rounds.next(context, proposer, scene, count, start + free + most_merges)?;
        count = (2 * count).min(batch);
        let kept = rounds.gains.len();
        if asked == 0 || kept == free + most_merges {
            break;
        }
        let before = std::mem::replace(&mut bought, worth(&rounds.by_gain()));
        if kept >= free && 2 * bought.saturating_sub(before) < asked {
            break;
        }
    }
    let ranked = rounds.ranked();
    let bought = worth(&rounds.by_gain());
    let merges = match (&prices, bought.checked_sub(free)) {
        (Some(prices), Some(paths)) => prices.merges_to_free(paths),
        _ => 0,
    };
    let merged = (merges > 0).then(|| {
        let coarse = scene.paths()[..start].iter().filter(|placed| placed.origin == Origin::Coarse);
        let coarse = coarse.filter_map(|placed| match (&placed.shape, placed.region) {
            (Shape::Path(path), Some(region)) => Some((region, *path)),
            _ => None,
        });
        let (mut merged, _) = market.redraw(&target, &fine, regions - merges, coarse);
        let fine_to_cut = crate::budget::region_map(&fine, merged.segmentation());
        // As many of E_r's paths as the merged drawing leaves room for, the largest gains.
        let mut chosen = vec![false; rounds.gains.len()];
        ranked.iter().take(budget.saturating_sub(merged.len())).for_each(|&i| chosen[i] = true);
        for (placed, _) in scene.paths()[start..].iter().zip(&chosen).filter(|(_, chosen)| **chosen) {
            let Shape::Path(path) = &placed.shape else { continue };
            let path = merged.fit_colour(path, Scope::All).unwrap_or(*path);
            let region = placed.region.map(|region| fine_to_cut[region as usize]);
            merged.try_push(Placed { shape: path.into(), region, origin: Origin::Refine }, Scope::All);
        }
        merged.repaint();
        merged
    });
    // The free paths alone: the best `free` of those kept, on the drawing as it is.
    let mut best_free = vec![false; rounds.gains.len()];
    ranked.iter().take(free).for_each(|&i| best_free[i] = true);
    scene.retain(|index, _| index < start || best_free[index - start]);
    if let Some(merged) = merged
        && merged.len() <= budget
        && merged.total_error() < scene.total_error()
    {
        *scene = merged;
    }
    Ok(rounds.tally(scene, before))
}

/// How many regions E_r's trade asks about first when no free path needs more: where it buys
/// nothing (photos, small budgets) this probe is all it costs, and a larger one drew no more
/// (docs/method.md).
pub const FIRST_PROBE: usize = 1;

/// E_r's rounds over one drawing: which regions are done with, their crops, and what it proposed
/// and kept.
struct Rounds {
    /// Regions none of whose proposals helped: not proposed for again.
    exhausted: Vec<bool>,
    /// Each region's crop, cut once.
    crops: Vec<Option<RegionCrop>>,
    /// Paths proposed.
    proposed: usize,
    /// The error each path kept took away, in the order kept (they are the scene's last).
    gains: Vec<f64>,
    /// Seconds in E_r's forward passes.
    network: f64,
}

impl Rounds {
    fn new(scene: &Scene) -> Self {
        let regions = scene.segmentation().regions.len();
        Self {
            exhausted: vec![false; regions],
            crops: vec![None; regions],
            proposed: 0,
            gains: Vec::new(),
            network: 0.0,
        }
    }

    /// One round: ranks the regions by squared error, has `proposer` propose paths for the
    /// worst `count` not exhausted, and tries each proposed path over the current drawing in
    /// its least-squares colour ([`Scene::fit_colour`]), keeping those that lower the squared
    /// error of their box, until the scene holds `limit` paths. Returns how many regions it
    /// proposed for (0: none was left, or the scene was full).
    fn next(
        &mut self,
        context: &Context,
        proposer: Proposer<'_>,
        scene: &mut Scene,
        count: usize,
        limit: usize,
    ) -> Result<usize, CheckpointError> {
        if scene.len() >= limit {
            return Ok(0);
        }
        let errors = scene.region_errors();
        let mut worst: Vec<u32> = (0..errors.len() as u32)
            .filter(|&r| !self.exhausted[r as usize] && errors[r as usize] > 0.0)
            .collect();
        worst_first(&mut worst, &errors);
        worst.truncate(count);
        let clock = Instant::now();
        for &r in &worst {
            if self.crops[r as usize].is_none() {
                self.crops[r as usize] = Some(scene.region_crop(context.config, r));
            }
        }
        let chosen: Vec<&RegionCrop> =
            worst.iter().map(|&r| self.crops[r as usize].as_ref().expect("cut above")).collect();
        if chosen.is_empty() {
            self.network += clock.elapsed().as_secs_f64();
            return Ok(0);
        }
        let (width, height) = scene.target().dimensions();
        let proposals = proposer.propose(context, scene, &chosen)?;
        self.network += clock.elapsed().as_secs_f64();
        for ((&region, crop), paths) in worst.iter().zip(&chosen).zip(proposals) {
            let mut kept = 0;
            for path in paths {
                if scene.len() >= limit {
                    return Ok(worst.len());
                }
                self.proposed += 1;
                let path = crop_to_image(path, crop, width, height);
                let path = scene.fit_colour(&path, Scope::All).unwrap_or(path);
                let placed = Placed { shape: path.into(), region: Some(region), origin: Origin::Refine };
                if let Some(gain) = scene.try_push(placed, Scope::All) {
                    kept += 1;
                    self.gains.push(gain);
                }
            }
            self.exhausted[region as usize] |= kept == 0;
        }
        Ok(worst.len())
    }

    /// Indices into [`Rounds::gains`], largest gain first.
    fn ranked(&self) -> Vec<usize> {
        let mut ranked: Vec<usize> = (0..self.gains.len()).collect();
        ranked.sort_by(|&a, &b| self.gains[b].total_cmp(&self.gains[a]));
        ranked
    }

    /// The gains, largest first.
    fn by_gain(&self) -> Vec<f64> {
        self.ranked().into_iter().map(|i| self.gains[i]).collect()
    }

    /// What E_r did to `scene`, whose squared error was `before`.
    fn tally(&self, scene: &Scene, before: f64) -> RefineTally {
        let kept = scene.counts().refine;
        let gain_db = if kept > 0 { 10.0 * (before / scene.total_error()).log10() } else { 0.0 };
        RefineTally { proposed: self.proposed, kept, gain_db, network_seconds: self.network }
    }
}
