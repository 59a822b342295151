//! The first stage: how an image is split into regions, and how many paths `--paths auto`
//! gives it.
//!
//! An image is over-segmented once and merged bottom-up into a tree ([`hierarchy`],
//! [`superpixel::Hierarchy`]): every region count is a cut of it, and the error of each cut's
//! flat fill is known without drawing it. A fixed budget cuts it at its region count; the
//! automatic budget reads every rung's error off it and cuts it where it stops; the coarse
//! stage prices the regions it merges away for E_c's paths on it.

use std::sync::Arc;

use image::Rgb32FImage;
use model::OperatingPoint;
use superpixel::{Hierarchy, SegmentOptions, Segmentation, SlicError};

use crate::fallback::FallbackDrawing;

/// The fewest pixels per region: SLIC cannot place centres closer than 4 × 4 pixels
/// meaningfully, and one path per pixel would only copy the raster.
pub const PIXELS_PER_REGION: usize = 16;

/// The most regions an image of `width × height` pixels is split into ([`PIXELS_PER_REGION`]).
pub fn max_regions(width: u32, height: u32) -> usize {
    (width as usize * height as usize / PIXELS_PER_REGION).max(1)
}

/// An image's regions for a budget: the merge tree of its over-segmentation, the cut of it that
/// is drawn, and that cut's fallback drawing (traced, rendered and scored once).
pub struct Segmented {
    /// Every region count of the image, as Ward's merges reach it: the coarse stage prices
    /// the regions it merges away to make room for E_c's paths with it, and cuts it again.
    pub hierarchy: Hierarchy,
    /// The regions drawn.
    pub segmentation: Arc<Segmentation>,
    /// Each region's outline in its mean colour over the background, with its rendering.
    pub fallback: FallbackDrawing,
}

impl Segmented {
    /// `image` split into `regions` regions of `hierarchy` (made on `image`), with its fallback
    /// drawing (boundaries fitted within `tolerance` pixels, if given).
    pub fn new(
        image: &Arc<Rgb32FImage>,
        hierarchy: Hierarchy,
        regions: usize,
        tolerance: Option<f32>,
    ) -> Self {
        let segmentation = Arc::new(hierarchy.cut(image, regions));
        let fallback = FallbackDrawing::new(image, &segmentation, tolerance);
        Self { hierarchy, segmentation, fallback }
    }
}

/// The merge tree of `image` for up to `regions` regions: the over-segmentation
/// [`SegmentOptions::ward`] makes at `compactness` (flat art's areas of one colour, else SLIC),
/// merged down to one region.
pub fn hierarchy(image: &Rgb32FImage, regions: usize, compactness: f32) -> Result<Hierarchy, SlicError> {
    let base = SegmentOptions::ward(compactness).over_segment(image, regions)?;
    Ok(Hierarchy::new(image, base))
}

/// The PSNR (dB) of a flat fill of `image` whose squared RGB error, summed over its pixels, is
/// `error` ([`Hierarchy::flat_error`]).
fn flat_psnr(error: f64, image: &Rgb32FImage) -> f64 {
    common::psnr_of_mse(error / (3 * image.width() as usize * image.height() as usize) as f64)
}

/// How [`auto_budget`] picks a path budget for an image: the fewest paths that are close enough
/// to the image, or past which more paths stop paying.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AutoBudget {
    /// Close enough: the PSNR (dB) at which no more paths are added.
    pub target_psnr: f64,
    /// Paying: the gain (dB) per doubling of the paths that more paths must bring, on average
    /// over every larger budget measured.
    pub min_gain: f64,
    /// The most paths.
    pub max_paths: usize,
    /// Flat art (a picture whose regions filled flat reach `target_psnr` within `flat_paths`)
    /// has its regions drawn along shared boundary curves fitted within this many pixels
    /// (`Job::tolerance`), when the job names no tolerance: at the few tens of paths such a
    /// picture gets, curves take fewer bytes than traced polygons and draw its edges better.
    pub flat_tolerance: f32,
    /// The most paths at which a picture that reaches `target_psnr` counts as flat art. Past
    /// a few tens of paths traced polygons draw more than curves at their size, and photos
    /// with smooth areas reach the target there too.
    pub flat_paths: usize,
}

impl Default for AutoBudget {
    /// 30 dB is where flat art looks drawn, not approximated. 0.25 dB per doubling keeps a
    /// textured photo climbing (the baboon of data/eval gains about 0.45 dB per doubling from 8
    /// to 500 paths; at 0.5 it stopped at 8 paths and 16.5 dB) while a flat picture, whose
    /// regions gain nothing from more of them, stays at 8. 2000 is the largest budget eval
    /// measures. Curves within 1 pixel on flat art: on the first 12 emoji of data/eval the
    /// automatic budget draws 4.8 KB at LPIPS 0.0136 (34.13 dB) with them and 7.0 KB at 0.0302
    /// (34.77 dB) with traced polygons, where vtracer's defaults draw 9.8 KB at 0.0200 (28.14 dB);
    /// at 500 paths and more, traced polygons draw more (emoji and photos). Flat art up to 64
    /// paths: on those emoji curves draw 32 paths in 5.7 KB at 34.96 dB / LPIPS 0.0139 and 64 in
    /// 10.5 KB at 36.33 / 0.0097 (polygons: 8.1 KB, 35.06 / 0.0323; 11.8 KB, 36.71 / 0.0246),
    /// but 125 in 21.3 KB at 36.71 / 0.0106 (polygons 19.4 KB, 38.07 / 0.0193) and 250 in
    /// 46.6 KB at 37.84 / 0.0110 (polygons 33.8 KB, 39.96 / 0.0134); every one of them stops
    /// at 64 or fewer, while the photos of data/eval that reach 30 dB do so at 256 paths and
    /// more, where curves cost them 0.5–0.9 dB (and bytes at 1024).
    fn default() -> Self {
        Self { target_psnr: 30.0, min_gain: 0.25, max_paths: 2000, flat_tolerance: 1.0, flat_paths: 64 }
    }
}

/// The smallest budget the auto ladder starts from: the background and 7 regions.
const AUTO_FIRST: usize = 8;

/// The automatic budget measures budgets up to this many paths on one hierarchy made for it;
/// a picture that climbs past it gets one more, made for the ceiling, for every larger rung.
/// One tree for the ceiling alone would serve every rung, but pictures that stop early (flat
/// art stops at tens of paths) would pay for an over-segmentation eight times 2000 paths.
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
    /// [`AutoBudget::flat_paths`].
    pub flat: bool,
}

/// A path budget for `image` by `auto`'s rule, at most `auto.max_paths` (and
/// [`crate::MAX_PATHS`]): budgets 8, 16, 32, … are measured until one reaches `auto.target_psnr`
/// or the ceiling, and the smallest from which no larger measured budget gains `auto.min_gain`
/// per doubling on average is chosen. A budget is measured by the squared error of its regions
/// (as many as `point` gives it) each filled with its mean colour, read off the image's merge
/// tree ([`hierarchy`]): about what the fallback drawing of those regions draws (cutting the
/// staircases adds 0.1–0.3 dB), without tracing or rendering any. Rungs up to [`AUTO_STAGE`]
/// paths are read off one tree made for it, larger rungs off one made for the ceiling. An
/// early plateau (a few regions cannot yet follow fine detail) does not stop the climb.
pub fn auto_budget(
    image: &Rgb32FImage,
    point: &OperatingPoint,
    compactness: f32,
    auto: &AutoBudget,
) -> Result<AutoChoice, SlicError> {
    let max_paths = auto.max_paths.clamp(2, crate::MAX_PATHS);
    let most = max_regions(image.width(), image.height());
    let regions_for = |paths: usize| point.filling_regions(paths).clamp(1, paths - 1).min(most);
    let tree_for = |paths: usize| hierarchy(image, regions_for(paths), compactness);
    let mut tree = (AUTO_STAGE.min(max_paths), tree_for(AUTO_STAGE.min(max_paths))?);
    let mut ladder: Vec<(usize, f64)> = Vec::new();
    let mut paths = AUTO_FIRST.min(max_paths);
    loop {
        if paths > tree.0 {
            tree = (max_paths, tree_for(max_paths)?);
        }
        let value = flat_psnr(tree.1.flat_error(regions_for(paths)), image);
        ladder.push((paths, value));
        if value >= auto.target_psnr || paths == max_paths || regions_for(paths) == most {
            break;
        }
        paths = (paths * 2).min(max_paths);
    }
    let pays = |(fewer, low): (usize, f64), (more, high): (usize, f64)| {
        high - low >= auto.min_gain * (more as f64 / fewer as f64).log2()
    };
    let knee = (0..ladder.len()).find(|&i| ladder[i + 1..].iter().all(|&later| !pays(ladder[i], later)));
    let paths = ladder[knee.unwrap_or(ladder.len() - 1)].0;
    let flat = ladder.iter().any(|&(paths, value)| paths <= auto.flat_paths && value >= auto.target_psnr);
    Ok(AutoChoice { paths, regions: regions_for(paths), hierarchy: tree.1, flat })
}

#[cfg(test)]
mod tests {
    use image::Rgb;
    use raster::render_exact;

    use super::*;

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
        let auto = AutoBudget::default();
        let two_colours = blocks(2, 48, 1);
        let few = auto_budget(&two_colours, &point, 30.0, &auto).unwrap();
        assert_eq!(few.paths, AUTO_FIRST, "four flat squares need no more than the first rung");
        assert_eq!(few.regions, point.filling_regions(AUTO_FIRST), "the budget's regions");
        // Its tree starts from the four squares (areas of one colour): fewer than the budget's
        // regions, and all it needs.
        assert_eq!(few.hierarchy.most_regions(), 4, "the squares are the tree's base");
        assert!(few.hierarchy.flat_error(4) < 1e-4, "each square its own colour");
        assert!(few.flat, "four flat squares are flat art");
        let detailed = blocks(16, 8, 2);
        let many = auto_budget(&detailed, &point, 30.0, &auto).unwrap();
        assert!(many.paths >= 128, "256 flat squares got only {} paths", many.paths);
        assert!(many.paths <= auto.max_paths);
        assert!(!many.flat, "flat colours that need {} paths are drawn as photos are", many.paths);
        // Noise no count of flat regions draws at 30 dB: not flat art.
        let noise = Rgb32FImage::from_fn(64, 64, |x, y| {
            let v = |c: u32| {
                ((x * 7919 + y * 104_729 + c * 1299).wrapping_mul(2_654_435_761) % 1000) as f32 / 1000.0
            };
            Rgb([v(0), v(1), v(2)])
        });
        assert!(!auto_budget(&noise, &point, 30.0, &auto).unwrap().flat, "noise is no flat art");
    }

    /// Flat art with edges that round regions straddle: diagonal bands and a disc.
    fn bands_and_disc() -> Rgb32FImage {
        Rgb32FImage::from_fn(96, 96, |x, y| {
            let (dx, dy) = (x as f32 - 60.0, y as f32 - 40.0);
            if dx * dx + dy * dy < 20.0 * 20.0 {
                Rgb([0.9, 0.2, 0.1])
            } else if (x + 2 * y) / 11 % 2 == 0 {
                Rgb([0.1, 0.3, 0.8])
            } else {
                Rgb([1.0, 0.9, 0.6])
            }
        })
    }

    #[test]
    fn the_drawn_regions_are_the_trees_cut_and_its_fallback_is_scored_exactly() {
        let image = Arc::new(bands_and_disc());
        let regions = 24;
        let segmented = Segmented::new(&image, hierarchy(&image, regions, 30.0).unwrap(), regions, None);
        assert_eq!(segmented.segmentation.regions.len(), regions);
        assert_eq!(segmented.fallback.regions.len(), regions);
        let flat = segmented.segmentation.flat_error(&image);
        let read = segmented.hierarchy.flat_error(regions);
        // (The tree sums its merges' costs in f64 from f32 means: a few parts in a million.)
        assert!((flat - read).abs() <= 1e-5 * flat, "the tree's {read} against the cut's {flat}");
        // What merging freely buys where round regions cannot follow the picture: better than
        // the method's own superpixels (plain SLIC at 30).
        let method = Arc::new(superpixel::segment(&image, regions, &SegmentOptions::default()).unwrap());
        let method_error = FallbackDrawing::new(&image, &method, None).error;
        assert!(
            segmented.fallback.error < 0.5 * method_error,
            "{} against plain SLIC's {method_error}",
            segmented.fallback.error
        );
        // The score is the exact rendering's error.
        let drawn =
            image::DynamicImage::ImageRgb8(render_exact(&segmented.fallback.paths(), 96, 96, [1.0; 3]));
        let mse = common::mse(&drawn.to_rgb32f(), &image);
        assert!((mse - segmented.fallback.mse()).abs() < 1e-9, "{mse} vs {}", segmented.fallback.mse());
    }

    #[test]
    fn auto_budget_keeps_to_its_ceiling() {
        let greedy = AutoBudget {
            target_psnr: f64::INFINITY,
            min_gain: f64::NEG_INFINITY,
            max_paths: 40,
            ..Default::default()
        };
        let choice = auto_budget(&blocks(16, 8, 3), &OperatingPoint::default(), 30.0, &greedy).unwrap();
        assert_eq!(choice.paths, 40);
    }
}
