//! The coarse stage: the background, then region after region in painter's order its fallback
//! path and the coarse model's paths that draw it better; by default each such path is paid
//! for with a region ([`Trade`]), so E_c draws only where it beats spending the same paths on
//! regions.

use std::sync::Arc;

use burn::tensor::Device;
use image::Rgb32FImage;
use model::{CoarseModel, CropBatch, ModelConfig, crop_to_image};
use raster::{Path, Shape};
use superpixel::{Hierarchy, RegionCrop, Segmentation, worst_first};

use crate::fallback::FallbackDrawing;
use crate::scene::{Origin, Placed, Scene, Scope, region_errors};

/// How many paths the coarse stage may draw.
#[derive(Clone, Copy, Debug)]
pub struct CoarseBudget<'a> {
    /// The most E_c paths kept (0: E_c is not run).
    pub paths: usize,
    /// The most paths the scene may hold when the stage ends (background and fallbacks
    /// included; they are always drawn).
    pub total: usize,
    /// `None`: E_c draws only with what the regions leave of `total`. `Some`: E_c's paths are
    /// bought with regions ([`Trade`]).
    pub trade: Option<Trade<'a>>,
}

/// The networks' paths paid for with regions: the segmentation fills the budget, and each E_c
/// (or E_r, [`crate::refine::draw_refinement_traded`]) path kept takes the place of a region,
/// merged away where merging costs least. A path is worth its region only if it takes away
/// more error than the merge adds, so the networks draw only where they beat spending the same
/// paths on regions.
#[derive(Clone, Copy, Debug)]
pub struct Trade<'a> {
    /// The image's merge tree, of which the scene's segmentation is a cut: what merging
    /// regions away costs, and the regions left.
    pub hierarchy: &'a Hierarchy,
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
/// image's merge tree) is largest. E_c draws its regions in rounds, worst first: the first
/// [`FIRST_ROUND`], then each round as many again as all before it, while it buys paths for at
/// least half of the regions it has drawn. The scene is then drawn again on that cut with those paths, and kept only if
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
    let regions = segmentation.regions.len();
    let propose_for = |asked: &[u32]| {
        let crops: Vec<RegionCrop> =
            asked.iter().map(|&r| config.region_crop(&segmentation, &target, r)).collect();
        let mut proposals = vec![Vec::new(); regions];
        for (&region, paths) in asked.iter().zip(propose(coarse, &crops, target.dimensions(), batch, device))
        {
            proposals[region as usize] = paths;
        }
        proposals
    };
    let error = fallback.error;
    let order = fallback.order.clone();
    let alone = fallback_only(&target, &segmentation, fallback);
    *scene = alone.clone();
    let Some(Trade { hierarchy, tolerance }) = budget.trade else {
        let mut kept = paint_with(scene, &order, propose_for(&chosen));
        kept.sort_by(|a, b| b.gain.total_cmp(&a.gain));
        keep_best(scene, &kept, spare);
        settle(scene, alone, error);
        return;
    };
    let price = |k: usize| hierarchy.flat_error(regions - k) - hierarchy.flat_error(regions);
    // E_c draws the worst regions first: where it buys paths for fewer than half of them, the
    // regions it gets less wrong would buy fewer still, and it stops there.
    let (mut asked, mut kept) = (0, Vec::new());
    let bought = loop {
        let upto = if asked == 0 { FIRST_ROUND } else { 2 * asked }.min(chosen.len());
        kept.extend(paint_with(scene, &order, propose_for(&chosen[asked..upto])));
        asked = upto;
        kept.sort_by(|a, b| b.gain.total_cmp(&a.gain));
        let gains: Vec<f64> = kept.iter().take(wanted).map(|tried| tried.gain).collect();
        let bought = worth_their_regions(&gains, price);
        if asked == chosen.len() || 2 * bought < asked {
            break bought;
        }
    };
    if bought == 0 {
        *scene = alone;
        return;
    }
    let cut = Arc::new(hierarchy.cut(&target, regions - bought));
    let mut bought: Vec<(usize, &Tried)> =
        kept[..bought].iter().map(|tried| (tried.position(scene), tried)).collect();
    bought.sort_by_key(|(position, _)| *position);
    let bought = bought.into_iter().map(|(_, tried)| (tried.region, tried.path));
    *scene = draw_on_cut(&target, &segmentation, cut, tolerance, bought);
    settle(scene, alone, error);
}

/// `target` drawn on `cut`, a cut of the merge tree `fine` is a finer cut of: the fallback
/// drawing of `cut`, then E_c's `paths` (each with the region of `fine` it was drawn for, in
/// painter's order), each in the region of `cut` that holds its own and kept where it still
/// lowers the error ([`paint_with`]). How a drawing is made again when regions are merged away
/// to pay for paths.
pub(crate) fn draw_on_cut(
    target: &Arc<Rgb32FImage>,
    fine: &Segmentation,
    cut: Arc<Segmentation>,
    tolerance: Option<f32>,
    paths: impl IntoIterator<Item = (u32, Path)>,
) -> Scene {
    let fine_to_cut = region_map(fine, &cut);
    let mut proposals = vec![Vec::new(); cut.regions.len()];
    for (region, path) in paths {
        proposals[fine_to_cut[region as usize] as usize].push(path);
    }
    let merged = FallbackDrawing::new(target, &cut, tolerance);
    let order = merged.order.clone();
    let mut scene = fallback_only(target, &cut, merged);
    paint_with(&mut scene, &order, proposals);
    scene
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

/// With a [`Trade`], how many regions E_c draws first, the worst (each region is a crop E_c
/// draws, about 9 ms of a 2-core CPU): on data/eval's photos it buys paths for fewer than half
/// of them and stops there, while on the emoji, where it buys most, the rounds grow to every
/// region it may draw.
const FIRST_ROUND: usize = 8;

/// How many of the paths with `gains` (largest first) to buy when the k-th costs the merges
/// that free k regions (`merged(k)`: the error they add): the k with the largest gain less
/// cost, 0 when no k gains more than it costs.
pub(crate) fn worth_their_regions(gains: &[f64], merged: impl Fn(usize) -> f64) -> usize {
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
fn fallback_only(
    target: &Arc<Rgb32FImage>,
    segmentation: &Arc<Segmentation>,
    fallback: FallbackDrawing,
) -> Scene {
    Scene::drawn(target.clone(), segmentation.clone(), fallback.placed(), fallback.canvas)
}

/// An E_c path that lowered the error where it was tried.
struct Tried {
    /// The error it took away.
    gain: f64,
    /// The region it was drawn for.
    region: u32,
    /// The path, in its fitted colour.
    path: Path,
}

impl Tried {
    /// Its place in `scene`, which holds it.
    fn position(&self, scene: &Scene) -> usize {
        let shape = Shape::Path(self.path);
        scene
            .paths()
            .iter()
            .position(|placed| placed.region == Some(self.region) && placed.shape == shape)
            .expect("a path kept is in the scene")
    }
}

/// Tries each of `proposals[region]` on `scene`, a drawing whose regions come in painter's order
/// `order` (their fallback paths, and E_c paths kept before): a path goes in right after its
/// region's paths, in its least-squares colour over what is drawn, if it lowers the error over
/// the pixels of the regions up to its own (later regions cover the rest). It is judged painted
/// over the drawing as it is, later regions and all: over those pixels they differ from the
/// drawing at its place in painter's order only along their anti-aliased edges, and nothing is
/// painted again but, once per region, the boxes of the paths it kept. Returns the paths kept.
fn paint_with(scene: &mut Scene, order: &[u32], mut proposals: Vec<Vec<Path>>) -> Vec<Tried> {
    let mut painted = vec![false; order.len()];
    let mut kept = Vec::new();
    let mut next = 1; // past the background
    for &region in order {
        painted[region as usize] = true;
        while next < scene.len() && scene.paths()[next].region == Some(region) {
            next += 1;
        }
        let before = scene.len();
        for path in std::mem::take(&mut proposals[region as usize]) {
            let scope = Scope::Regions(&painted);
            let path = scene.fit_colour(&path, scope).unwrap_or(path);
            let placed = Placed { shape: path.into(), region: Some(region), origin: Origin::Coarse };
            if let Some(gain) = scene.try_push(placed, scope) {
                kept.push(Tried { gain, region, path });
            }
        }
        let added = scene.len() - before;
        scene.move_last(added, next);
        next += added;
    }
    kept
}

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

/// For each region of `fine`, the region of `coarse` that holds it (`coarse` is a cut of a
/// hierarchy over `fine`, so each fine region lies in one).
pub(crate) fn region_map(fine: &Segmentation, coarse: &Segmentation) -> Vec<u32> {
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
pub(crate) fn propose(
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
