//! SuperSVG-B as stages over one [`Scene`]: segment (the best of a few segmentations) → coarse
//! (background, fallbacks, E_c) → refine (E_r). Fine-tuning ([`crate::finetune`]) and export work on the scene it returns.

use std::time::Instant;

use burn::tensor::Device;
use image::Rgb32FImage;
use model::OperatingPoint;
use raster::render_exact;
use superpixel::{SegmentOptions, Segmentation, SlicError, segment};

use crate::coarse::{CoarseBudget, draw_coarse};
use crate::fallback::FallbackDrawing;
use crate::metrics::mse;
use crate::models::Models;
use crate::refine::draw_refinement;
use crate::scene::Scene;

/// The most paths [`vectorize`] draws: at 20 000, segmenting, fitting and the exact canvas take
/// about 10 s at 512 px; more paths than that is more regions than such an image has of
/// [`MIN_REGION_PIXELS`].
pub const MAX_PATHS: usize = 20_000;

/// The fewest pixels a region is cut with (4 × 4): SLIC cannot place more centres than that
/// meaningfully, and one path per pixel would only copy the raster.
pub const MIN_REGION_PIXELS: usize = 16;

/// The most regions an image of `width × height` pixels is split into.
pub fn max_regions(width: u32, height: u32) -> usize {
    (width as usize * height as usize / MIN_REGION_PIXELS).max(1)
}

/// Settings of one vectorization.
#[derive(Clone, Debug)]
pub struct Options {
    /// The most paths of the result (at least 2: the background and one region). Fewer are
    /// drawn only when no further path lowers the error.
    pub paths: usize,
    /// Number of superpixels; by default the operating point's for the budget. Clamped to
    /// `paths − 1` and to [`max_regions`].
    pub regions: Option<usize>,
    /// How the budget is split; by default the one stored with the models.
    pub operating_point: Option<OperatingPoint>,
    /// SLIC compactness (the method's 30).
    pub compactness: f32,
    /// Crops per network call.
    pub batch: usize,
}

impl Default for Options {
    fn default() -> Self {
        Self { paths: 500, regions: None, operating_point: None, compactness: 30.0, batch: 32 }
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
    /// The image could not be segmented.
    #[error(transparent)]
    Segmentation(#[from] SlicError),
}

/// The outcome of [`vectorize`].
pub struct Vectorization {
    /// The drawing: paths with their regions and stages, and its exact rendering.
    pub scene: Scene,
    /// The operating point used.
    pub operating_point: OperatingPoint,
    /// Seconds per stage.
    pub timings: Vec<(&'static str, f64)>,
}

/// The SLIC compactness of the plain-SLIC candidates of [`choose_segmentation`], as fractions of
/// the method's: less compact regions follow colour edges instead of staying round, which flat
/// art rewards. On the 31 emoji of data/eval at the stored operating point, one extra candidate
/// at 1/2 or 1/3 of 30 gains about 1 dB at 500 paths, these three 1.4 / 1.0 dB at 500 / 2000
/// (docs/operating-point.md, measured when regions were fitted with one path); 1/6 alone gained
/// 0.3. Each candidate costs one SLIC, one tracing and one rendering.
const PLAIN_COMPACTNESS: [f32; 4] = [1.0, 2.0 / 3.0, 1.0 / 2.0, 1.0 / 3.0];

/// The candidate of [`choose_segmentation`] whose regions take any shape: SLIC for this many
/// times the regions at a third of the compactness, merged by colour with no floor on
/// compactness, so that regions follow the image's colour edges as far as the count allows.
/// Only traced outlines draw such regions well. With it, the fallback alone draws data/eval's
/// photos at 25.45 dB / LPIPS 0.281 and the first 12 emoji at 36.64 / 0.023 at 500 paths
/// (docs/eval), against 22.95 / 0.427 and 27.47 / 0.072 with one fitted path per region of
/// the earlier candidates. It is also the costliest candidate (most of `infer`'s time).
const FREE_OVERSEGMENT: f32 = 64.0;

/// How [`choose_segmentation`]'s candidates are made: merged freely ([`FREE_OVERSEGMENT`]),
/// merged by colour as `point` makes them (if it oversegments), then plain SLIC at each of
/// [`PLAIN_COMPACTNESS`] × `compactness`.
fn candidates(point: &OperatingPoint, compactness: f32) -> impl Iterator<Item = SegmentOptions> {
    let free = SegmentOptions {
        compactness: compactness / 3.0,
        oversegment: FREE_OVERSEGMENT,
        min_compactness: 0.0,
    };
    let plain = OperatingPoint { oversegment: 1.0, ..*point };
    let merged = (point.oversegment > 1.0).then(|| point.segment_options(compactness));
    std::iter::once(free)
        .chain(merged)
        .chain(PLAIN_COMPACTNESS.map(|fraction| plain.segment_options(compactness * fraction)))
}

/// `image` split into `regions` superpixels, of the candidates ([`candidates`]) the one whose
/// fallback drawing draws it best (least squared error).
/// Returns the chosen segmentation with its fallback drawing (traced once: scoring a candidate
/// costs its tracing and one rendering).
pub fn choose_segmentation(
    image: &Rgb32FImage,
    regions: usize,
    point: &OperatingPoint,
    compactness: f32,
) -> Result<(Segmentation, FallbackDrawing), SlicError> {
    let mut best: Option<(f64, Segmentation, FallbackDrawing)> = None;
    for options in candidates(point, compactness) {
        let segmentation = segment(image, regions, &options)?;
        let drawing = FallbackDrawing::new(image, &segmentation);
        let error = drawing_error(&drawing, image);
        if best.as_ref().is_none_or(|(least, ..)| error < *least) {
            best = Some((error, segmentation, drawing));
        }
    }
    let (_, segmentation, drawing) = best.expect("at least one candidate");
    Ok((segmentation, drawing))
}

/// Mean squared error of the exact rendering of `drawing` (over white) against `image`.
fn drawing_error(drawing: &FallbackDrawing, image: &Rgb32FImage) -> f64 {
    let (width, height) = image.dimensions();
    let drawn = render_exact(&drawing.paths(), width, height, [1.0; 3]);
    mse(&image::DynamicImage::ImageRgb8(drawn).to_rgb32f(), image)
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
}

impl Default for AutoBudget {
    /// 30 dB is where flat art looks drawn, not approximated. 0.25 dB per doubling keeps a
    /// textured photo climbing (the baboon of data/eval gains about 0.45 dB per doubling from 8
    /// to 500 paths; at 0.5 it stopped at 8 paths and 16.5 dB) while a flat picture, whose
    /// fallback drawing gains nothing from more regions, stays at 8. 2000 is the largest budget
    /// eval measures.
    fn default() -> Self {
        Self { target_psnr: 30.0, min_gain: 0.25, max_paths: 2000 }
    }
}

/// The smallest budget the auto ladder starts from: the background and 7 regions.
const AUTO_FIRST: usize = 8;

/// A path budget for `image` by `auto`'s rule, judged on the fallback drawing (what every
/// region gets first), segmented as [`vectorize`] segments for `point`: budgets 8, 16, 32, …
/// are measured until one reaches `auto.target_psnr` or `auto.max_paths` is reached, and the
/// smallest from which no larger measured budget gains `auto.min_gain` per doubling on average
/// is chosen. An early plateau (a few regions cannot yet follow fine detail) does not stop the
/// climb; a flat picture whose seams keep it just under the target stays at 8. Costs about
/// twice the segmenting and fitting of the largest budget measured.
pub fn auto_budget(
    image: &Rgb32FImage,
    point: &OperatingPoint,
    compactness: f32,
    auto: &AutoBudget,
) -> Result<usize, VectorizeError> {
    let max_paths = auto.max_paths.clamp(2, MAX_PATHS);
    let most = max_regions(image.width(), image.height());
    let mut ladder: Vec<(usize, f64)> = Vec::new();
    let mut paths = AUTO_FIRST.min(max_paths);
    loop {
        let regions = point.regions(paths).clamp(1, paths - 1).min(most);
        let (_, drawing) = choose_segmentation(image, regions, point, compactness)?;
        let quality = -10.0 * drawing_error(&drawing, image).max(1e-10).log10();
        ladder.push((paths, quality));
        if quality >= auto.target_psnr || paths == max_paths || regions == most {
            break;
        }
        paths = (paths * 2).min(max_paths);
    }
    let pays = |(fewer, low): (usize, f64), (more, high): (usize, f64)| {
        high - low >= auto.min_gain * (more as f64 / fewer as f64).log2()
    };
    let knee = (0..ladder.len()).find(|&i| ladder[i + 1..].iter().all(|&later| !pays(ladder[i], later)));
    Ok(ladder[knee.unwrap_or(ladder.len() - 1)].0)
}

/// The operating point [`vectorize`] uses: the one in `options`, else the models' own, with no
/// budget kept for E_r when there is none.
pub fn operating_point(models: &Models, options: &Options) -> OperatingPoint {
    let mut point = options.operating_point.unwrap_or(models.operating_point);
    if models.refine.is_none() {
        point.refine_share = 0.0;
    }
    point
}

/// Vectorizes `image` (working resolution) with `models` on `device`.
pub fn vectorize(
    models: &Models,
    image: &Rgb32FImage,
    options: &Options,
    device: &Device,
) -> Result<Vectorization, VectorizeError> {
    if !(2..=MAX_PATHS).contains(&options.paths) {
        return Err(VectorizeError::Budget(options.paths));
    }
    let mut timings = Vec::new();
    let mut clock = Instant::now();
    let mut lap = |name: &'static str, timings: &mut Vec<(&'static str, f64)>| {
        timings.push((name, clock.elapsed().as_secs_f64()));
        clock = Instant::now();
    };

    let point = operating_point(models, options);
    let most = max_regions(image.width(), image.height());
    let regions =
        options.regions.unwrap_or_else(|| point.regions(options.paths)).clamp(1, options.paths - 1).min(most);
    let (segmentation, fallback) = choose_segmentation(image, regions, &point, options.compactness)?;
    let mut scene = Scene::new(image.clone(), segmentation);
    lap("superpixels", &mut timings);

    let budget = CoarseBudget {
        paths: point.coarse_paths(options.paths),
        total: options.paths - point.reserved_for_refine(options.paths),
    };
    draw_coarse(&models.coarse, &models.config, &mut scene, fallback, budget, options.batch, device);
    lap("coarse", &mut timings);

    if let Some(refine) = &models.refine {
        draw_refinement(refine, &models.config, &mut scene, options.paths, options.batch, device);
    }
    lap("refine", &mut timings);
    Ok(Vectorization { scene, operating_point: point, timings })
}

#[cfg(test)]
mod tests {
    use image::Rgb;

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
        assert_eq!(few, AUTO_FIRST, "four flat squares need no more than the first rung");
        let detailed = blocks(16, 8, 2);
        let many = auto_budget(&detailed, &point, 30.0, &auto).unwrap();
        assert!(many >= 128, "256 flat squares got only {many} paths");
        assert!(many <= auto.max_paths);
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
    fn the_chosen_segmentation_draws_no_worse_than_any_candidate() {
        let image = bands_and_disc();
        let point = OperatingPoint { oversegment: 3.0, min_compactness: 0.3, ..OperatingPoint::default() };
        let (segmentation, drawing) = choose_segmentation(&image, 24, &point, 30.0).unwrap();
        let chosen = drawing_error(&drawing, &image);
        assert_eq!(drawing.regions.len(), segmentation.regions.len());
        let candidates: Vec<SegmentOptions> = candidates(&point, 30.0).collect();
        assert_eq!(
            candidates.len(),
            2 + PLAIN_COMPACTNESS.len(),
            "the free and the merged candidates, then the plain ones"
        );
        let errors: Vec<f64> = candidates
            .iter()
            .map(|options| {
                let candidate = segment(&image, 24, options).unwrap();
                drawing_error(&FallbackDrawing::new(&image, &candidate), &image)
            })
            .collect();
        for (options, error) in candidates.iter().zip(&errors) {
            assert!(chosen <= *error, "chose error {chosen}, but {options:?} draws {error}");
        }
        assert!(
            chosen < errors[1],
            "on flat art a less compact candidate should beat plain SLIC at 30: {errors:?}"
        );
    }

    #[test]
    fn auto_budget_keeps_to_its_ceiling() {
        let greedy = AutoBudget { target_psnr: f64::INFINITY, min_gain: f64::NEG_INFINITY, max_paths: 40 };
        let paths = auto_budget(&blocks(16, 8, 3), &OperatingPoint::default(), 30.0, &greedy).unwrap();
        assert_eq!(paths, 40);
    }
}
