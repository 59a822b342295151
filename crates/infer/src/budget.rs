//! What a job's paths buy, in one place: how many paths ([`PathBudget`], chosen per image for
//! an automatic budget), how many regions they cut the image into, what E_c and E_r may take
//! (the operating point), and the market where their paths are paid for with regions.
//!
//! A [`BudgetPlan`] is made once per job from the job, the models and the image. By default
//! the regions fill the budget less E_r's share, and a network's path is bought with a region
//! only where it takes away more error than merging that region away adds: the [`Market`]
//! prices merges ([`Pricing`]: Ward's criterion off the merge tree, or by drawing the merged
//! cut) and both network stages buy through it, then draw the scene again on the coarser
//! cut. A given `--regions` fixes the split: no market.

use std::sync::Arc;

use image::Rgb32FImage;
use model::OperatingPoint;
use raster::Path;
use superpixel::{Hierarchy, RegionFill, Segmentation, SlicError};

use crate::fallback::{FallbackDrawing, Style};
use crate::fills::{RAMP_BYTES, REGION_BYTES, Ramps};
use crate::job::{AutoRule, Fills, Job, MAX_PATHS, PathBudget, Refiner, Split, Warning};
use crate::models::Models;
use crate::scene::{Scene, Tried, paint_with};
use crate::segmentation::{hierarchy, max_regions};

/// How a job's budget is spent on one image, decided before anything is drawn.
#[derive(Clone, Debug)]
pub struct BudgetPlan {
    /// The most paths (what an automatic budget chose).
    pub paths: usize,
    /// Whether the budget was chosen automatically.
    pub auto: bool,
    /// The operating point in force: the job's or the models' own, with no share for E_r
    /// when there is none ([`BudgetPlan::point`]).
    pub point: OperatingPoint,
    /// The regions the image is cut into.
    pub regions: usize,
    /// How the regions are drawn: the tolerance (the job's, or curves for flat art under an
    /// automatic budget) and the fills ([`Job::fills_for`], ramps priced at the cut).
    pub style: Style,
    /// Whether the networks' paths are bought with regions ([`Market`]): unless the job fixed
    /// the region count.
    pub traded: bool,
}

impl BudgetPlan {
    /// The plan for `job` (valid: [`Job::validate`]) with `models` on `image`, with the merge
    /// tree it measured (its cut at [`BudgetPlan::regions`] is the drawing's segmentation) and
    /// what it had to do differently from what the job asked.
    pub fn new(
        job: &Job,
        models: &Models,
        image: &Rgb32FImage,
    ) -> Result<(Self, Hierarchy, Vec<Warning>), SlicError> {
        let (width, height) = image.dimensions();
        let point = Self::point(job, models);
        let most = max_regions(width, height);
        let mut warnings = Vec::new();
        let (paths, regions, tree, tolerance, fills) = match job.paths {
            PathBudget::Count(paths) => {
                // Unless told how many, the regions fill what E_r's share leaves, and E_c and E_r
                // buy their paths from them.
                let asked = job.regions.unwrap_or_else(|| point.filling_regions(paths)).clamp(1, paths - 1);
                // Only a count the user gave is said to be lowered: the default fills the budget.
                if asked > most && job.regions.is_some() {
                    warnings.push(Warning::RegionsLowered { asked, used: most, width, height });
                }
                let regions = asked.min(most);
                let tree = hierarchy(image, regions, job.compactness)?;
                // Flat art as an automatic budget judges it; a tree made for fewer regions
                // than the test reads (a budget under its paths) is too coarse to tell.
                let fills = job.fills_for(|| {
                    let rule = AutoRule::default();
                    let test = flat_art_regions(image, &point, &rule);
                    Ok::<_, SlicError>(if regions >= test {
                        is_flat_art(&tree, image, &point, &rule)
                    } else {
                        is_flat_art(&hierarchy(image, test, job.compactness)?, image, &point, &rule)
                    })
                })?;
                (paths, regions, tree, job.tolerance, fills)
            }
            PathBudget::Auto(rule) => {
                let choice = auto_budget(image, &point, job.compactness, &rule)?;
                let tolerance = job.tolerance.or(choice.flat.then_some(rule.flat_tolerance));
                let fills = job.fills_for(|| Ok::<_, SlicError>(choice.flat))?;
                (choice.paths, choice.regions, choice.hierarchy, tolerance, fills)
            }
        };
        let auto = matches!(job.paths, PathBudget::Auto(_));
        // Regions that may be ramps are merged as such: the same base merged again, a ramp
        // priced at the bytes it costs, in what a region's bytes take away on Ward's tree.
        let (ramps, tree) = match fills {
            Fills::Flat => (Ramps::None, tree),
            fills => {
                let region_worth = region_worth(&tree, regions);
                let price = region_worth * RAMP_BYTES / REGION_BYTES;
                let tree = tree.refilled(image, RegionFill::Ramp { price }, RAMP_MERGES_FROM * regions);
                let ramps =
                    if fills == Fills::Linear { Ramps::Every } else { Ramps::Paying { region_worth } };
                (ramps, tree)
            }
        };
        let style = Style { tolerance, ramps };
        let plan = Self { paths, auto, point, regions, style, traded: job.regions.is_none() };
        Ok((plan, tree, warnings))
    }

    /// The operating point `job` uses: the one given, else the models' own, with no share
    /// kept for E_r when there is none (and no optimizer in its place). The paper's inference
    /// has none; it reads as the stored one here.
    pub fn point(job: &Job, models: &Models) -> OperatingPoint {
        let mut point = match job.operating_point {
            Split::Point(point) => point,
            Split::Stored | Split::Paper => models.operating_point,
        };
        if models.refine.is_none() && job.refiner == Refiner::Network {
            point.refine_share = 0.0;
        }
        point
    }

    /// What the coarse stage may draw, trading through `market` when the plan trades.
    pub fn coarse<'a>(&self, market: Option<Market<'a>>) -> CoarseShare<'a> {
        CoarseShare {
            paths: self.point.coarse_paths(self.paths),
            total: self.paths - self.point.reserved_for_refine(self.paths),
            market: market.filter(|_| self.traded),
        }
    }
}

/// How many paths the coarse stage may draw.
#[derive(Clone, Copy, Debug)]
pub struct CoarseShare<'a> {
    /// The most E_c paths kept (0: E_c is not run).
    pub paths: usize,
    /// The most paths the scene may hold when the stage ends (background and fallbacks
    /// included; they are always drawn).
    pub total: usize,
    /// `None`: E_c draws only with what the regions leave of `total`. `Some`: E_c's paths are
    /// bought with regions.
    pub market: Option<Market<'a>>,
}

/// The smallest budget the automatic ladder starts from: the background and 7 regions.
const AUTO_FIRST: usize = 8;

/// With ramps, Ward's merges are kept down to this many times the drawn regions and the rest
/// are merged again knowing that regions may be ramps: below it a ramp rarely pays for its price
/// (the merges agree), and merging the fine cells again is most of the second tree's time.
const RAMP_MERGES_FROM: usize = 2;

/// The squared error one region takes away at the cut of `tree` into `regions` regions: the
/// mean of what the merges down to an eighth fewer regions (at least one) add, a merge each.
fn region_worth(tree: &Hierarchy, regions: usize) -> f64 {
    let coarser = regions.saturating_sub((regions / 8).max(1)).max(tree.fewest_regions());
    if coarser >= regions {
        return 0.0;
    }
    (tree.fill_error(coarser) - tree.fill_error(regions)).max(0.0) / (regions - coarser) as f64
}

/// The automatic budget measures budgets up to this many paths on one merge tree made for it;
/// a picture that climbs past it gets one more, made for the ceiling, for every larger rung.
/// One tree for the ceiling alone would serve every rung, but pictures that stop early (flat
/// art stops at tens of paths) would pay for an over-segmentation eight times the ceiling.
pub const AUTO_STAGE: usize = 256;

/// The budget [`auto_budget`] chose, and the merge tree to cut for it.
pub struct AutoChoice {
    /// Paths.
    pub paths: usize,
    /// Regions for those paths (as the operating point fills them).
    pub regions: usize,
    /// The tree the budget was measured on, made for at least `regions` regions.
    pub hierarchy: Hierarchy,
    /// Whether the picture is flat art: its regions filled flat reached the target within
    /// [`AutoRule::flat_paths`].
    pub flat: bool,
}

/// A path budget for `image` by `rule`, at most `rule.max_paths` (and [`MAX_PATHS`]): budgets
/// 8, 16, 32, … are measured until one reaches `rule.target_psnr` or the ceiling, and the
/// smallest from which no larger measured budget gains `rule.min_gain` per doubling on average
/// is chosen. A budget is measured by the squared error of its regions (as many as `point`
/// gives it) each filled with its mean colour, read off the image's merge tree
/// ([`hierarchy`]): about what the fallback drawing of those regions draws, without tracing or
/// rendering any. Rungs up to [`AUTO_STAGE`] paths are read off one tree made for it, larger
/// rungs off one made for the ceiling. An early plateau (a few regions cannot yet follow fine
/// detail) does not stop the climb.
pub fn auto_budget(
    image: &Rgb32FImage,
    point: &OperatingPoint,
    compactness: f32,
    rule: &AutoRule,
) -> Result<AutoChoice, SlicError> {
    let max_paths = rule.max_paths.clamp(2, MAX_PATHS);
    let most = max_regions(image.width(), image.height());
    let regions_for = |paths: usize| regions_of(point, paths, image);
    let tree_for = |paths: usize| hierarchy(image, regions_for(paths), compactness);
    let mut tree = (AUTO_STAGE.min(max_paths), tree_for(AUTO_STAGE.min(max_paths))?);
    let flat = is_flat_art(&tree.1, image, point, rule);
    let mut ladder: Vec<(usize, f64)> = Vec::new();
    let mut paths = AUTO_FIRST.min(max_paths);
    loop {
        if paths > tree.0 {
            tree = (max_paths, tree_for(max_paths)?);
        }
        let value = flat_psnr(tree.1.fill_error(regions_for(paths)), image);
        ladder.push((paths, value));
        if value >= rule.target_psnr || paths == max_paths || regions_for(paths) == most {
            break;
        }
        paths = (paths * 2).min(max_paths);
    }
    let pays = |(fewer, low): (usize, f64), (more, high): (usize, f64)| {
        high - low >= rule.min_gain * (more as f64 / fewer as f64).log2()
    };
    let knee = (0..ladder.len()).find(|&i| ladder[i + 1..].iter().all(|&later| !pays(ladder[i], later)));
    let paths = ladder[knee.unwrap_or(ladder.len() - 1)].0;
    Ok(AutoChoice { paths, regions: regions_for(paths), hierarchy: tree.1, flat })
}

/// Whether `image` is flat art by `rule`, read off its merge tree `tree`: its regions filled
/// flat reach `rule.target_psnr` within `rule.flat_paths` paths (as `point` splits them). Flat
/// art is drawn with curves under an automatic budget ([`AutoChoice::flat`]) and in flat
/// fills by default at any budget ([`Job::fills_for`]).
fn is_flat_art(tree: &Hierarchy, image: &Rgb32FImage, point: &OperatingPoint, rule: &AutoRule) -> bool {
    flat_psnr(tree.fill_error(flat_art_regions(image, point, rule)), image) >= rule.target_psnr
}

/// The regions [`is_flat_art`] reads: those of `rule.flat_paths` paths, as `point` splits them.
fn flat_art_regions(image: &Rgb32FImage, point: &OperatingPoint, rule: &AutoRule) -> usize {
    regions_of(point, rule.flat_paths.max(2), image)
}

/// The regions `paths` paths (at least 2) hold as `point` splits them: at least one, fewer than
/// the paths, and at most `image`'s [`max_regions`].
fn regions_of(point: &OperatingPoint, paths: usize, image: &Rgb32FImage) -> usize {
    point.filling_regions(paths).clamp(1, paths - 1).min(max_regions(image.width(), image.height()))
}

/// The PSNR (dB) of a flat fill of `image` whose squared RGB error, summed over its pixels, is
/// `error` ([`Hierarchy::fill_error`]).
fn flat_psnr(error: f64, image: &Rgb32FImage) -> f64 {
    common::psnr_of_mse(error / (3 * image.width() as usize * image.height() as usize) as f64)
}

/// Where the networks' paths are paid for with regions: the segmentation fills the budget,
/// and each E_c or E_r path kept takes the place of a region, merged away where merging costs
/// least. A path is worth its region only if it takes away more error than the merge adds, so
/// the networks draw only where they beat spending the same paths on regions.
#[derive(Clone, Copy, Debug)]
pub struct Market<'a> {
    /// The image's merge tree, of which the scene's segmentation is a cut: what merging
    /// regions away costs, and the regions left.
    pub hierarchy: &'a Hierarchy,
    /// How the fallback drawing of the merged regions is drawn (as [`FallbackDrawing::new`]
    /// takes it).
    pub style: Style,
    /// How merging regions away is priced.
    pub pricing: Pricing,
}

impl<'a> Market<'a> {
    /// The market for `fallback`, the fallback drawing of `segmentation` (a cut of
    /// `hierarchy`), drawn in `style`: priced as [`Pricing::for_drawing`] says.
    pub fn for_drawing(
        hierarchy: &'a Hierarchy,
        segmentation: &Segmentation,
        fallback: &FallbackDrawing,
        style: Style,
    ) -> Self {
        let pricing = Pricing::for_drawing(hierarchy.fill_error(segmentation.regions.len()), fallback.error);
        Self { hierarchy, style, pricing }
    }

    /// `target` drawn again on the cut of the merge tree with `regions` regions, coarser than
    /// `fine`, the cut it was drawn on: the fallback drawing of the cut, then E_c's `paths`
    /// (each with the region of `fine` it was drawn for, in painter's order), each in the region
    /// of the cut that holds its own and kept where it still lowers the error ([`paint_with`]),
    /// with the paths kept. How a drawing is made again when regions are merged away to pay for
    /// paths.
    pub(crate) fn redraw(
        &self,
        target: &Arc<Rgb32FImage>,
        fine: &Segmentation,
        regions: usize,
        paths: impl IntoIterator<Item = (u32, Path)>,
    ) -> (Scene, Vec<Tried>) {
        let cut = Arc::new(self.hierarchy.cut(target, regions));
        let fine_to_cut = region_map(fine, &cut);
        let mut proposals = vec![Vec::new(); cut.regions.len()];
        for (region, path) in paths {
            proposals[fine_to_cut[region as usize] as usize].push(path);
        }
        let merged = FallbackDrawing::new(target, &cut, self.style);
        let order = merged.order.clone();
        let mut scene = merged.into_scene(target, &cut);
        let kept = paint_with(&mut scene, &order, proposals);
        (scene, kept)
    }
}

/// How a [`Market`] prices merging regions away.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pricing {
    /// The merge tree's error ([`Hierarchy::fill_error`], Ward's where regions are flat): read
    /// for free, and close to what the drawing loses where the regions' colours vary within
    /// them (photos).
    Flat,
    /// Measured by drawing the merged regions: where the drawing's error is mostly its traced
    /// outlines' (flat art), which Ward's criterion does not see.
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
/// the traced outlines that merges must be priced by drawing them: photos sit near 1, where
/// Ward's price and the drawn one agree, flat art well below (docs/method.md has the shares).
pub const FLAT_SHARE: f64 = 0.85;

/// For each region of `fine`, the region of `coarse` that holds it (`coarse` is a cut of a
/// hierarchy over `fine`, so each fine region lies in one).
pub(crate) fn region_map(fine: &Segmentation, coarse: &Segmentation) -> Vec<u32> {
    let mut map = vec![0; fine.regions.len()];
    for (&f, &c) in fine.labels.iter().zip(&coarse.labels) {
        map[f as usize] = c;
    }
    map
}

/// What merging regions away costs one drawing ([`Pricing`]); with [`Pricing::Drawn`],
/// measured by drawing the cuts: the error the fallback drawing gains and the paths it frees.
/// Ward's flat error misses both on flat art: there it is near zero while the traced outlines
/// of the merged regions draw measurably worse, and a region whose polygon lowered nothing
/// frees no path when merged away. Cuts are measured at 1, 2, 4, … merges, as far as asked
/// ([`Prices::buy`]), and read between.
pub(crate) struct Prices<'a> {
    target: &'a Arc<Rgb32FImage>,
    market: Market<'a>,
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

impl<'a> Prices<'a> {
    /// Prices for merging away up to `most` regions of `fine`, a cut of `market`'s merge tree
    /// (drawing `fine` first if they are [`Pricing::Drawn`]).
    pub(crate) fn new(
        target: &'a Arc<Rgb32FImage>,
        fine: &Arc<Segmentation>,
        market: Market<'a>,
        most: usize,
    ) -> Self {
        let drawn = match market.pricing {
            Pricing::Flat => (0.0, 0),
            Pricing::Drawn => {
                let drawing = FallbackDrawing::new(target, fine, market.style);
                (drawing.error, drawing.placed().len())
            }
        };
        Self::measured(target, fine, market, most, drawn)
    }

    /// [`Prices::new`] where `fine`'s fallback drawing is known: its error and its paths.
    pub(crate) fn measured(
        target: &'a Arc<Rgb32FImage>,
        fine: &Arc<Segmentation>,
        market: Market<'a>,
        most: usize,
        drawn: (f64, usize),
    ) -> Self {
        Self { target, market, regions: fine.regions.len(), most, fine: drawn, points: vec![(0, 0.0, 0)] }
    }

    /// How many of the paths with `gains` (the error each takes away, largest first) to buy
    /// when the first `free` cost nothing and each one past them costs a region: the k with
    /// the largest gain less the cost of the merges that free k − `free` regions, 0 when no k
    /// gains more than it costs. Measures as many cuts as that needs.
    pub(crate) fn buy(&mut self, gains: &[f64], free: usize) -> usize {
        self.measure_to_free(gains.get(free..).unwrap_or_default());
        worth_their_regions(gains, |k| {
            self.to_free(k.saturating_sub(free)).map_or(f64::INFINITY, |(cost, _)| cost)
        })
    }

    /// The merges that free `paths` paths (0 where no measured cut frees that many).
    pub(crate) fn merges_to_free(&self, paths: usize) -> usize {
        self.to_free(paths).map_or(0, |(_, merges)| merges)
    }

    /// Measures cuts until one frees a path for each of `gains` (the error each path to be
    /// paid for takes away, largest first), or adds more error than all of them take away
    /// (cuts with more merges cost more: none would pay), or `most` merges are measured.
    /// Nothing is measured with [`Pricing::Flat`].
    fn measure_to_free(&mut self, gains: &[f64]) {
        if self.market.pricing == Pricing::Flat {
            return;
        }
        while let Some(&(merges, cost, freed)) = self.points.last()
            && freed < gains.len()
            && cost <= gains.iter().sum()
            && merges < self.most
        {
            let merges = (2 * merges).clamp(1, self.most);
            let cut = Arc::new(self.market.hierarchy.cut(self.target, self.regions - merges));
            let drawing = FallbackDrawing::new(self.target, &cut, self.market.style);
            let freed = self.fine.1.saturating_sub(drawing.placed().len());
            self.points.push((merges, drawing.error - self.fine.0, freed));
        }
    }

    /// The error that freeing `paths` paths adds and the merges that free them: with
    /// [`Pricing::Flat`] one merge a path, priced by Ward's criterion; with [`Pricing::Drawn`]
    /// read linearly between the measured cuts. `None` where no cut (measured) frees that many.
    fn to_free(&self, paths: usize) -> Option<(f64, usize)> {
        if paths == 0 {
            return Some((0.0, 0));
        }
        if self.market.pricing == Pricing::Flat {
            let hierarchy = self.market.hierarchy;
            let cost =
                |merges| hierarchy.fill_error(self.regions - merges) - hierarchy.fill_error(self.regions);
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

#[cfg(test)]
mod tests {
    use image::Rgb;

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
            Rgb([(x / 20) as f32 * 0.8, (y / 20) as f32 * 0.6, 0.3 + (x % 7) as f32 * 0.01])
        }));
        let hierarchy = hierarchy(&image, 16, 30.0).unwrap();
        let segmentation = Arc::new(hierarchy.cut(&image, 16));
        (image, segmentation, hierarchy)
    }

    #[test]
    fn drawn_prices_are_read_between_the_measured_cuts() {
        let (image, segmentation, hierarchy) = quarters();
        let market = Market { hierarchy: &hierarchy, style: Style::default(), pricing: Pricing::Drawn };
        let mut prices = Prices::measured(&image, &segmentation, market, 8, (1.0, 17));
        prices.points = vec![(0, 0.0, 0), (1, 0.5, 1), (2, 1.5, 1), (4, 2.0, 3)];
        assert_eq!(prices.to_free(0), Some((0.0, 0)));
        assert_eq!(prices.to_free(1), Some((0.5, 1)));
        // Past 2 merges (1 path freed) and short of 4 (3 freed): halfway for 2 paths.
        assert_eq!(prices.to_free(2), Some((1.75, 3)));
        assert_eq!(prices.to_free(4), None, "no measured cut frees 4 paths");
        assert_eq!(prices.merges_to_free(4), 0);
        // Free paths cost nothing; the fourth costs the first merge's 0.5, the fifth 1.75.
        assert_eq!(prices.buy(&[3.0, 2.0, 1.0, 0.6, 0.4], 3), 4);
    }

    #[test]
    fn drawn_prices_are_the_fallback_drawings_of_the_cuts() {
        let (image, segmentation, hierarchy) = quarters();
        let market = Market { hierarchy: &hierarchy, style: Style::default(), pricing: Pricing::Drawn };
        let regions = segmentation.regions.len();
        let mut prices = Prices::new(&image, &segmentation, market, regions - 1);
        prices.measure_to_free(&[1e9; 5]);
        let fine = FallbackDrawing::new(&image, &segmentation, Style::default());
        assert!(prices.points.len() > 2, "cuts measured: {:?}", prices.points);
        for &(merges, cost, freed) in &prices.points[1..] {
            let cut = Arc::new(hierarchy.cut(&image, regions - merges));
            let drawing = FallbackDrawing::new(&image, &cut, Style::default());
            assert_eq!(cost, drawing.error - fine.error, "{merges} merges");
            assert_eq!(freed, fine.placed().len().saturating_sub(drawing.placed().len()), "{merges} merges");
        }
        let (&(merges, _, freed), _) = prices.points.split_last().unwrap();
        assert!(freed >= 5 || merges == regions - 1, "measured until 5 paths are freed: {:?}", prices.points);
        // Flat prices measure nothing and read Ward's criterion, one merge a path.
        let flat = Market { pricing: Pricing::Flat, ..market };
        let mut ward = Prices::new(&image, &segmentation, flat, regions - 1);
        ward.measure_to_free(&[1e9; 5]);
        assert_eq!(ward.points.len(), 1);
        let expected = hierarchy.fill_error(regions - 3) - hierarchy.fill_error(regions);
        assert_eq!(ward.to_free(3), Some((expected, 3)));
    }

    #[test]
    fn merges_are_drawn_where_the_outlines_hold_much_of_the_error() {
        assert_eq!(Pricing::for_drawing(9.5, 10.0), Pricing::Flat);
        assert_eq!(Pricing::for_drawing(10.5, 10.0), Pricing::Flat, "antialiasing can draw below flat");
        assert_eq!(Pricing::for_drawing(6.5, 10.0), Pricing::Drawn);
    }

    /// `cells × cells` squares of `side` pixels in colours drawn from `seed`.
    fn blocks(cells: u32, side: u32, seed: u32) -> Rgb32FImage {
        let colour =
            |i: u32, c: u32| ((i.wrapping_mul(2_654_435_761) ^ (seed + c * 97)) % 251) as f32 / 250.0;
        Rgb32FImage::from_fn(cells * side, cells * side, |x, y| {
            let i = (y / side) * cells + x / side;
            Rgb([colour(i, 0), colour(i, 1), colour(i, 2)])
        })
    }

    #[test]
    fn auto_budget_stops_early_on_flat_art_and_climbs_on_detail() {
        let point = OperatingPoint::default();
        let rule = AutoRule::default();
        let two_colours = blocks(2, 48, 1);
        let few = auto_budget(&two_colours, &point, 30.0, &rule).unwrap();
        assert_eq!(few.paths, AUTO_FIRST, "four flat squares need no more than the first rung");
        assert_eq!(few.regions, point.filling_regions(AUTO_FIRST), "the budget's regions");
        // Its tree starts from the four squares (areas of one colour): fewer than the budget's
        // regions, and all it needs.
        assert_eq!(few.hierarchy.most_regions(), 4, "the squares are the tree's base");
        assert!(few.hierarchy.fill_error(4) < 1e-4, "each square its own colour");
        assert!(few.flat, "four flat squares are flat art");
        let detailed = blocks(16, 8, 2);
        let many = auto_budget(&detailed, &point, 30.0, &rule).unwrap();
        assert!(many.paths >= 128, "256 flat squares got only {} paths", many.paths);
        assert!(many.paths <= rule.max_paths);
        assert!(!many.flat, "flat colours that need {} paths are drawn as photos are", many.paths);
        // Noise no count of flat regions draws at 30 dB: not flat art.
        let noise = Rgb32FImage::from_fn(64, 64, |x, y| {
            let v = |c: u32| {
                ((x * 7919 + y * 104_729 + c * 1299).wrapping_mul(2_654_435_761) % 1000) as f32 / 1000.0
            };
            Rgb([v(0), v(1), v(2)])
        });
        assert!(!auto_budget(&noise, &point, 30.0, &rule).unwrap().flat, "noise is no flat art");
    }

    #[test]
    fn auto_budget_keeps_to_its_ceiling() {
        let greedy = AutoRule {
            target_psnr: f64::INFINITY,
            min_gain: f64::NEG_INFINITY,
            max_paths: 40,
            ..Default::default()
        };
        let choice = auto_budget(&blocks(16, 8, 3), &OperatingPoint::default(), 30.0, &greedy).unwrap();
        assert_eq!(choice.paths, 40);
    }

    /// Redrawn on a coarser cut, a drawing has that cut's regions and its fallback drawing's
    /// paths; E_c's paths are painted in the regions that hold theirs.
    #[test]
    fn a_redrawn_scene_is_the_coarser_cuts_drawing() {
        let (image, fine, hierarchy) = quarters();
        let market = Market { hierarchy: &hierarchy, style: Style::default(), pricing: Pricing::Flat };
        let (scene, kept) = market.redraw(&image, &fine, 4, std::iter::empty());
        assert_eq!(scene.segmentation().regions.len(), 4);
        assert!(kept.is_empty());
        let cut = Arc::new(hierarchy.cut(&image, 4));
        assert_eq!(scene.paths(), FallbackDrawing::new(&image, &cut, Style::default()).placed());
        // Each fine region maps to the one of the cut that holds its pixels.
        let map = region_map(&fine, &cut);
        for (&f, &c) in fine.labels.iter().zip(&cut.labels) {
            assert_eq!(map[f as usize], c);
        }
    }
}
