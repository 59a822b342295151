//! A fixed set of region crops from held-out images, and how well a model draws them.
//!
//! Scored the way inference uses a model: each crop starts as its region's mean colour (the
//! fallback), the model's paths are painted over it with the exact renderer, and a path counts
//! only if it lowers the error inside the region (inference's acceptance test). The figure to
//! beat is the flat fill itself.

use image::Rgb32FImage;
use model::{MIN_REGION_PIXELS, ModelConfig};
use raster::{Path, coverage_exact, paint_exact};
use serde::Serialize;
use superpixel::{RegionCrop, SegmentOptions, segment};
use tiny_skia::{Color, Pixmap};

use crate::config::{DataConfig, ValidationConfig};
use crate::data::{DataError, ImageSet};

/// The validation crops.
pub struct Validation {
    crops: Vec<RegionCrop>,
    dilation: usize,
}

/// How a model drew the validation crops.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Scores {
    /// PSNR (dB) inside the regions of the flat mean-colour fill: the bar to clear.
    pub psnr_flat: f64,
    /// PSNR inside the regions with every visible path painted over the fill.
    pub psnr_drawn: f64,
    /// PSNR inside the regions with only the paths that helped (inference's acceptance).
    pub psnr_kept: f64,
    /// Share of the visible paths' area outside their region's mask dilated by the boundary
    /// loss's dilation (in crop cells).
    pub spill: f64,
    /// Visible paths per crop.
    pub visible: f64,
    /// Paths per crop that helped.
    pub kept: f64,
}

impl Validation {
    /// Cuts the set from `config.images`, with regions made as inference makes them (`data`
    /// gives the SLIC compactness) and crops cut
    /// by `model`'s input contract; `dilation` is the boundary loss's. Deterministic.
    pub fn build(
        config: &ValidationConfig,
        data: &DataConfig,
        model: &ModelConfig,
        dilation: usize,
    ) -> Result<Option<Self>, DataError> {
        let Some(folder) = &config.images else { return Ok(None) };
        let images = ImageSet::load(folder, config.image_size)?;
        let per_image = config.crops.div_ceil(images.len());
        let mut crops = Vec::with_capacity(config.crops);
        for index in 0..images.len() {
            let scene: &Rgb32FImage = images.get(index);
            let count = region_count(config.segments, index, images.len());
            let count = count.clamp(1, (scene.width() * scene.height()) as usize);
            let options = SegmentOptions::ward(data.compactness);
            let segmentation = segment(scene, count, &options)
                .map_err(|source| DataError::ValidationSegment { path: folder.clone(), source })?;
            let usable: Vec<u32> = (0..segmentation.regions.len() as u32)
                .filter(|&r| segmentation.regions[r as usize].pixels >= MIN_REGION_PIXELS)
                .collect();
            let step = (usable.len() / per_image.max(1)).max(1);
            for &region in usable.iter().step_by(step).take(per_image) {
                crops.push(model.region_crop(&segmentation, scene, region));
            }
        }
        crops.truncate(config.crops);
        if crops.is_empty() {
            return Err(DataError::NoValidationCrops { path: folder.clone(), min: MIN_REGION_PIXELS });
        }
        Ok(Some(Self { crops, dilation }))
    }

    /// [`Validation::build`] with how often a run scores the set (`config.every` steps): what
    /// [`crate::trainer::Run`] takes.
    pub fn scheduled(
        config: &ValidationConfig,
        data: &DataConfig,
        model: &ModelConfig,
        dilation: usize,
    ) -> Result<Option<(Self, usize)>, DataError> {
        Ok(Self::build(config, data, model, dilation)?.map(|set| (set, config.every)))
    }

    /// The crops.
    pub fn crops(&self) -> &[RegionCrop] {
        &self.crops
    }

    /// Each crop's mean colour inside its mask.
    pub fn mean_colours(&self) -> Vec<[f32; 3]> {
        self.crops.iter().map(RegionCrop::mean_colour).collect()
    }

    /// Scores `scenes` (one per crop, paths in the crop's unit square with their opacity).
    ///
    /// # Panics
    /// If there are fewer scenes than crops.
    pub fn score(&self, scenes: &[Vec<Path>]) -> Scores {
        assert!(scenes.len() >= self.crops.len(), "one scene per validation crop");
        let (mut flat, mut drawn, mut kept, mut cells) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        let (mut outside, mut covered, mut visible, mut helped) = (0.0f64, 0.0f64, 0usize, 0usize);
        for (crop, scene) in self.crops.iter().zip(scenes) {
            let size = crop.size as u32;
            let color = crop.mean_colour();
            let mut canvas = Pixmap::new(size, size).expect("a non-empty crop");
            let [r, g, b] = color.map(|c| c.clamp(0.0, 1.0));
            canvas.fill(Color::from_rgba(r, g, b, 1.0).expect("a clamped colour"));
            let start = masked_error(crop, &canvas);
            flat += start;
            cells += 3.0 * crop.mask.iter().map(|&m| m as f64).sum::<f64>();
            let shown: Vec<&Path> = scene.iter().filter(|path| path.is_visible()).collect();
            visible += shown.len();

            let mut all = canvas.clone();
            for path in &shown {
                paint_exact(&mut all, path, (size, size), (0, 0));
            }
            drawn += masked_error(crop, &all);

            let (mut best, mut current) = (canvas, start);
            for path in &shown {
                let mut trial = best.clone();
                paint_exact(&mut trial, path, (size, size), (0, 0));
                let error = masked_error(crop, &trial);
                if error < current {
                    (best, current) = (trial, error);
                    helped += 1;
                }
            }
            kept += current;

            let near = dilate(&crop.mask, crop.size, self.dilation);
            for path in &shown {
                let Some(mask) = coverage_exact(path, size, size) else { continue };
                for (value, &inside) in mask.data().iter().zip(&near) {
                    let coverage = *value as f64 / 255.0;
                    covered += coverage;
                    if !inside {
                        outside += coverage;
                    }
                }
            }
        }
        let psnr = |error: f64| common::psnr_of_mse(error / cells.max(1.0));
        let crops = self.crops.len().max(1) as f64;
        Scores {
            psnr_flat: psnr(flat),
            psnr_drawn: psnr(drawn),
            psnr_kept: psnr(kept),
            spill: if covered > 0.0 { outside / covered } else { 0.0 },
            visible: visible as f64 / crops,
            kept: helped as f64 / crops,
        }
    }
}

/// The region count of image `index` of `images`: `[low, high]` spread geometrically from the
/// first image to the last.
pub(crate) fn region_count([low, high]: [usize; 2], index: usize, images: usize) -> usize {
    let t = if images > 1 { index as f64 / (images - 1) as f64 } else { 0.0 };
    (low as f64 * (high as f64 / low as f64).powf(t)).round() as usize
}

/// Sum of squared differences inside the crop's mask between the canvas and the crop.
fn masked_error(crop: &RegionCrop, canvas: &Pixmap) -> f64 {
    let cells = crop.size * crop.size;
    let data = canvas.data();
    let mut sum = 0.0f64;
    for (cell, &inside) in crop.mask.iter().enumerate() {
        if inside == 0.0 {
            continue;
        }
        for c in 0..3 {
            let drawn = data[4 * cell + c] as f64 / 255.0;
            sum += (drawn - crop.pixels[c * cells + cell] as f64).powi(2);
        }
    }
    sum
}

/// The mask grown by `radius` cells (Chebyshev), as booleans.
fn dilate(mask: &[f32], size: usize, radius: usize) -> Vec<bool> {
    let mut out = vec![false; size * size];
    for y in 0..size {
        for x in 0..size {
            let (y0, y1) = (y.saturating_sub(radius), (y + radius).min(size - 1));
            let (x0, x1) = (x.saturating_sub(radius), (x + radius).min(size - 1));
            out[y * size + x] = (y0..=y1).any(|v| (x0..=x1).any(|u| mask[v * size + u] > 0.5));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use image::{Rgb, RgbImage};

    use super::*;

    #[test]
    fn flat_fill_is_the_bar_and_helpful_paths_clear_it() {
        let dir = std::env::temp_dir().join(format!("supersvg-validation-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        RgbImage::from_fn(
            64,
            48,
            |x, y| if x < 32 && y < 24 { Rgb([230, 40, 40]) } else { Rgb([20, 40, 200]) },
        )
        .save(dir.join("a.png"))
        .unwrap();
        let config = ValidationConfig {
            images: Some(dir.clone()),
            crops: 3,
            segments: [2, 2],
            every: 10,
            image_size: 64,
            refine_share: 0.1,
            coarse_share: 0.2,
        };
        let data = DataConfig { image_size: 64, ..Default::default() };
        let model = ModelConfig { input_size: 16, ..ModelConfig::preset(model::Preset::Cpu) };
        let validation = Validation::build(&config, &data, &model, 1).unwrap().unwrap();
        assert_eq!(validation.crops().len(), 2, "one crop per region of the two-region image");

        // Images too small to hold a region of MIN_REGION_PIXELS refuse to make a set.
        let tiny = dir.join("tiny");
        std::fs::create_dir_all(&tiny).unwrap();
        RgbImage::from_pixel(3, 3, Rgb([9, 9, 9])).save(tiny.join("a.png")).unwrap();
        let config_tiny = ValidationConfig { images: Some(tiny.clone()), ..config.clone() };
        let err = Validation::build(&config_tiny, &data, &model, 1).err().expect("no crops is an error");
        assert!(matches!(&err, DataError::NoValidationCrops { path, .. } if *path == tiny), "{err}");

        let nothing = vec![Vec::new(); validation.crops().len()];
        let scores = validation.score(&nothing);
        assert_eq!(
            (scores.psnr_drawn, scores.psnr_kept, scores.kept),
            (scores.psnr_flat, scores.psnr_flat, 0.0)
        );
        // A path in the wrong colour over the whole crop: drawn is worse, kept leaves it out,
        // and it spills wherever the region does not fill the crop.
        let wrong =
            Path::quadrilateral([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]], [0.0, 1.0, 0.0], 1.0);
        let scores_wrong = validation.score(&vec![vec![wrong]; validation.crops().len()]);
        assert!(scores_wrong.psnr_drawn < scores.psnr_flat);
        assert_eq!(scores_wrong.psnr_kept, scores.psnr_flat);
        assert_eq!(scores_wrong.visible, 1.0);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
