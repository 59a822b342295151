//! The coarse stage: the background, then region after region in painter's order its fallback
//! path and the coarse model's paths that draw it better; by default each such path is paid
//! for with a region ([`Trade`]), so E_c draws only where it beats spending the same paths on
//! regions.

use std::sync::Arc;
use std::time::Instant;

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
    /// How merging regions away is priced.
    pub pricing: Pricing,
}

/// How a [`Trade`] prices merging regions away.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pricing {
    /// Ward's flat error of the merge tree ([`Hierarchy::flat_error`]): read for free, and
    /// close to what the drawing loses where the regions' colours vary within them (photos).
    Flat,
    /// Measured by drawing the merged regions: where the drawing's error is
    /// mostly its traced outlines' (flat art), which Ward's criterion does not see.
    Drawn,
}

impl Pricing {
    /// [`Pricing::Drawn`] where the regions' flat error (`flat`) is under [`FLAT_SHARE`] of
    /// the error of their fallback drawing (`drawn`): the rest is the traced outlines'.
    pub fn for_drawing(flat: f64, drawn: f64) -> Self {
        if flat < FLAT_SHARE * drawn { Pricing::Drawn } else { Pricing::Flat }
    }
}

/// Below this share of the fallback drawing's error, the regions' flat error leaves enough to
/// the traced outlines that merges must be priced by drawing them. On data/eval at 500 and
/// 2000 regions the share is 0.93–1.10 on the photos (where Ward's price and the drawn one
/// agree within a few per cent) and 0.60–0.72 on the emoji (where Ward's price is a hundredth
/// of the drawn one at 2000 paths, or twice it).
pub const FLAT_SHARE: f64 = 0.85;

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
/// gain less the cost of the merges that free k paths (priced as the trade's [`Pricing`]
/// says) is largest. E_c draws its regions in rounds, worst first:
/// the first [`FIRST_ROUND`], then each round as many again as all before it, while it buys
/// paths for at least half of the regions it has drawn. The scene is then drawn again on that
/// cut with those paths (the ones that gained least dropped where the cut frees fewer paths
/// than its prices read), and kept only if it beats the fallback drawing of the full
/// segmentation.
///
/// Returns the seconds E_c's forward passes took (cropping its regions and reading out its
/// paths included).
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
) -> f64 {
    assert!(scene.is_empty(), "the coarse stage starts the drawing");
    let (target, segmentation) = (scene.target().clone(), scene.segmentation().clone());
    let spare = budget.paths.min(budget.total.saturating_sub(1 + fallback.order.len()));
    let wanted = match budget.trade {
        Some(_) => budget.paths.min(segmentation.regions.len().saturating_sub(1)),
        None => spare,
    };
    if wanted == 0 {
        *scene = fallback_only(&target, &segmentation, fallback);
        return 0.0;
    }
    let chosen = worst_regions(scene, &fallback, wanted);
    let regions = segmentation.regions.len();
    let mut network = 0.0;
    let mut propose_for = |asked: &[u32]| {
        let clock = Instant::now();
        let crops: Vec<RegionCrop> =
            asked.iter().map(|&r| config.region_crop(&segmentation, &target, r)).collect();
        let mut proposals = vec![Vec::new(); regions];
        for (&region, paths) in asked.iter().zip(propose(coarse, &crops, target.dimensions(), batch, device))
        {
            proposals[region as usize] = paths;
        }
        network += clock.elapsed().as_secs_f64();
        proposals
    };
    let error = fallback.error;
    let order = fallback.order.clone();
    let alone = fallback_only(&target, &segmentation, fallback);
    *scene = alone.clone();
    let Some(trade) = budget.trade else {
        let mut kept = paint_with(scene, &order, propose_for(&chosen));
        kept.sort_by(|a, b| b.gain.total_cmp(&a.gain));
        keep_best(scene, &kept, spare);
        settle(scene, alone, error);
        return network;
    };
    let most = regions.saturating_sub(trade.hierarchy.fewest_regions());
    let mut prices = MergePrices::measured(&target, &segmentation, trade, most, (error, alone.len()));
    let mut worth = |kept: &[Tried]| {
        let gains: Vec<f64> = kept.iter().take(wanted).map(|tried| tried.gain).collect();
        prices.measure_to_free(&gains);
        let bought =
            worth_their_regions(&gains, |k| prices.to_free(k).map_or(f64::INFINITY, |(cost, _)| cost));
        (bought, prices.to_free(bought).map_or(0, |(_, merges)| merges))
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
        return network;
    }
    let cut = Arc::new(trade.hierarchy.cut(&target, regions - merges));
    let mut bought: Vec<(usize, &Tried)> =
        kept[..bought].iter().map(|tried| (tried.position(scene), tried)).collect();
    bought.sort_by_key(|(position, _)| *position);
    let bought = bought.into_iter().map(|(_, tried)| (tried.region, tried.path));
    let mut drawn;
    (*scene, drawn) = draw_on_cut(&target, &segmentation, cut, trade.tolerance, bought);
    // The prices are read between measured cuts: where this cut freed fewer paths than read,
    // the paths that gained least go.
    drawn.sort_by(|a, b| b.gain.total_cmp(&a.gain));
    keep_best(scene, &drawn, drawn.len().saturating_sub(scene.len().saturating_sub(budget.total)));
    settle(scene, alone, error);
    network
}

/// `target` drawn on `cut`, a cut of the merge tree `fine` is a finer cut of: the fallback
/// drawing of `cut`, then E_c's `paths` (each with the region of `fine` it was drawn for, in
/// painter's order), each in the region of `cut` that holds its own and kept where it still
/// lowers the error ([`paint_with`]), with the paths kept. How a drawing is made again when
/// regions are merged away to pay for paths.
pub(crate) fn draw_on_cut(
    target: &Arc<Rgb32FImage>,
    fine: &Segmentation,
    cut: Arc<Segmentation>,
    tolerance: Option<f32>,
    paths: impl IntoIterator<Item = (u32, Path)>,
) -> (Scene, Vec<Tried>) {
    let fine_to_cut = region_map(fine, &cut);
    let mut proposals = vec![Vec::new(); cut.regions.len()];
    for (region, path) in paths {
        proposals[fine_to_cut[region as usize] as usize].push(path);
    }
    let merged = FallbackDrawing::new(target, &cut, tolerance);
    let order = merged.order.clone();
    let mut scene = fallback_only(target, &cut, merged);
    let kept = paint_with(&mut scene, &order, proposals);
    (scene, kept)
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
pub const FIRST_ROUND: usize = 8;

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

/// What merging regions away costs a drawing ([`Pricing`]); with [`Pricing::Drawn`], measured
/// by drawing the cuts: the error the fallback drawing gains and the paths it frees. Ward's flat error
/// ([`Hierarchy::flat_error`]) misses both on flat art: there it is near zero while the traced
/// outlines of the merged regions draw measurably worse (an emoji at 2000 paths: 0.008
/// predicted, 0.81 drawn for 582 merges), and a region whose polygon lowered nothing frees no
/// path when merged away. A drawing costs about 13 ms at 1600 regions, so cuts are measured at
/// 1, 2, 4, … merges, as far as asked ([`MergePrices::measure_to_free`]), and read between.
pub(crate) struct MergePrices<'a> {
    target: &'a Arc<Rgb32FImage>,
    trade: Trade<'a>,
    /// Regions of the finest cut, the one measured against.
    regions: usize,
    /// The most merges measured.
    most: usize,
    /// The finest cut's fallback drawing: its error and its paths ([`Pricing::Drawn`] only).
    fine: (f64, usize),
    /// (merges, error added, paths freed), merges ascending from (0, 0, 0); measured with
    /// [`Pricing::Drawn`] only.
    points: Vec<(usize, f64, usize)>,
}

impl<'a> MergePrices<'a> {
    /// Prices for merging away up to `most` regions of `fine`, a cut of `trade`'s merge tree
    /// (drawing `fine` first if they are [`Pricing::Drawn`]).
    pub(crate) fn new(
        target: &'a Arc<Rgb32FImage>,
        fine: &Arc<Segmentation>,
        trade: Trade<'a>,
        most: usize,
    ) -> Self {
        let drawn = match trade.pricing {
            Pricing::Flat => (0.0, 0),
            Pricing::Drawn => {
                let drawing = FallbackDrawing::new(target, fine, trade.tolerance);
                (drawing.error, drawing.placed().len())
            }
        };
        Self::measured(target, fine, trade, most, drawn)
    }

    /// [`MergePrices::new`] where `fine`'s fallback drawing is known: its error and its paths.
    pub(crate) fn measured(
        target: &'a Arc<Rgb32FImage>,
        fine: &Arc<Segmentation>,
        trade: Trade<'a>,
        most: usize,
        drawn: (f64, usize),
    ) -> Self {
        Self { target, trade, regions: fine.regions.len(), most, fine: drawn, points: vec![(0, 0.0, 0)] }
    }

    /// Measures cuts until one frees a path for each of `gains` (the error each path to be
    /// paid for takes away, largest first), or adds more error than all of them take away
    /// (cuts with more merges cost more: none would pay), or `most` merges are measured.
    /// Nothing is measured with [`Pricing::Flat`].
    pub(crate) fn measure_to_free(&mut self, gains: &[f64]) {
        if self.trade.pricing == Pricing::Flat {
            return;
        }
        while let Some(&(merges, cost, freed)) = self.points.last()
            && freed < gains.len()
            && cost <= gains.iter().sum()
            && merges < self.most
        {
            let merges = (2 * merges).clamp(1, self.most);
            let cut = Arc::new(self.trade.hierarchy.cut(self.target, self.regions - merges));
            let drawing = FallbackDrawing::new(self.target, &cut, self.trade.tolerance);
            let freed = self.fine.1.saturating_sub(drawing.placed().len());
            self.points.push((merges, drawing.error - self.fine.0, freed));
        }
    }

    /// The error that freeing `paths` paths adds and the merges that free them: with
    /// [`Pricing::Flat`] one merge a path, priced by Ward's criterion; with [`Pricing::Drawn`]
    /// read linearly between the measured cuts. `None` where no cut (measured) frees that many.
    pub(crate) fn to_free(&self, paths: usize) -> Option<(f64, usize)> {
        if paths == 0 {
            return Some((0.0, 0));
        }
        if self.trade.pricing == Pricing::Flat {
            let hierarchy = self.trade.hierarchy;
            let cost =
                |merges| hierarchy.flat_error(self.regions - merges) - hierarchy.flat_error(self.regions);
            return (paths <= self.most).then(|| (cost(paths), paths));
        }
        let above = self.points.iter().position(|&(_, _, freed)| freed >= paths)?;
        let ((m0, c0, f0), (m1, c1, f1)) = (self.points[above - 1], self.points[above]);
        // Every cut before `above` frees fewer than `paths`: f0 < paths <= f1.
        let t = (paths - f0) as f64 / (f1 - f0) as f64;
        let merges = m0 + ((m1 - m0) as f64 * t).ceil() as usize;
        Some((c0 + (c1 - c0) * t, merges.min(m1)))
    }
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
pub(crate) struct Tried {
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

    fn quarters() -> (Arc<Rgb32FImage>, Arc<Segmentation>, Hierarchy) {
        let image = Arc::new(Rgb32FImage::from_fn(40, 40, |x, y| {
            image::Rgb([(x / 20) as f32 * 0.8, (y / 20) as f32 * 0.6, 0.3 + (x % 7) as f32 * 0.01])
        }));
        let hierarchy = crate::segmentation::hierarchy(&image, 16, 30.0).unwrap();
        let segmentation = Arc::new(hierarchy.cut(&image, 16));
        (image, segmentation, hierarchy)
    }

    #[test]
    fn drawn_prices_are_read_between_the_measured_cuts() {
        let (image, segmentation, hierarchy) = quarters();
        let trade = Trade { hierarchy: &hierarchy, tolerance: None, pricing: Pricing::Drawn };
        let mut prices = MergePrices::measured(&image, &segmentation, trade, 8, (1.0, 17));
        prices.points = vec![(0, 0.0, 0), (1, 0.5, 1), (2, 1.5, 1), (4, 2.0, 3)];
        assert_eq!(prices.to_free(0), Some((0.0, 0)));
        assert_eq!(prices.to_free(1), Some((0.5, 1)));
        // Past 2 merges (1 path freed) and short of 4 (3 freed): halfway for 2 paths.
        assert_eq!(prices.to_free(2), Some((1.75, 3)));
        assert_eq!(prices.to_free(4), None, "no measured cut frees 4 paths");
    }

    #[test]
    fn drawn_prices_are_the_fallback_drawings_of_the_cuts() {
        let (image, segmentation, hierarchy) = quarters();
        let trade = Trade { hierarchy: &hierarchy, tolerance: None, pricing: Pricing::Drawn };
        let regions = segmentation.regions.len();
        let mut prices = MergePrices::new(&image, &segmentation, trade, regions - 1);
        prices.measure_to_free(&[1e9; 5]);
        let fine = FallbackDrawing::new(&image, &segmentation, None);
        assert!(prices.points.len() > 2, "cuts measured: {:?}", prices.points);
        for &(merges, cost, freed) in &prices.points[1..] {
            let cut = Arc::new(hierarchy.cut(&image, regions - merges));
            let drawing = FallbackDrawing::new(&image, &cut, None);
            assert_eq!(cost, drawing.error - fine.error, "{merges} merges");
            assert_eq!(freed, fine.placed().len().saturating_sub(drawing.placed().len()), "{merges} merges");
        }
        let (&(merges, _, freed), _) = prices.points.split_last().unwrap();
        assert!(freed >= 5 || merges == regions - 1, "measured until 5 paths are freed: {:?}", prices.points);
        // Flat prices measure nothing and read Ward's criterion, one merge a path.
        let flat = Trade { pricing: Pricing::Flat, ..trade };
        let mut ward = MergePrices::new(&image, &segmentation, flat, regions - 1);
        ward.measure_to_free(&[1e9; 5]);
        assert_eq!(ward.points.len(), 1);
        let expected = hierarchy.flat_error(regions - 3) - hierarchy.flat_error(regions);
        assert_eq!(ward.to_free(3), Some((expected, 3)));
    }

    #[test]
    fn merges_are_drawn_where_the_outlines_hold_much_of_the_error() {
        assert_eq!(Pricing::for_drawing(9.5, 10.0), Pricing::Flat);
        assert_eq!(Pricing::for_drawing(10.5, 10.0), Pricing::Flat, "antialiasing can draw below flat");
        assert_eq!(Pricing::for_drawing(6.5, 10.0), Pricing::Drawn);
    }
}
