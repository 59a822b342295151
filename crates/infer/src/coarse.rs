//! The coarse stage: the background, then region after region in painter's order its fallback
//! path and the coarse model's paths that draw it better; by default each such path is paid
//! for with a region ([`Market`]), so E_c draws only where it beats spending the same paths on
//! regions.

use web_time::Instant;

use model::{CheckpointError, CoarseModel, CropBatch, crop_to_image};
use raster::Path;
use superpixel::{RegionCrop, worst_first};

use crate::budget::{CoarseShare, Prices};
use crate::fallback::FallbackDrawing;
use crate::models::{Context, Network};
use crate::scene::{Scene, Tried, paint_with, region_errors};

/// Draws `scene` (which must be empty) from `fallback`, the fallback drawing of its
/// segmentation: the background path, then for every region in painter's order its fallback
/// path and the E_c paths that draw it better. With no E_c paths to draw, the scene takes the
/// fallback drawing's rendering as it is.
///
/// E_c draws the regions the fallback drawing gets most wrong, as many as it may keep paths:
/// a model's path pays where a flat region errs most. Each visible path, in the least-squares
/// colour over what is drawn ([`Scene::fit_colour`]), is tried in E_c's order and kept if it
/// lowers the squared error over the pixels of the regions painted so far (later regions
/// will paint over the rest); of those, the ones that lowered it most are kept, up to the
/// budget. If the kept paths together made the whole image worse than the fallback drawing
/// alone (a path can reach a later region where its fallback leaves a seam), they are all
/// dropped.
///
/// With a market, the segmentation is meant to fill `share.total` on its own: the k paths
/// kept are the k that took away the most error, for the k (up to `share.paths`) at which
/// their gain less the cost of the merges that free k paths is largest. E_c
/// draws its regions in rounds, worst first: the first `FIRST_ROUND`, then each round as
/// many again as all before it, while it buys paths for at least half of the regions it has
/// drawn. The scene is then drawn again on that cut with those paths (the ones that gained
/// least dropped where the cut frees fewer paths than its prices read), and kept only if it
/// beats the fallback drawing of the full segmentation.
///
/// Returns the seconds E_c's forward passes took (cropping its regions and reading out its
/// paths included). E_c is read ([`Network::get`]) only when it has regions to draw; an error
/// reading it is the only error.
///
/// # Panics
/// If the scene already holds paths.
pub fn draw_coarse(
    coarse: &Network<CoarseModel>,
    context: &Context,
    scene: &mut Scene,
    fallback: FallbackDrawing,
    share: CoarseShare,
) -> Result<f64, CheckpointError> {
    assert!(scene.is_empty(), "the coarse stage starts the drawing");
    let (target, segmentation) = (scene.target().clone(), scene.segmentation().clone());
    let spare = share.paths.min(share.total.saturating_sub(1 + fallback.order.len()));
    let wanted = match share.market {
        Some(_) => share.paths.min(segmentation.regions.len().saturating_sub(1)),
        None => spare,
    };
    if wanted == 0 {
        *scene = fallback.into_scene(&target, &segmentation);
        return Ok(0.0);
    }
    let coarse = coarse.get()?;
    let chosen = worst_regions(scene, &fallback, wanted);
    let regions = segmentation.regions.len();
    let mut network = 0.0;
    let mut propose_for = |asked: &[u32]| {
        let clock = Instant::now();
        let crops: Vec<RegionCrop> =
            asked.iter().map(|&r| context.config.region_crop(&segmentation, &target, r)).collect();
        let mut proposals = vec![Vec::new(); regions];
        for (&region, paths) in asked.iter().zip(propose(coarse, context, &crops, target.dimensions())) {
            proposals[region as usize] = paths;
        }
        network += clock.elapsed().as_secs_f64();
        proposals
    };
    let error = fallback.error;
    let order = fallback.order.clone();
    let alone = fallback.into_scene(&target, &segmentation);
    *scene = alone.clone();
    let Some(market) = share.market else {
        let mut kept = paint_with(scene, &order, propose_for(&chosen));
        kept.sort_by(|a, b| b.gain.total_cmp(&a.gain));
        keep_best(scene, &kept, spare);
        settle(scene, alone, error);
        return Ok(network);
    };
    let most = regions.saturating_sub(market.hierarchy.fewest_regions());
    let mut prices = Prices::measured(&target, &segmentation, market, most, (error, alone.len()));
    let mut worth = |kept: &[Tried]| {
        let gains: Vec<f64> = kept.iter().take(wanted).map(|tried| tried.gain).collect();
        let bought = prices.buy(&gains, 0);
        (bought, prices.merges_to_free(bought))
    };
    // E_c draws the worst regions first: where it buys paths for fewer than half of them, the
    // regions it gets less wrong would buy fewer still, and it stops there.
    let (mut asked, mut kept) = (0, Vec::new());
    let (bought, merges) = loop {
        let upto = if asked == 0 { FIRST_ROUND } else { 2 * asked }.min(chosen.len());
        kept.extend(paint_with(scene, &order, propose_for(&chosen[asked..upto])));
        asked = upto;
        kept.sort_by(|a, b| b.gain.total_cmp(&a.gain));
        let (bought, merges) = worth(&kept);
        if asked == chosen.len() || 2 * bought < asked {
            break (bought, merges);
        }
    };
    if bought == 0 || merges == 0 {
        *scene = alone;
        return Ok(network);
    }
    let mut bought: Vec<(usize, &Tried)> =
        kept[..bought].iter().map(|tried| (tried.position(scene), tried)).collect();
    bought.sort_by_key(|(position, _)| *position);
    let bought = bought.into_iter().map(|(_, tried)| (tried.region, tried.path));
    let mut drawn;
    (*scene, drawn) = market.redraw(&target, &segmentation, regions - merges, bought);
    // The prices are read between measured cuts: where this cut freed fewer paths than read,
    // the paths that gained least go.
    drawn.sort_by(|a, b| b.gain.total_cmp(&a.gain));
    keep_best(scene, &drawn, drawn.len().saturating_sub(scene.len().saturating_sub(share.total)));
    settle(scene, alone, error);
    Ok(network)
}

/// `scene` with E_c's paths, painted again in one pass (its boxes were painted in windows), or
/// `alone`, the fallback drawing whose error is `error`, if the paths kept made the whole image
/// worse (a path can reach a later region where its fallback leaves a seam) or none was kept.
fn settle(scene: &mut Scene, alone: Scene, error: f64) {
    if scene.counts().coarse > 0 {
        scene.repaint();
    }
    if scene.counts().coarse == 0 || scene.total_error() > error {
        *scene = alone;
    }
}

/// With a market, how many regions E_c draws first, the worst (each is a crop E_c draws):
/// where it buys paths for fewer than half of them it stops there, while where it buys most
/// the rounds grow to every region it may draw.
pub const FIRST_ROUND: usize = 8;

/// Drops every E_c path of `scene` but the `most` of `kept` (sorted by gain, largest first).
fn keep_best(scene: &mut Scene, kept: &[Tried], most: usize) {
    if kept.len() > most {
        let mut dropped = vec![false; scene.len()];
        for tried in &kept[most..] {
            dropped[tried.position(scene)] = true;
        }
        scene.retain(|index, _| !dropped[index]);
    }
}

/// The `count` regions of `scene`'s image whose pixels `fallback` gets most wrong.
fn worst_regions(scene: &Scene, fallback: &FallbackDrawing, count: usize) -> Vec<u32> {
    let errors = region_errors(&fallback.canvas, scene.target(), scene.segmentation());
    let mut ranked: Vec<u32> = (0..errors.len() as u32).collect();
    worst_first(&mut ranked, &errors);
    ranked.truncate(count);
    ranked
}

/// E_c on every crop, `context.batch` at a time: each crop's visible paths, opaque, in the
/// image's unit square, in the model's painter's order.
pub(crate) fn propose(
    coarse: &CoarseModel,
    context: &Context,
    crops: &[RegionCrop],
    (width, height): (u32, u32),
) -> Vec<Vec<Path>> {
    let mut proposals = Vec::with_capacity(crops.len());
    for chunk in crops.chunks(context.batch.max(1)) {
        let scenes = coarse.forward(CropBatch::new(chunk, context.device).pixels).to_scenes();
        for (crop, scene) in chunk.iter().zip(scenes) {
            let visible = scene.into_iter().filter(Path::is_visible);
            proposals.push(
                visible.map(|path| crop_to_image(Path { alpha: 1.0, ..path }, crop, width, height)).collect(),
            );
        }
    }
    proposals
}
