//! The paper's inference (SuperSVG, CVPR 2024, as its reference code runs it), for a model
//! trained with the paper preset to be set beside the paper's Table 1: budget / 64 SLIC
//! regions, every visible E_c path of each kept in label order, then one pass of E_r over
//! ⌈remaining / 8⌉ regions of a second SLIC, every visible path appended. No fallback paths, no
//! trade of paths against regions, no acceptance test, the models' own colours.
//!
//! Two weaknesses of the reference are not copied: a background path in the colour of what the
//! paths leave uncovered lies under everything (the reference leaves those pixels empty), and a
//! budget too small for every visible E_c path cuts each region to its share of it (its first
//! paths in E_c's painter's order) instead of dropping the last regions' paths wholesale.

use std::sync::Arc;
use web_time::Instant;

use image::Rgb32FImage;
use model::{CropBatch, canvas_cells, crop_to_image};
use raster::{Path, Shape};
use superpixel::{RegionCrop, Segmentation, SlicOptions, slic};

use crate::coarse::propose;
use crate::fallback::background;
use crate::job::VectorizeError;
use crate::models::{Context, Models};
use crate::refine::RefineTally;
use crate::scene::{Origin, Placed, Scene};
use crate::segmentation::max_regions;

/// Paths of the budget per coarse region: the reference cuts `budget / 64` superpixels (its E_c
/// draws 128 paths a region, of which about half are visible).
pub const PATHS_PER_REGION: usize = 64;

/// The reference's SLIC for E_c's regions (compactness 50, σ 5).
fn coarse_slic(regions: usize) -> SlicOptions {
    SlicOptions { n_segments: regions, compactness: 50.0, sigma: 5.0, ..SlicOptions::default() }
}

/// The reference's second SLIC, for E_r's regions (compactness 20, σ 5).
fn refine_slic(regions: usize) -> SlicOptions {
    SlicOptions { n_segments: regions, compactness: 20.0, sigma: 5.0, ..SlicOptions::default() }
}

/// The regions E_c draws for a budget of `paths` on a `width × height` image: `paths / 64`, at
/// least one, at most [`max_regions`].
pub fn coarse_regions(paths: usize, width: u32, height: u32) -> usize {
    (paths / PATHS_PER_REGION).clamp(1, max_regions(width, height))
}

/// Draws `target` with at most `paths` paths the paper's way (see the module): the scene's
/// segmentation is E_c's SLIC; E_r's paths, drawn for the regions of a second SLIC, belong to
/// none of its regions. With the scene come what E_r did (every path it appends is kept, and
/// its gain may be negative) and the seconds both networks' forward passes took.
pub fn draw_paper(
    models: &Models,
    context: &Context,
    target: &Arc<Rgb32FImage>,
    paths: usize,
) -> Result<(Scene, RefineTally, f64), VectorizeError> {
    let (width, height) = target.dimensions();
    let segmentation = Arc::new(slic(target, &coarse_slic(coarse_regions(paths, width, height)))?);
    let config = context.config;
    let crops: Vec<RegionCrop> = (0..segmentation.regions.len() as u32)
        .map(|region| config.region_crop(&segmentation, target, region))
        .collect();
    let share = (paths - 1) / segmentation.regions.len();
    let mut drawn: Vec<Placed> = Vec::new();
    let clock = Instant::now();
    let proposals = propose(models.coarse.get()?, context, &crops, (width, height));
    let coarse_network = clock.elapsed().as_secs_f64();
    for (region, proposed) in proposals.into_iter().enumerate() {
        drawn.extend(proposed.into_iter().take(share).map(|path| Placed {
            shape: path.into(),
            region: Some(region as u32),
            origin: Origin::Coarse,
        }));
    }
    let shapes: Vec<Shape> = drawn.iter().map(|placed| placed.shape.clone()).collect();
    let mut scene = Scene::new(target.clone(), segmentation);
    let under =
        Placed { shape: background(target, &shapes).into(), region: None, origin: Origin::Background };
    for placed in std::iter::once(under).chain(drawn) {
        scene.push(placed);
    }
    let mut tally = RefineTally::default();
    if let Some(refine) = &models.refine {
        let remaining = paths.saturating_sub(scene.len());
        if remaining > 0 {
            let regions = remaining.div_ceil(config.refine_paths).min(max_regions(width, height));
            let second = slic(target, &refine_slic(regions))?;
            let before = scene.total_error();
            let clock = Instant::now();
            let proposed = propose_refinement(context, refine.get()?, &scene, &second);
            tally.network_seconds = clock.elapsed().as_secs_f64();
            tally.proposed = proposed.len();
            // Appended until the scene holds `paths` (a path that cannot be drawn is passed over).
            for path in proposed {
                if scene.len() == paths {
                    break;
                }
                scene.push(Placed { shape: path.into(), region: None, origin: Origin::Refine });
            }
            tally.kept = scene.counts().refine;
            tally.gain_db = 10.0 * (before / scene.total_error()).log10();
        }
    }
    let networks = coarse_network + tally.network_seconds;
    Ok((scene, tally, networks))
}

/// E_r once over every region of `second` on `scene`'s canvas as the coarse stage left it
/// (`context.batch` crops a call): its visible paths, opaque, in label order.
fn propose_refinement(
    context: &Context,
    refine: &model::RefineModel,
    scene: &Scene,
    second: &Segmentation,
) -> Vec<Path> {
    let device = context.device;
    let (width, height) = scene.target().dimensions();
    let canvas = scene.canvas_image();
    let crops: Vec<RegionCrop> = (0..second.regions.len() as u32)
        .map(|region| context.config.region_crop(second, scene.target(), region))
        .collect();
    let mut proposed = Vec::new();
    for chunk in crops.chunks(context.batch.max(1)) {
        let targets = CropBatch::new(chunk, device);
        let cells = targets.masked_canvas(canvas_cells(&canvas, chunk, device), &context.config.input);
        for (crop, scene) in chunk.iter().zip(refine.forward(targets.pixels, cells).to_scenes()) {
            let visible = scene.into_iter().filter(Path::is_visible);
            proposed
                .extend(visible.map(|path| crop_to_image(Path { alpha: 1.0, ..path }, crop, width, height)));
        }
    }
    proposed
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_budget_gives_a_region_per_64_paths_within_what_the_image_holds() {
        assert_eq!(coarse_regions(500, 512, 512), 7);
        assert_eq!(coarse_regions(2000, 512, 512), 31);
        assert_eq!(coarse_regions(30, 512, 512), 1, "a small budget still draws one region");
        assert_eq!(coarse_regions(20_000, 16, 16), 16, "one region per 16 pixels at most");
    }
}
