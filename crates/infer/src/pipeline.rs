//! SuperSVG-B as stages over one [`Scene`]: segment (the better of two segmentations) → coarse
//! (background, fallbacks, E_c) → refine (E_r). Fine-tuning ([`crate::finetune`]) and export work on the scene it returns.

use std::time::Instant;

use burn::tensor::Device;
use image::Rgb32FImage;
use model::OperatingPoint;
use raster::render_exact;
use superpixel::{Segmentation, SlicError, segment};

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

/// `image` split into `regions` superpixels as the operating point makes them (SLIC merged by
/// colour) or by plain SLIC, whichever the fallback drawing draws better: merged regions follow
/// a photo's colours with fewer shapes, while on flat art they grow into shapes one path fits
/// badly (data/eval: merging gains 0.8 dB on photos and loses 0.9 dB on emoji at 500 paths).
/// Returns the chosen segmentation with its fallback drawing (fitted once: scoring a candidate
/// costs its fitting and one rendering).
pub fn choose_segmentation(
    image: &Rgb32FImage,
    regions: usize,
    point: &OperatingPoint,
    compactness: f32,
) -> Result<(Segmentation, FallbackDrawing), SlicError> {
    let merged = segment(image, regions, &point.segment_options(compactness))?;
    let merged_drawing = FallbackDrawing::new(image, &merged);
    if point.oversegment <= 1.0 {
        return Ok((merged, merged_drawing));
    }
    let plain =
        segment(image, regions, &OperatingPoint { oversegment: 1.0, ..*point }.segment_options(compactness))?;
    let plain_drawing = FallbackDrawing::new(image, &plain);
    let error = |drawing: &FallbackDrawing| {
        let (width, height) = image.dimensions();
        let drawn = render_exact(&drawing.paths(), width, height, [1.0; 3]);
        mse(&image::DynamicImage::ImageRgb8(drawn).to_rgb32f(), image)
    };
    Ok(if error(&plain_drawing) < error(&merged_drawing) {
        (plain, plain_drawing)
    } else {
        (merged, merged_drawing)
    })
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

    let mut point = options.operating_point.unwrap_or(models.operating_point);
    if models.refine.is_none() {
        point.refine_share = 0.0;
    }
    let most = max_regions(image.width(), image.height());
    let regions =
        options.regions.unwrap_or_else(|| point.regions(options.paths)).clamp(1, options.paths - 1).min(most);
    let (segmentation, fallback) = choose_segmentation(image, regions, &point, options.compactness)?;
    let mut scene = Scene::new(image.clone(), segmentation);
    lap("superpixels", &mut timings);

    let reserved = (options.paths as f64 * point.refine_share as f64).floor() as usize;
    let budget = CoarseBudget { per_region: point.coarse_paths, total: options.paths - reserved };
    draw_coarse(&models.coarse, &models.config, &mut scene, fallback, budget, options.batch, device);
    lap("coarse", &mut timings);

    if let Some(refine) = &models.refine {
        draw_refinement(refine, &models.config, &mut scene, options.paths, options.batch, device);
    }
    lap("refine", &mut timings);
    Ok(Vectorization { scene, operating_point: point, timings })
}
