//! The coarse stage: the background, then region after region in painter's order its fallback
//! path and the coarse model's paths that draw it better.

use burn::tensor::Device;
use model::{CoarseModel, CropBatch, ModelConfig, crop_to_image};
use raster::Path;
use superpixel::RegionCrop;

use crate::fallback::FallbackDrawing;
use crate::scene::{Origin, Placed, Scene, Scope};

/// How many coarse paths the stage may keep.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CoarseBudget {
    /// The most E_c paths kept per region (0: E_c is not run).
    pub per_region: usize,
    /// The most paths the scene may hold when the stage ends (background and fallbacks
    /// included; they are always drawn).
    pub total: usize,
}

/// Draws `scene` (which must be empty) from `fallback`, the fallback drawing of its
/// segmentation: the background path, then for every region in painter's order its fallback
/// path and, in E_c's order, each visible E_c path that lowers the squared
/// error over the pixels of the regions painted so far (later regions will paint over the
/// rest), up to the budget. If the kept paths together made the whole image worse than the
/// fallback drawing alone (a path can reach a later region where its fallback leaves a seam),
/// they are all dropped.
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
    let FallbackDrawing { order, regions: fallbacks, background } = fallback;
    let proposals = if budget.per_region == 0 {
        vec![Vec::new(); order.len()]
    } else {
        let crops: Vec<RegionCrop> = order.iter().map(|&r| scene.region_crop(config, r)).collect();
        propose(coarse, &crops, scene.target().dimensions(), batch, device)
    };
    scene.push(Placed { path: background, region: None, origin: Origin::Background });
    let mut spare = budget.total.saturating_sub(1 + order.len());
    let mut painted = vec![false; order.len()];
    for ((&region, fallback), candidates) in order.iter().zip(fallbacks).zip(proposals) {
        painted[region as usize] = true;
        if let Some(path) = fallback {
            scene.push(Placed { path, region: Some(region), origin: Origin::Fallback });
        }
        let mut kept = 0;
        for path in candidates {
            if kept == budget.per_region || spare == 0 {
                break;
            }
            let placed = Placed { path, region: Some(region), origin: Origin::Coarse };
            if scene.try_push(placed, Scope::Regions(&painted), 0.0) {
                kept += 1;
                spare -= 1;
            }
        }
    }
    if scene.paths().iter().any(|placed| placed.origin == Origin::Coarse) {
        let mut fallback_only = scene.clone();
        fallback_only.retain(|placed| placed.origin != Origin::Coarse);
        if scene.total_error() > fallback_only.total_error() {
            *scene = fallback_only;
        }
    }
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
            let visible = scene.into_iter().filter(|path| path.alpha > 0.5);
            proposals.push(
                visible.map(|path| crop_to_image(Path { alpha: 1.0, ..path }, crop, width, height)).collect(),
            );
        }
    }
    proposals
}
