//! The coarse stage: the background, then region after region in painter's order its fallback
//! path and the coarse model's paths that draw it better.

use burn::tensor::Device;
use model::{CoarseModel, CropBatch, ModelConfig, crop_to_image};
use raster::Path;
use superpixel::{RegionCrop, worst_first};

use crate::fallback::FallbackDrawing;
use crate::scene::{Origin, Placed, Scene, Scope, region_errors};

/// How many paths the coarse stage may draw.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CoarseBudget {
    /// The most E_c paths kept (0: E_c is not run).
    pub paths: usize,
    /// The most paths the scene may hold when the stage ends (background and fallbacks
    /// included; they are always drawn).
    pub total: usize,
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
    let spare = budget.paths.min(budget.total.saturating_sub(1 + fallback.order.len()));
    let fallback_only = |scene: &Scene, fallback: FallbackDrawing| {
        let (target, segmentation) = (scene.target().clone(), scene.segmentation().clone());
        Scene::drawn(target, segmentation, fallback.placed(), fallback.canvas)
    };
    if spare == 0 {
        *scene = fallback_only(scene, fallback);
        return;
    }
    let mut proposals = vec![Vec::new(); fallback.order.len()];
    let chosen = worst_regions(scene, &fallback, spare);
    let crops: Vec<RegionCrop> = chosen.iter().map(|&r| scene.region_crop(config, r)).collect();
    let proposed = propose(coarse, &crops, scene.target().dimensions(), batch, device);
    for (&region, paths) in chosen.iter().zip(proposed) {
        proposals[region as usize] = paths;
    }
    let (order, fallbacks, background) = (&fallback.order, &fallback.regions, fallback.background);
    scene.push(Placed { shape: background.into(), region: None, origin: Origin::Background });
    let mut painted = vec![false; order.len()];
    // (index in the scene, error it took away) of every E_c path that helped.
    let mut gains: Vec<(usize, f64)> = Vec::new();
    for (&region, shape) in order.iter().zip(fallbacks) {
        painted[region as usize] = true;
        if let Some(shape) = shape {
            scene.push(Placed { shape: shape.clone(), region: Some(region), origin: Origin::Fallback });
        }
        for path in std::mem::take(&mut proposals[region as usize]) {
            let scope = Scope::Regions(&painted);
            let path = scene.fit_colour(&path, scope).unwrap_or(path);
            let placed = Placed { shape: path.into(), region: Some(region), origin: Origin::Coarse };
            if let Some(gain) = scene.try_push(placed, scope) {
                gains.push((scene.len() - 1, gain));
            }
        }
    }
    if gains.len() > spare {
        gains.sort_by(|a, b| b.1.total_cmp(&a.1));
        let mut dropped = vec![false; scene.len()];
        for &(index, _) in &gains[spare..] {
            dropped[index] = true;
        }
        scene.retain(|index, _| !dropped[index]);
    }
    if scene.counts().coarse == 0 || scene.total_error() > fallback.error {
        *scene = fallback_only(scene, fallback);
    }
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
fn propose(
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
