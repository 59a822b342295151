//! SuperSVG-F: optimizing every path of a result against the image with the soft rasterizer.
//!
//! Region-local so it scales to thousands of paths: the paths of one superpixel are optimized
//! inside that region's padded bounding box, painted over a fixed exact rendering of all other
//! paths, against the image there (L2, Adam). Regions take turns, worst first, until the step
//! or time budget is spent. Coordinates stay in the region's box and colours in [0, 1].

use std::time::Instant;

use burn::module::Param;
use burn::optim::{AdamConfig, GradientsParams};
use burn::tensor::{Device, Tensor, TensorData};
use image::Rgb32FImage;
use raster::{PARAMS, Path, PathBatch, SoftRasterOptions, paint_exact, paint_soft, render_exact};
use superpixel::{BoundingBox, CropTransform};
use tiny_skia::Pixmap;

use crate::scene::{Scene, pixel_error};

/// How long to fine-tune.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Budget {
    /// This many Adam steps for every region.
    StepsPerRegion(usize),
    /// Rounds over all regions until this many seconds have passed.
    Seconds(f64),
}

/// Settings of the fine-tuning.
#[derive(Clone, Debug)]
pub struct FinetuneOptions {
    /// When to stop.
    pub budget: Budget,
    /// Adam learning rate (parameters are in units of the region's box).
    pub lr: f64,
    /// Adam steps a region takes per turn.
    pub steps_per_turn: usize,
    /// Pixels added around each region's box.
    pub padding: u32,
    /// The soft rasterizer.
    pub raster: SoftRasterOptions,
}

impl Default for FinetuneOptions {
    fn default() -> Self {
        Self {
            budget: Budget::StepsPerRegion(20),
            lr: 1e-3,
            steps_per_turn: 5,
            padding: 4,
            raster: SoftRasterOptions::default(),
        }
    }
}

/// Fine-tunes the paths of `scene` (all but the background) against its image on `device`
/// (with autodiff). A region's tuned paths are kept only where the exact drawing of its box
/// gets closer to the image; if the whole exact rendering still came out worse than before,
/// the scene keeps its old paths. Returns the number of optimizer steps taken.
pub fn finetune(scene: &mut Scene, options: &FinetuneOptions, device: &Device) -> usize {
    let started = Instant::now();
    let before: f64 = scene.region_errors().iter().sum();
    let original = scene.scene();
    let image = scene.target().clone();
    let (width, height) = image.dimensions();
    let segmentation = scene.segmentation().clone();
    let regions: Vec<Option<u32>> = scene.paths().iter().map(|placed| placed.region).collect();
    let mut paths = scene.scene();
    let mut order: Vec<u32> = (0..segmentation.regions.len() as u32).collect();
    let errors = scene.region_errors();
    order.sort_by(|a, b| errors[*b as usize].total_cmp(&errors[*a as usize]));
    let mut steps = 0;
    let mut taken = vec![0usize; order.len()];
    'rounds: loop {
        let mut progressed = false;
        for &region in &order {
            let turn = match options.budget {
                Budget::StepsPerRegion(total) => options.steps_per_turn.min(total - taken[region as usize]),
                Budget::Seconds(limit) if started.elapsed().as_secs_f64() >= limit => break 'rounds,
                Budget::Seconds(_) => options.steps_per_turn,
            };
            let members: Vec<usize> = (0..paths.len()).filter(|&i| regions[i] == Some(region)).collect();
            if turn == 0 || members.is_empty() {
                continue;
            }
            let bbox = segmentation.regions[region as usize].bbox.padded(options.padding, width, height);
            let transform = CropTransform::of_box(bbox);
            let others: Vec<Path> =
                paths.iter().enumerate().filter(|(i, _)| !members.contains(i)).map(|(_, p)| *p).collect();
            let local: Vec<Path> =
                members.iter().map(|&i| to_box(paths[i], &transform, width, height)).collect();
            let tuned = optimize(&local, &others, &image, bbox, turn, options, device);
            // Kept only if the exact drawing of the box, every path in painter's order, is
            // closer to the image: the soft render over a fixed canvas only approximates it.
            let mut candidate = paths.clone();
            for (&i, path) in members.iter().zip(tuned) {
                candidate[i] = from_box(path, &transform, width, height);
            }
            if box_error(&candidate, &image, bbox) < box_error(&paths, &image, bbox) {
                paths = candidate;
            }
            taken[region as usize] += turn;
            steps += turn;
            progressed = true;
        }
        if !progressed {
            break;
        }
    }
    scene.set_paths(&paths);
    if scene.region_errors().iter().sum::<f64>() > before {
        scene.set_paths(&original);
    }
    steps
}

/// Squared error inside `bbox` between `paths`, painted exactly in order (over white, as
/// [`Scene`] scores), and `image`.
fn box_error(paths: &[Path], image: &Rgb32FImage, bbox: BoundingBox) -> f64 {
    let (width, height) = image.dimensions();
    let Some(mut pixmap) = Pixmap::new(bbox.width(), bbox.height()) else { return 0.0 };
    for path in paths {
        paint_exact(&mut pixmap, path, (width, height), (bbox.x0, bbox.y0));
    }
    let mut sum = 0.0;
    for y in 0..bbox.height() {
        for x in 0..bbox.width() {
            let index = (y * bbox.width() + x) as usize;
            sum += pixel_error(pixmap.data(), index, image.get_pixel(bbox.x0 + x, bbox.y0 + y));
        }
    }
    sum
}

/// `steps` Adam steps on `local` (box unit square) painted over the exact rendering of
/// `others`, against the image inside `bbox`.
fn optimize(
    local: &[Path],
    others: &[Path],
    image: &Rgb32FImage,
    bbox: BoundingBox,
    steps: usize,
    options: &FinetuneOptions,
    device: &Device,
) -> Vec<Path> {
    let (width, height) = image.dimensions();
    let (w, h) = (bbox.width() as usize, bbox.height() as usize);
    let everything_else =
        image::DynamicImage::ImageRgb8(render_exact(others, width, height, options.raster.background))
            .to_rgb32f();
    let planar = |source: &Rgb32FImage| -> Tensor<4> {
        let values: Vec<f32> = (0..3)
            .flat_map(|c| {
                (bbox.y0..bbox.y1)
                    .flat_map(move |y| (bbox.x0..bbox.x1).map(move |x| source.get_pixel(x, y).0[c]))
            })
            .collect();
        Tensor::from_data(TensorData::new(values, [1, 3, h, w]), device)
    };
    let (canvas, target) = (planar(&everything_else), planar(image));
    let initial = PathBatch::from_scenes(&[local.to_vec()], device).into_params();
    let mut params = Param::from_tensor(initial);
    let mut optimizer = AdamConfig::new().init();
    for _ in 0..steps {
        let render = paint_soft(canvas.clone(), &PathBatch::new(params.val()), &options.raster);
        let loss = (render - target.clone()).square().mean();
        let grads = GradientsParams::from_grads(loss.backward(), &params);
        params = optimizer.step(options.lr, params, grads);
        params = params.map(|p| keep_in_range(p).detach().require_grad());
    }
    let tuned = PathBatch::new(params.val().detach());
    tuned.to_scenes().remove(0)
}

/// Coordinates and colours clamped to [0, 1]; α left as it is.
fn keep_in_range(params: Tensor<3>) -> Tensor<3> {
    let [batch, paths, _] = params.dims();
    let ranged = params.clone().narrow(2, 0, PARAMS - 1).clamp(0.0, 1.0);
    Tensor::cat(vec![ranged, params.narrow(2, PARAMS - 1, 1).reshape([batch, paths, 1])], 2)
}

fn to_box(path: Path, transform: &CropTransform, width: u32, height: u32) -> Path {
    path.map_points(|[x, y]| transform.from_image([x * width as f32, y * height as f32]))
}

fn from_box(path: Path, transform: &CropTransform, width: u32, height: u32) -> Path {
    path.map_points(|p| transform.to_image_unit(p, width, height))
}
