//! SuperSVG-B: superpixels → coarse paths per region → refinement where the error is largest.

use std::time::Instant;

use burn::tensor::{Device, Tensor, TensorData};
use image::Rgb32FImage;
use raster::{Path, render_exact};
use superpixel::{CropOptions, RegionCrop, Segmentation, SlicOptions, resample_area, slic};

use crate::models::Models;

/// Settings of one vectorization.
#[derive(Clone, Debug)]
pub struct Options {
    /// Exact number of paths wanted (fewer only if the image is already perfectly drawn).
    pub paths: usize,
    /// Number of superpixels; by default `paths / (2 × visible coarse paths per region)`.
    pub regions: Option<usize>,
    /// SLIC compactness (the method's 30).
    pub compactness: f32,
    /// Crops per network call.
    pub batch: usize,
    /// Colour under all paths.
    pub background: [f32; 3],
}

impl Default for Options {
    fn default() -> Self {
        Self { paths: 500, regions: None, compactness: 30.0, batch: 32, background: [1.0; 3] }
    }
}

/// A path of the result and the superpixel it was drawn for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placed {
    /// The path, in the image's unit square.
    pub path: Path,
    /// Index of its region in the segmentation.
    pub region: u32,
}

/// The outcome of [`vectorize`].
pub struct Vectorization {
    /// Every path in painter's order.
    pub paths: Vec<Placed>,
    /// The superpixels the image was split into.
    pub segmentation: Segmentation,
    /// How many paths came from the coarse stage (before pruning to the budget).
    pub coarse_paths: usize,
    /// Seconds per stage.
    pub timings: Vec<(&'static str, f64)>,
}

impl Vectorization {
    /// The paths alone, in painter's order.
    pub fn scene(&self) -> Vec<Path> {
        self.paths.iter().map(|placed| placed.path).collect()
    }
}

/// Vectorizes `image` (working resolution) with `models` on `device`.
pub fn vectorize(models: &Models, image: &Rgb32FImage, options: &Options, device: &Device) -> Vectorization {
    let mut timings = Vec::new();
    let mut clock = Instant::now();
    let mut lap = |name: &'static str, timings: &mut Vec<(&'static str, f64)>| {
        timings.push((name, clock.elapsed().as_secs_f64()));
        clock = Instant::now();
    };

    let pixels = (image.width() * image.height()) as usize;
    let per_region = 2.0 * models.visible_per_region;
    let regions = options.regions.unwrap_or_else(|| (options.paths as f32 / per_region).round() as usize);
    let slic_options = SlicOptions {
        n_segments: regions.clamp(1, pixels),
        compactness: options.compactness,
        ..Default::default()
    };
    let segmentation = slic(image, &slic_options).expect("a non-empty image and a valid region count");
    let crop_options = CropOptions { size: models.config.input_size, ..Default::default() };
    let crops: Vec<RegionCrop> = (0..segmentation.regions.len() as u32)
        .map(|region| segmentation.crop(image, region, &crop_options))
        .collect();
    lap("superpixels", &mut timings);

    let mut paths = coarse_paths(models, &crops, image, options.batch, device);
    let coarse_count = paths.len();
    if paths.len() > options.paths {
        paths = prune(paths, options.paths, image.dimensions(), options.background);
    }
    lap("coarse", &mut timings);

    if let Some(refine) = &models.refine {
        refine_paths(refine, models, &mut paths, &crops, &segmentation, image, options, device);
    }
    lap("refine", &mut timings);
    Vectorization { paths, segmentation, coarse_paths: coarse_count, timings }
}

/// E_c on every region crop; the visible paths of each region, mapped onto the image, region
/// after region.
fn coarse_paths(
    models: &Models,
    crops: &[RegionCrop],
    image: &Rgb32FImage,
    batch: usize,
    device: &Device,
) -> Vec<Placed> {
    let mut placed = Vec::new();
    for (chunk_index, chunk) in crops.chunks(batch.max(1)).enumerate() {
        let input = stack(chunk.iter().map(|crop| crop.pixels.as_slice()), models.config.input_size, device);
        let scenes = models.coarse.forward(input).to_scenes();
        for (offset, (crop, scene)) in chunk.iter().zip(scenes).enumerate() {
            let region = (chunk_index * batch.max(1) + offset) as u32;
            for path in scene.into_iter().filter(|path| path.alpha > 0.5) {
                let path = to_image(path, crop, image);
                placed.push(Placed { path, region });
            }
        }
    }
    placed
}

/// Rounds of E_r: render what is drawn, rank regions by squared error, add `m` paths to each of
/// the worst ones (one batch per round) until the budget is spent.
#[allow(clippy::too_many_arguments)]
fn refine_paths(
    refine: &model::RefineModel,
    models: &Models,
    paths: &mut Vec<Placed>,
    crops: &[RegionCrop],
    segmentation: &Segmentation,
    image: &Rgb32FImage,
    options: &Options,
    device: &Device,
) {
    let size = models.config.input_size;
    let per_call = models.config.refine_paths;
    let (width, height) = image.dimensions();
    while paths.len() < options.paths {
        let remaining = options.paths - paths.len();
        let scene: Vec<Path> = paths.iter().map(|p| p.path).collect();
        let canvas = render(&scene, width, height, options.background);
        let errors = region_errors(&canvas, image, segmentation);
        let mut worst: Vec<u32> = (0..errors.len() as u32).filter(|&r| errors[r as usize] > 0.0).collect();
        worst.sort_by(|a, b| errors[*b as usize].total_cmp(&errors[*a as usize]).then(a.cmp(b)));
        worst.truncate(remaining.div_ceil(per_call).min(options.batch.max(1)));
        if worst.is_empty() {
            break;
        }
        let targets = stack(worst.iter().map(|&r| crops[r as usize].pixels.as_slice()), size, device);
        let canvases: Vec<Vec<f32>> =
            worst.iter().map(|&r| canvas_crop(&canvas, &crops[r as usize], options.background)).collect();
        let canvases = stack(canvases.iter().map(Vec::as_slice), size, device);
        let added = refine.forward(targets, canvases).to_scenes();
        for (&region, scene) in worst.iter().zip(added) {
            for path in scene {
                if paths.len() == options.paths {
                    return;
                }
                paths.push(Placed { path: to_image(path, &crops[region as usize], image), region });
            }
        }
    }
}

/// The current canvas cut like a region's crop, with the background outside the region (as
/// the refinement model saw its canvas in training).
fn canvas_crop(canvas: &Rgb32FImage, crop: &RegionCrop, background: [f32; 3]) -> Vec<f32> {
    let mut cut = resample_area(canvas, &crop.transform, crop.size);
    let cells = crop.size * crop.size;
    for (cell, &inside) in crop.mask.iter().enumerate() {
        if inside == 0.0 {
            for (c, value) in background.iter().enumerate() {
                cut[c * cells + cell] = *value;
            }
        }
    }
    cut
}

/// The exact rendering of `scene` as RGB in [0, 1].
pub(crate) fn render(scene: &[Path], width: u32, height: u32, background: [f32; 3]) -> Rgb32FImage {
    image::DynamicImage::ImageRgb8(render_exact(scene, width, height, background)).to_rgb32f()
}

/// Sum of squared differences per region.
pub(crate) fn region_errors(
    canvas: &Rgb32FImage,
    image: &Rgb32FImage,
    segmentation: &Segmentation,
) -> Vec<f64> {
    let mut errors = vec![0.0; segmentation.regions.len()];
    for ((a, b), &label) in canvas.pixels().zip(image.pixels()).zip(&segmentation.labels) {
        errors[label as usize] += (0..3).map(|c| (a.0[c] as f64 - b.0[c] as f64).powi(2)).sum::<f64>();
    }
    errors
}

/// A path predicted in `crop`'s unit square, moved to the image's unit square.
fn to_image(path: Path, crop: &RegionCrop, image: &Rgb32FImage) -> Path {
    let (width, height) = image.dimensions();
    Path { alpha: 1.0, ..path.map_points(|p| crop.transform.to_image_unit(p, width, height)) }
}

/// `[n, 3, S, S]` from n planar crops.
fn stack<'a>(crops: impl Iterator<Item = &'a [f32]>, size: usize, device: &Device) -> Tensor<4> {
    let values: Vec<f32> = crops.flat_map(|crop| crop.iter().copied()).collect();
    let count = values.len() / (3 * size * size);
    Tensor::from_data(TensorData::new(values, [count, 3, size, size]), device)
}

/// Keeps the `budget` most useful paths in their order. A path's use is its area (pixels) times
/// how far its colour is from what it covers — the previous path of its region, or the
/// background for the first — so large paths that change the picture stay and small ones that
/// repeat their neighbour's colour go.
pub fn prune(
    paths: Vec<Placed>,
    budget: usize,
    (width, height): (u32, u32),
    background: [f32; 3],
) -> Vec<Placed> {
    let mut last_color: std::collections::HashMap<u32, [f32; 3]> = std::collections::HashMap::new();
    let usefulness: Vec<f32> = paths
        .iter()
        .map(|placed| {
            let under = last_color.insert(placed.region, placed.path.color).unwrap_or(background);
            let contrast: f32 = (0..3).map(|c| (placed.path.color[c] - under[c]).powi(2)).sum::<f32>().sqrt();
            area(&placed.path, width, height) * contrast
        })
        .collect();
    let mut order: Vec<usize> = (0..paths.len()).collect();
    order.sort_by(|&a, &b| usefulness[b].total_cmp(&usefulness[a]).then(a.cmp(&b)));
    let mut keep = vec![false; paths.len()];
    order.into_iter().take(budget).for_each(|index| keep[index] = true);
    paths.into_iter().zip(keep).filter_map(|(path, kept)| kept.then_some(path)).collect()
}

/// Area in pixels enclosed by a path (its control polygon flattened, shoelace formula).
fn area(path: &Path, width: u32, height: u32) -> f32 {
    const STEPS: usize = 8;
    let mut points = Vec::with_capacity(4 * STEPS);
    for j in 0..4 {
        let [p0, p1, p2, p3] = path.segment(j);
        for i in 0..STEPS {
            let t = i as f32 / STEPS as f32;
            let s = 1.0 - t;
            let w = [s * s * s, 3.0 * s * s * t, 3.0 * s * t * t, t * t * t];
            let x = w[0] * p0[0] + w[1] * p1[0] + w[2] * p2[0] + w[3] * p3[0];
            let y = w[0] * p0[1] + w[1] * p1[1] + w[2] * p2[1] + w[3] * p3[1];
            points.push([x * width as f32, y * height as f32]);
        }
    }
    let twice: f32 = (0..points.len())
        .map(|i| {
            let (a, b) = (points[i], points[(i + 1) % points.len()]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum();
    twice.abs() / 2.0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(lo: f32, hi: f32, color: [f32; 3]) -> Path {
        Path::quadrilateral([[lo, lo], [hi, lo], [hi, hi], [lo, hi]], color, 1.0)
    }

    #[test]
    fn area_of_a_square() {
        assert!((area(&square(0.25, 0.75, [0.0; 3]), 100, 40) - 50.0 * 20.0).abs() < 1e-2);
    }

    #[test]
    fn pruning_keeps_the_useful_paths_in_order() {
        let placed = |path, region| Placed { path, region };
        let paths = vec![
            placed(square(0.0, 1.0, [0.2, 0.2, 0.2]), 0), // big, dark on white: kept
            placed(square(0.4, 0.5, [0.2, 0.2, 0.2]), 0), // small, same colour as below: dropped
            placed(square(0.1, 0.6, [0.9, 0.1, 0.1]), 0), // large, red on dark: kept
            placed(square(0.7, 0.8, [0.0, 0.0, 1.0]), 1), // small but contrasting, its region's first
        ];
        let kept = prune(paths.clone(), 3, (64, 64), [1.0; 3]);
        assert_eq!(kept, vec![paths[0], paths[2], paths[3]]);
    }
}
