//! The first stage: how an image is split into regions, and how many paths `--paths auto`
//! gives it.
//!
//! A budget's regions are the best-drawn of a few candidate segmentations
//! ([`choose_segmentation`]). The automatic budget reads the error of every region count off one
//! merge hierarchy ([`superpixel::Hierarchy`]) of the finest candidate's over-segmentation, and
//! the cut it picks is that candidate for the chosen budget: the image is segmented once for
//! the search and the drawing together.

use image::Rgb32FImage;
use model::OperatingPoint;
use superpixel::{Hierarchy, SegmentOptions, Segmentation, SlicError, SlicOptions, segment, slic};

use crate::fallback::FallbackDrawing;

/// The fewest pixels per region: SLIC cannot place centres closer than 4 × 4 pixels
/// meaningfully, and one path per pixel would only copy the raster.
pub const PIXELS_PER_REGION: usize = 16;

/// The most regions an image of `width × height` pixels is split into ([`PIXELS_PER_REGION`]).
pub fn max_regions(width: u32, height: u32) -> usize {
    (width as usize * height as usize / PIXELS_PER_REGION).max(1)
}

/// The candidate of [`choose_segmentation`] whose regions take any shape: SLIC for this many
/// times the regions at a third of the compactness, merged by colour with no floor on
/// compactness, so that regions follow the image's colour edges as far as the count allows.
/// Only traced outlines draw such regions well. With it, the fallback alone draws data/eval's
/// photos at 25.45 dB / LPIPS 0.281 and the first 12 emoji at 36.64 / 0.023 at 500 paths
/// (docs/eval), against 22.95 / 0.427 and 27.47 / 0.072 with one fitted path per region of
/// the earlier candidates. It is also the costliest candidate (most of `infer`'s time).
const FREE_OVERSEGMENT: f32 = 64.0;

/// How the freely merged candidate is made for `compactness` ([`FREE_OVERSEGMENT`]).
fn free_options(compactness: f32) -> SegmentOptions {
    SegmentOptions { compactness: compactness / 3.0, oversegment: FREE_OVERSEGMENT, min_compactness: 0.0 }
}

/// A segmentation of an image with its fallback drawing (traced, rendered and scored once).
pub struct Segmented {
    /// The regions.
    pub segmentation: Segmentation,
    /// Each region's outline in its mean colour over the background, with its rendering.
    pub fallback: FallbackDrawing,
}

/// `image` split into `regions` superpixels: of the candidates — merged freely
/// ([`FREE_OVERSEGMENT`]; `free` when the caller already cut it, as the automatic budget does)
/// and, on flat art only ([`PLAIN_FROM_PSNR`]), as `point` segments (SLIC at `compactness` for
/// `oversegment` × the regions, merged by colour above its compactness floor) and plain SLIC at
/// several compactnesses — the one whose regions, each filled with its mean colour, draw it best (least
/// squared error), with its fallback drawing (the only candidate traced and rendered).
///
/// The second pays on flat art at a few hundred regions and fewer: on the 31 emoji of
/// data/eval, by the flat-fill error at 15 to 127 regions, the free candidate alone is 1.1–3.8 dB
/// worse than the best of all six, and with the second beside it 0.08–0.44 dB worse; on the
/// photos the free one was the best at every count from 7 to 1999 on all 8 (one exception:
/// 0.02 dB at 7), so there it is not made (0.05–0.09 s of a photo at 500 paths).
///
/// An image longer than [`CHOICE_SIDE`] has the candidates compared on a copy of that size
/// (when the copy still has [`CHOICE_PIXELS_PER_REGION`] pixels a region), and only the winner
/// is made at full size: one segmentation of the large image instead of one per candidate.
pub fn choose_segmentation(
    image: &Rgb32FImage,
    regions: usize,
    point: &OperatingPoint,
    compactness: f32,
    tolerance: Option<f32>,
    free: Option<Segmentation>,
) -> Result<Segmented, SlicError> {
    let small = (image.width().max(image.height()) > CHOICE_SIDE)
        .then(|| common::decode::resized(image, CHOICE_SIDE))
        .filter(|small| {
            regions * CHOICE_PIXELS_PER_REGION <= small.width() as usize * small.height() as usize
        });
    if let Some(small) = small {
        let winner = best_candidate(&small, regions, point, compactness, None)?.1;
        let segmentation = match (winner, free) {
            (None, Some(free)) => free,
            (None, None) => segment(image, regions, &free_options(compactness))?,
            (Some(options), _) => segment(image, regions, &options)?,
        };
        return Ok(score(image, segmentation, tolerance));
    }
    let (best, _) = best_candidate(image, regions, point, compactness, free)?;
    Ok(score(image, best, tolerance))
}

/// Images longer than this (px) have [`choose_segmentation`]'s candidates compared on a copy
/// this long: at 4096 px every candidate segmented at full size cost 48 s of a 55 s run.
const CHOICE_SIDE: u32 = 1024;

/// The fewest pixels a region has in [`choose_segmentation`]'s small copy for the comparison
/// there to stand for the full-size one (a 16 × 16 block).
const CHOICE_PIXELS_PER_REGION: usize = 256;

/// The candidate of [`choose_segmentation`] that draws `image` best, and how it was made
/// (`None` for the freely merged one).
fn best_candidate(
    image: &Rgb32FImage,
    regions: usize,
    point: &OperatingPoint,
    compactness: f32,
    free: Option<Segmentation>,
) -> Result<(Segmentation, Option<SegmentOptions>), SlicError> {
    let free = match free {
        Some(free) => free,
        None => segment(image, regions, &free_options(compactness))?,
    };
    // Ranked by the flat-fill error: the fallback drawing differs from it only along region
    // boundaries (staircases cut, 0.1–0.3 dB), and it chooses as tracing and rendering every
    // candidate did on data/eval (the same SVGs), at the cost of one pass over the pixels.
    let mut best = (free.flat_error(image), free, None);
    let flat_art = flat_psnr(best.0, image) >= PLAIN_FROM_PSNR;
    let plain = OperatingPoint { oversegment: 1.0, ..*point };
    let few = PLAIN_COMPACTNESS.map(|fraction| plain.segment_options(compactness * fraction));
    let others = flat_art.then(|| std::iter::once(point.segment_options(compactness)).chain(few));
    for options in others.into_iter().flatten() {
        let candidate = segment(image, regions, &options)?;
        let error = candidate.flat_error(image);
        if error < best.0 {
            best = (error, candidate, Some(options));
        }
    }
    Ok((best.1, best.2))
}

/// When the freely merged candidate's regions, each filled with its mean colour, draw the
/// image at this PSNR (dB) or better, [`choose_segmentation`] also tries the operating point's
/// merged regions and plain SLIC at each of [`PLAIN_COMPACTNESS`] × the compactness. That is
/// flat art (the automatic budget's "close
/// enough"), where plain SLIC's regions sometimes win: on the 31 emoji of data/eval, by the
/// flat-fill error, on 3–11 of them at 7 to 255 regions, and trying them at every budget keeps
/// `--paths auto` at 35.34 dB where never trying them gives 35.11. On the photos (about 25 dB
/// at 500 paths, 28.5 at 2000) they never won at any count, and the four SLICs were 0.23 s of
/// a photo's 0.48 s of segmenting at 500 paths. The operating point's regions lost there by
/// 1.3–2.9 dB of flat-fill PSNR at 500 paths; gating them too leaves every SVG of data/eval's
/// photos and emoji at 500 and `auto` (and photos at 2000) as it was.
const PLAIN_FROM_PSNR: f64 = 30.0;

/// The SLIC compactness of [`choose_segmentation`]'s plain-SLIC candidates ([`PLAIN_FROM_PSNR`]), as
/// fractions of the method's: less compact regions follow colour edges instead of staying round,
/// which flat art rewards.
const PLAIN_COMPACTNESS: [f32; 4] = [1.0, 2.0 / 3.0, 1.0 / 2.0, 1.0 / 3.0];

/// The PSNR (dB) of a flat fill of `image` whose squared RGB error, summed over its pixels, is
/// `error` ([`Segmentation::flat_error`], [`Hierarchy::flat_error`]).
fn flat_psnr(error: f64, image: &Rgb32FImage) -> f64 {
    common::psnr_of_mse(error / (3 * image.width() as usize * image.height() as usize) as f64)
}

/// `segmentation` with its fallback drawing (boundaries fitted within `tolerance` pixels, if given).
fn score(image: &Rgb32FImage, segmentation: Segmentation, tolerance: Option<f32>) -> Segmented {
    let fallback = FallbackDrawing::new(image, &segmentation, tolerance);
    Segmented { segmentation, fallback }
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
    /// regions gain nothing from more of them, stays at 8. 2000 is the largest budget eval
    /// measures.
    fn default() -> Self {
        Self { target_psnr: 30.0, min_gain: 0.25, max_paths: 2000 }
    }
}

/// The smallest budget the auto ladder starts from: the background and 7 regions.
const AUTO_FIRST: usize = 8;

/// The automatic budget measures budgets up to this many paths on one hierarchy over-segmented
/// for it (0.2 s on a 512-px photo); each larger budget it climbs to gets a hierarchy
/// over-segmented for it alone, whose cut is then exactly that budget's freely merged
/// candidate. One hierarchy for the ceiling would serve every rung, but an over-segmentation
/// for 2000 paths is about two pixels a segment (2.9 s to segment and merge on data/eval's
/// rocket, against 0.57 s for 512): pictures that stop early would pay for it (the rocket stops
/// at 512 paths, and its search cost 2.2 times its drawing).
const AUTO_STAGE: usize = 256;

/// The budget [`auto_budget`] chose, and the freely merged segmentation for it (the candidate
/// [`choose_segmentation`] takes as `free`).
pub struct AutoChoice {
    /// Paths.
    pub paths: usize,
    /// The hierarchy's cut at the budget's region count.
    pub free: Segmentation,
}

/// A path budget for `image` by `auto`'s rule, at most `auto.max_paths` (and
/// [`crate::MAX_PATHS`]): budgets 8, 16, 32, … are measured until one reaches `auto.target_psnr`
/// or the ceiling, and the smallest from which no larger measured budget gains `auto.min_gain`
/// per doubling on average is chosen. A budget is measured by the squared error of its regions
/// (as many as `point` gives it) each filled with its mean colour, read off a merge hierarchy
/// of the freely merged candidate's over-segmentation: about what the fallback drawing of those
/// regions draws (cutting the staircases adds 0.1–0.3 dB), without tracing or rendering any.
/// Rungs up to [`AUTO_STAGE`] paths are read off one hierarchy over-segmented for it, each larger
/// rung off its own, over-segmented as that budget's freely merged candidate is: the cut handed
/// back for a budget above [`AUTO_STAGE`] is exactly the candidate `--paths N` would make, so
/// the drawing is what that fixed budget draws. An early plateau (a few regions cannot yet follow
/// fine detail) does not stop the climb.
pub fn auto_budget(
    image: &Rgb32FImage,
    point: &OperatingPoint,
    compactness: f32,
    auto: &AutoBudget,
) -> Result<AutoChoice, SlicError> {
    let max_paths = auto.max_paths.clamp(2, crate::MAX_PATHS);
    let pixels = image.width() as usize * image.height() as usize;
    let most = max_regions(image.width(), image.height());
    let regions_for = |paths: usize| point.filling_regions(paths).clamp(1, paths - 1).min(most);
    let free = free_options(compactness);
    let hierarchy_for = |paths: usize| -> Result<Hierarchy, SlicError> {
        let asked = (regions_for(paths) as f64 * free.oversegment as f64).ceil() as usize;
        let options = SlicOptions {
            n_segments: asked.clamp(1, pixels),
            compactness: free.compactness,
            ..Default::default()
        };
        Ok(Hierarchy::new(image, slic(image, &options)?))
    };
    let quality =
        |hierarchy: &Hierarchy, paths: usize| flat_psnr(hierarchy.flat_error(regions_for(paths)), image);
    // (the largest budget it was over-segmented for, the hierarchy), finest last.
    let mut hierarchies = vec![(AUTO_STAGE.min(max_paths), hierarchy_for(AUTO_STAGE.min(max_paths))?)];
    let mut ladder: Vec<(usize, f64)> = Vec::new();
    let mut paths = AUTO_FIRST.min(max_paths);
    loop {
        if paths > hierarchies[hierarchies.len() - 1].0 {
            hierarchies.push((paths, hierarchy_for(paths)?));
        }
        let value = quality(&hierarchies[hierarchies.len() - 1].1, paths);
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
    let (_, hierarchy) =
        hierarchies.iter().find(|(most, _)| paths <= *most).expect("the finest covers every rung");
    Ok(AutoChoice { paths, free: hierarchy.cut(image, regions_for(paths)) })
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
        assert_eq!(
            few.free.regions.len(),
            point.filling_regions(AUTO_FIRST),
            "the cut is the budget's regions"
        );
        let detailed = blocks(16, 8, 2);
        let many = auto_budget(&detailed, &point, 30.0, &auto).unwrap();
        assert!(many.paths >= 128, "256 flat squares got only {} paths", many.paths);
        assert!(many.paths <= auto.max_paths);
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
        let point = OperatingPoint { oversegment: 3.0, min_compactness: 0.3, ..OperatingPoint::default() };
        let plain = OperatingPoint { oversegment: 1.0, ..point };
        let regions = 24;
        // 24 regions cannot follow the bands (far from flat art by PLAIN_FROM_PSNR), but can
        // draw four squares exactly (flat art: the plain candidates are tried).
        let mut flat_art = Vec::new();
        for image in [bands_and_disc(), blocks(2, 48, 1)] {
            let chosen = choose_segmentation(&image, regions, &point, 30.0, None, None).unwrap();
            assert_eq!(chosen.fallback.regions.len(), chosen.segmentation.regions.len());
            let free = segment(&image, regions, &free_options(30.0)).unwrap();
            let flat = flat_psnr(free.flat_error(&image), &image) >= PLAIN_FROM_PSNR;
            flat_art.push(flat);
            let plains = PLAIN_COMPACTNESS.map(|fraction| plain.segment_options(30.0 * fraction));
            let tried = flat.then(|| std::iter::once(point.segment_options(30.0)).chain(plains));
            let candidates: Vec<SegmentOptions> =
                std::iter::once(free_options(30.0)).chain(tried.into_iter().flatten()).collect();
            let segmentations: Vec<Segmentation> =
                candidates.iter().map(|options| segment(&image, regions, options).unwrap()).collect();
            // The rule: the least flat-fill error.
            let chosen_flat = chosen.segmentation.flat_error(&image);
            assert!(segmentations.iter().all(|s| chosen_flat <= s.flat_error(&image)));
            // What the rule stands for: the traced drawing that draws best (every candidate drawn).
            for (options, segmentation) in candidates.iter().zip(&segmentations) {
                let error = FallbackDrawing::new(&image, segmentation, None).error;
                assert!(
                    chosen.fallback.error <= error,
                    "chose {}, but {options:?} draws {error}",
                    chosen.fallback.error
                );
            }
            // And what choosing buys where round regions cannot follow the picture: better than
            // the method's own superpixels (plain SLIC at 30).
            let method = segment(&image, regions, &SegmentOptions::default()).unwrap();
            let method_error = FallbackDrawing::new(&image, &method, None).error;
            assert!(
                flat || chosen.fallback.error < method_error,
                "{} against plain SLIC's {method_error}",
                chosen.fallback.error
            );
            // The score is the exact rendering's error.
            let drawn =
                image::DynamicImage::ImageRgb8(render_exact(&chosen.fallback.paths(), 96, 96, [1.0; 3]));
            let mse = common::mse(&drawn.to_rgb32f(), &image);
            assert!((mse - chosen.fallback.mse()).abs() < 1e-9, "{mse} vs {}", chosen.fallback.mse());
        }
        assert_eq!(flat_art, [false, true], "one picture on each side of PLAIN_FROM_PSNR");
    }

    #[test]
    fn a_large_image_is_segmented_once_as_its_small_copy_chose() {
        // Longer than CHOICE_SIDE: the candidates are compared on a 1024 × 32 copy.
        let image = Rgb32FImage::from_fn(1280, 40, |x, y| {
            if (x / 37 + y / 13) % 3 == 0 {
                Rgb([0.9, 0.2, 0.1])
            } else {
                Rgb([0.1, 0.3, 0.8 - x as f32 / 4000.0])
            }
        });
        let point = OperatingPoint { oversegment: 3.0, min_compactness: 0.3, ..OperatingPoint::default() };
        let chosen = choose_segmentation(&image, 24, &point, 30.0, None, None).unwrap();
        let small = common::decode::resized(&image, CHOICE_SIDE);
        assert_eq!(small.dimensions(), (1024, 32));
        let winner = best_candidate(&small, 24, &point, 30.0, None).unwrap().1;
        let full = segment(&image, 24, &winner.unwrap_or_else(|| free_options(30.0))).unwrap();
        assert_eq!(chosen.segmentation.labels, full.labels, "not the small copy's winner, made at full size");
        assert_eq!(chosen.fallback.error, FallbackDrawing::new(&image, &full, None).error);
    }

    #[test]
    fn auto_budget_keeps_to_its_ceiling() {
        let greedy = AutoBudget { target_psnr: f64::INFINITY, min_gain: f64::NEG_INFINITY, max_paths: 40 };
        let choice = auto_budget(&blocks(16, 8, 3), &OperatingPoint::default(), 30.0, &greedy).unwrap();
        assert_eq!(choice.paths, 40);
    }
}
