//! The coarse stage: the background, then region after region in painter's order its fallback
//! path and the coarse model's paths that draw it better; by default each such path is paid
//! for with a region ([`Trade`]), so E_c draws only where it beats spending the same paths on
//! regions.

use burn::tensor::Device;
use image::Rgb32FImage;
use model::{CoarseModel, CropBatch, ModelConfig, crop_to_image};
use raster::Path;
use superpixel::{Hierarchy, RegionCrop, Segmentation, worst_first};

use crate::fallback::FallbackDrawing;
use crate::scene::{Origin, Placed, Scene, Scope, region_errors};

/// How many paths the coarse stage may draw.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CoarseBudget {
    /// The most E_c paths kept (0: E_c is not run).
    pub paths: usize,
    /// The most paths the scene may hold when the stage ends (background and fallbacks
    /// included; they are always drawn).
    pub total: usize,
    /// `None`: E_c draws only with what the regions leave of `total`. `Some`: E_c's paths are
    /// bought with regions ([`Trade`]).
    pub trade: Option<Trade>,
}

/// E_c's paths paid for with regions: the segmentation fills the budget, and each E_c path kept
/// takes the place of a region, merged away where merging costs least. A path is worth its
/// region only if it takes away more error than the merge adds, so E_c draws only where it
/// beats spending the same paths on regions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Trade {
    /// The tolerance the fallback drawing of the merged regions is drawn with (as
    /// [`FallbackDrawing::new`] takes it).
    pub tolerance: Option<f32>,
}

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
/// With a [`Trade`], the segmentation is meant to fill `total` on its own: the k paths kept
/// are the k that took away the most error, for the k (up to `budget.paths`) at which their
/// gain less the cost of merging k regions away ([`Hierarchy::flat_error`] of the
/// segmentation's merge order) is largest. E_c first draws only the worst quarter of its
/// regions ([`FIRST_ROUND`]) and goes on to the rest only where it buys paths for at least
/// half of those. The scene is then drawn again on that cut with those paths, and kept only if
/// it beats the fallback drawing of the full segmentation.
///
/// # Panics
/// If the scene already holds paths.
pub fn draw_coarse(
    coarse: &CoarseModel,
    config: &ModelConfig,
    scene: &mut Scene,
    fallback: FallbackDrawing,
    budget: CoarseBudget,
    batch: usize,
    device: &Device,
) {
    assert!(scene.is_empty(), "the coarse stage starts the drawing");
    let (target, segmentation) = (scene.target().clone(), scene.segmentation().clone());
    let spare = budget.paths.min(budget.total.saturating_sub(1 + fallback.order.len()));
    let wanted = match budget.trade {
        Some(_) => budget.paths.min(segmentation.regions.len().saturating_sub(1)),
        None => spare,
    };
    if wanted == 0 {
        *scene = fallback_only(&target, &segmentation, fallback);
        return;
    }
    let chosen = worst_regions(scene, &fallback, wanted);
    let mut proposals = vec![Vec::new(); fallback.order.len()];
    let propose_for = |regions: &[u32], proposals: &mut Vec<Vec<Path>>| {
        let crops: Vec<RegionCrop> =
            regions.iter().map(|&r| config.region_crop(&segmentation, &target, r)).collect();
        for (&region, paths) in
            regions.iter().zip(propose(coarse, &crops, target.dimensions(), batch, device))
        {
            proposals[region as usize] = paths;
        }
    };
    let Some(Trade { tolerance }) = budget.trade else {
        propose_for(&chosen, &mut proposals);
        let mut kept = paint_with(scene, &fallback, proposals);
        kept.sort_by(|a, b| b.gain.total_cmp(&a.gain));
        keep_best(scene, &kept, spare);
        if scene.counts().coarse == 0 || scene.total_error() > fallback.error {
            *scene = fallback_only(&target, &segmentation, fallback);
        }
        return;
    };
    let hierarchy = Hierarchy::new(&target, segmentation.clone());
    let regions = segmentation.regions.len();
    let price = |k: usize| hierarchy.flat_error(regions - k) - hierarchy.flat_error(regions);
    // E_c draws the worst regions first: where it buys paths for fewer than half of them, the
    // regions it gets less wrong would buy fewer still, and it stops there.
    let first = chosen.len().div_ceil(FIRST_ROUND);
    let mut asked = 0;
    let (kept, bought) = loop {
        let upto = if asked == 0 { first } else { chosen.len() };
        propose_for(&chosen[asked..upto], &mut proposals);
        asked = upto;
        *scene = Scene::new(target.clone(), segmentation.clone());
        let mut kept = paint_with(scene, &fallback, proposals.clone());
        kept.sort_by(|a, b| b.gain.total_cmp(&a.gain));
        let gains: Vec<f64> = kept.iter().take(wanted).map(|tried| tried.gain).collect();
        let bought = worth_their_regions(&gains, price);
        if asked == chosen.len() || 2 * bought < asked {
            break (kept, bought);
        }
    };
    if bought == 0 {
        *scene = fallback_only(&target, &segmentation, fallback);
        return;
    }
    let cut = hierarchy.cut(&target, regions - bought);
    let fine_to_cut = region_map(&segmentation, &cut);
    let mut bought: Vec<&Tried> = kept[..bought].iter().collect();
    bought.sort_by_key(|tried| tried.index);
    let mut proposals = vec![Vec::new(); cut.regions.len()];
    for tried in bought {
        proposals[fine_to_cut[tried.region as usize] as usize].push(tried.path);
    }
    let merged_fallback = FallbackDrawing::new(&target, &cut, tolerance);
    *scene = Scene::new(target.clone(), cut);
    paint_with(scene, &merged_fallback, proposals);
    if scene.counts().coarse == 0 || scene.total_error() > fallback.error {
        *scene = fallback_only(&target, &segmentation, fallback);
    }
}

/// With a [`Trade`], E_c first draws this fraction (one in so many) of the regions it may draw,
/// the worst: on data/eval's photos it buys paths for fewer than half of them and stops there
/// (a quarter of the E_c calls), while on the emoji, where it buys most, it goes on to the rest.
const FIRST_ROUND: usize = 4;

/// How many of the paths with `gains` (largest first) to buy when the k-th costs the merges
/// that free k regions (`merged(k)`: the error they add): the k with the largest gain less
/// cost, 0 when no k gains more than it costs.
fn worth_their_regions(gains: &[f64], merged: impl Fn(usize) -> f64) -> usize {
    let mut best = (0, 0.0);
    let mut gained = 0.0;
    for (k, gain) in gains.iter().enumerate() {
        gained += gain;
        let net = gained - merged(k + 1);
        if net > best.1 {
            best = (k + 1, net);
        }
    }
    best.0
}

/// The scene of `fallback` alone, the drawing of `segmentation` of `target`.
fn fallback_only(target: &Rgb32FImage, segmentation: &Segmentation, fallback: FallbackDrawing) -> Scene {
    Scene::drawn(target.clone(), segmentation.clone(), fallback.placed(), fallback.canvas)
}

/// An E_c path that lowered the error where it was tried.
struct Tried {
    /// Its place in the scene.
    index: usize,
    /// The error it took away.
    gain: f64,
    /// The region it was drawn for.
    region: u32,
    /// The path, in its fitted colour.
    path: Path,
}

/// Paints the background, then region after region of `fallback` in painter's order its
/// fallback path and each of `proposals[region]` that lowers the error over the regions painted
/// so far (in its least-squares colour); returns the E_c paths kept.
fn paint_with(scene: &mut Scene, fallback: &FallbackDrawing, mut proposals: Vec<Vec<Path>>) -> Vec<Tried> {
    scene.push(Placed { shape: fallback.background.into(), region: None, origin: Origin::Background });
    let mut painted = vec![false; fallback.order.len()];
    let mut kept = Vec::new();
    for (&region, shape) in fallback.order.iter().zip(&fallback.regions) {
        painted[region as usize] = true;
        if let Some(shape) = shape {
            scene.push(Placed { shape: shape.clone(), region: Some(region), origin: Origin::Fallback });
        }
        for path in std::mem::take(&mut proposals[region as usize]) {
            let scope = Scope::Regions(&painted);
            let path = scene.fit_colour(&path, scope).unwrap_or(path);
            let placed = Placed { shape: path.into(), region: Some(region), origin: Origin::Coarse };
            if let Some(gain) = scene.try_push(placed, scope) {
                kept.push(Tried { index: scene.len() - 1, gain, region, path });
            }
        }
    }
    kept
}

/// Drops every E_c path of `scene` but the `most` of `kept` (sorted by gain, largest first).
fn keep_best(scene: &mut Scene, kept: &[Tried], most: usize) {
    if kept.len() > most {
        let mut dropped = vec![false; scene.len()];
        for tried in &kept[most..] {
            dropped[tried.index] = true;
        }
        scene.retain(|index, _| !dropped[index]);
    }
}

/// For each region of `fine`, the region of `coarse` that holds it (`coarse` is a cut of a
/// hierarchy over `fine`, so each fine region lies in one).
fn region_map(fine: &Segmentation, coarse: &Segmentation) -> Vec<u32> {
    let mut map = vec![0; fine.regions.len()];
    for (&f, &c) in fine.labels.iter().zip(&coarse.labels) {
        map[f as usize] = c;
    }
    map
}

/// The `count` regions of `scene`'s image whose pixels `fallback` gets most wrong.
fn worst_regions(scene: &Scene, fallback: &FallbackDrawing, count: usize) -> Vec<u32> {
    let errors = region_errors(&fallback.canvas, scene.target(), scene.segmentation());
    let mut ranked: Vec<u32> = (0..errors.len() as u32).collect();
    worst_first(&mut ranked, &errors);
    ranked.truncate(count);
    ranked
}

/// E_c on every crop, `batch` at a time: each crop's visible paths, opaque, in the image's unit
/// square, in the model's painter's order.
fn propose(
    coarse: &CoarseModel,
    crops: &[RegionCrop],
    (width, height): (u32, u32),
    batch: usize,
    device: &Device,
) -> Vec<Vec<Path>> {
    let mut proposals = Vec::with_capacity(crops.len());
    for chunk in crops.chunks(batch.max(1)) {
        let scenes = coarse.forward(CropBatch::new(chunk, device).pixels).to_scenes();
        for (crop, scene) in chunk.iter().zip(scenes) {
            let visible = scene.into_iter().filter(Path::is_visible);
            proposals.push(
                visible.map(|path| crop_to_image(Path { alpha: 1.0, ..path }, crop, width, height)).collect(),
            );
        }
    }
    proposals
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_are_bought_while_they_gain_more_than_their_regions_cost() {
        let merges = [0.0, 2.0, 6.0, 20.0];
        let merged = |k: usize| merges[k];
        // Nets: 10 − 2 = 8, 15 − 6 = 9, 16 − 20 = −4.
        assert_eq!(worth_their_regions(&[10.0, 5.0, 1.0], merged), 2);
        assert_eq!(worth_their_regions(&[1.5, 1.0, 0.5], merged), 0, "no path beats its region");
        assert_eq!(worth_their_regions(&[], merged), 0);
        assert_eq!(worth_their_regions(&[30.0, 5.0, 4.0], |_| 0.0), 3, "free merges buy every path");
    }
}
