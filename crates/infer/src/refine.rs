//! The refinement stage: E_r adds paths to the regions drawn worst, and a path stays only if it
//! lowers the error of the box it was drawn in.

use burn::tensor::Device;
use model::{CropBatch, ModelConfig, RefineModel, canvas_cells, crop_to_image};
use serde::Serialize;
use superpixel::{RegionCrop, worst_first};

use crate::scene::{Origin, Placed, Scene, Scope};

/// What E_r did in a drawing: how many paths it proposed, how many lowered the error and were
/// kept, and by how much they lowered it. What an E_r checkpoint is worth to inference (`eval`
/// reports it per method; `--refine CKPT` scores another).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct RefineTally {
    /// Paths E_r proposed.
    pub proposed: usize,
    /// Paths kept.
    pub kept: usize,
    /// How much they raised the drawing's PSNR (dB, whole image): 10·log₁₀ of the squared
    /// error before over after.
    pub gain_db: f64,
}

/// Rounds of E_r until `scene` holds `budget` paths or no region is left to improve: each round
/// ranks the regions by squared error, gives E_r (target, canvas) crops of the worst `batch`
/// (as many as the remaining budget can use), and tries each proposed path over the current
/// drawing in its least-squares colour ([`Scene::fit_colour`]), keeping those that lower the
/// squared error of their box. A region none of whose
/// proposals helped is not proposed for again; the budget goes to the next-worst ones.
pub fn draw_refinement(
    refine: &RefineModel,
    config: &ModelConfig,
    scene: &mut Scene,
    budget: usize,
    batch: usize,
    device: &Device,
) -> RefineTally {
    let before = scene.total_error();
    let mut tally = RefineTally::default();
    let regions = scene.segmentation().regions.len();
    let mut exhausted = vec![false; regions];
    let mut crops: Vec<Option<RegionCrop>> = vec![None; regions];
    let (width, height) = scene.target().dimensions();
    'rounds: while scene.len() < budget {
        let remaining = budget - scene.len();
        let errors = scene.region_errors();
        let mut worst: Vec<u32> =
            (0..regions as u32).filter(|&r| !exhausted[r as usize] && errors[r as usize] > 0.0).collect();
        worst_first(&mut worst, &errors);
        worst.truncate(remaining.div_ceil(config.refine_paths).min(batch.max(1)));
        if worst.is_empty() {
            break;
        }
        for &r in &worst {
            if crops[r as usize].is_none() {
                crops[r as usize] = Some(scene.region_crop(config, r));
            }
        }
        let chosen: Vec<&RegionCrop> =
            worst.iter().map(|&r| crops[r as usize].as_ref().expect("cut above")).collect();
        let targets = CropBatch::new(chosen.iter().copied(), device);
        let canvas = canvas_cells(&scene.canvas_image(), chosen.iter().copied(), device);
        let canvas = targets.masked_canvas(canvas, &config.input);
        let proposals = refine.forward(targets.pixels, canvas).to_scenes();
        for ((&region, crop), paths) in worst.iter().zip(chosen).zip(proposals) {
            let mut kept = 0;
            for path in paths {
                if scene.len() == budget {
                    break 'rounds;
                }
                tally.proposed += 1;
                let path = crop_to_image(path, crop, width, height);
                let path = scene.fit_colour(&path, Scope::All).unwrap_or(path);
                let placed = Placed { shape: path.into(), region: Some(region), origin: Origin::Refine };
                if scene.try_push(placed, Scope::All).is_some() {
                    kept += 1;
                    tally.kept += 1;
                }
            }
            exhausted[region as usize] |= kept == 0;
        }
    }
    if tally.kept > 0 {
        tally.gain_db = 10.0 * (before / scene.total_error()).log10();
    }
    tally
}
