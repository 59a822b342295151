//! The input contract: how a region of an image becomes what E_c and E_r read.
//!
//! Training and inference build their inputs only through this module, with the settings a
//! checkpoint carries ([`InputSpec`] inside [`ModelConfig`]), so a model always sees at
//! inference the kind of input it was trained on: the same padding around the region's box, the
//! same resampling, the same fill outside the mask, and for E_r a canvas cut and masked exactly
//! like its target.

use burn::tensor::{Device, Tensor, TensorData};
use image::Rgb32FImage;
use raster::Path;
use superpixel::{CropOptions, RegionCrop, Segmentation, resample_area};

use crate::config::{InputSpec, ModelConfig};

/// The smallest region (pixels) a model is trained or validated on: a 4 × 4 patch, the least
/// that resized to the model's input still holds a shape rather than a few blurred cells.
pub const MIN_REGION_PIXELS: usize = 16;

impl ModelConfig {
    /// How crops for this model are cut (size, padding, fill).
    pub fn crop_options(&self) -> CropOptions {
        CropOptions { size: self.input_size, padding: self.input.padding, fill: self.input.fill }
    }

    /// Region `region` of `image` (segmented by `segmentation`), cut out as the models read it.
    ///
    /// # Panics
    /// If `region` is not a label of the segmentation or the image size differs from it.
    pub fn region_crop(&self, segmentation: &Segmentation, image: &Rgb32FImage, region: u32) -> RegionCrop {
        segmentation.crop(image, region, &self.crop_options())
    }
}

/// A path a model drew in `crop`'s unit square, moved to the unit square of the `width ×
/// height` image the crop was cut from.
pub fn crop_to_image(path: Path, crop: &RegionCrop, width: u32, height: u32) -> Path {
    path.map_points(|point| crop.transform.to_image_unit(point, width, height))
}

/// Region crops as tensors: what E_c reads, and E_r's target.
#[derive(Clone, Debug)]
pub struct CropBatch {
    /// `[B, 3, S, S]`: colours inside each region, the fill outside.
    pub pixels: Tensor<4>,
    /// `[B, 1, S, S]`: 1 inside each region, 0 outside.
    pub masks: Tensor<4>,
}

impl CropBatch {
    /// Stacks crops of one size on `device`.
    ///
    /// # Panics
    /// If `crops` is empty or the crops differ in size.
    pub fn new<'a>(crops: impl IntoIterator<Item = &'a RegionCrop>, device: &Device) -> Self {
        let (mut pixels, mut masks, mut count, mut size) = (Vec::new(), Vec::new(), 0, None);
        for crop in crops {
            assert!(size.is_none_or(|s| s == crop.size), "crops of one batch share a size");
            size = Some(crop.size);
            pixels.extend_from_slice(&crop.pixels);
            masks.extend_from_slice(&crop.mask);
            count += 1;
        }
        let size = size.expect("a batch holds at least one crop");
        Self {
            pixels: Tensor::from_data(TensorData::new(pixels, [count, 3, size, size]), device),
            masks: Tensor::from_data(TensorData::new(masks, [count, 1, size, size]), device),
        }
    }

    /// `[B, 3, 1, 1]`: each crop's mean colour inside its mask (what inference's fallback fills
    /// the region with before any network draws on it); 0 for an empty mask.
    pub fn mean_colours(&self) -> Tensor<4> {
        let area = self.masks.clone().sum_dim(2).sum_dim(3).clamp_min(1.0);
        (self.pixels.clone() * self.masks.clone()).sum_dim(2).sum_dim(3) / area
    }

    /// E_r's second input: `canvas` (`[B, 3, S, S]`, what is drawn so far over each crop's
    /// rectangle) with `spec.fill` outside each region's mask, the rule the crops follow.
    pub fn masked_canvas(&self, canvas: Tensor<4>, spec: &InputSpec) -> Tensor<4> {
        let masks = self.masks.clone();
        canvas * masks.clone() + (masks.neg() + 1.0) * spec.fill
    }
}

/// The canvas under each crop's rectangle, area-resampled to the crop's cells: `[B, 3, S, S]`
/// for [`CropBatch::masked_canvas`] at inference, where what is drawn so far is an image.
///
/// # Panics
/// If `crops` is empty or the crops differ in size.
pub fn canvas_cells<'a>(
    canvas: &Rgb32FImage,
    crops: impl IntoIterator<Item = &'a RegionCrop>,
    device: &Device,
) -> Tensor<4> {
    let (mut values, mut count, mut size) = (Vec::new(), 0, 0);
    for crop in crops {
        values.extend(resample_area(canvas, &crop.transform, crop.size));
        size = crop.size;
        count += 1;
    }
    assert!(count > 0, "a batch holds at least one crop");
    Tensor::from_data(TensorData::new(values, [count, 3, size, size]), device)
}

#[cfg(test)]
mod tests {
    use image::Rgb;
    use superpixel::{SlicOptions, slic};

    use super::*;
    use crate::config::Preset;

    #[test]
    fn canvases_are_masked_like_crops() {
        let image = Rgb32FImage::from_fn(48, 32, |x, y| {
            Rgb([x as f32 / 48.0, y as f32 / 32.0, if (x / 12 + y / 8) % 2 == 0 { 0.9 } else { 0.1 }])
        });
        let segmentation = slic(&image, &SlicOptions { n_segments: 6, ..Default::default() }).unwrap();
        let config = ModelConfig { input_size: 16, ..ModelConfig::preset(Preset::Cpu) };
        let device = Device::flex();
        let crops: Vec<RegionCrop> = (0..segmentation.regions.len() as u32)
            .map(|r| config.region_crop(&segmentation, &image, r))
            .collect();
        let batch = CropBatch::new(&crops, &device);
        // The canvas of a perfect drawing, masked, is the crop itself (up to resampling: both
        // average the same pixels where the cell lies wholly inside the region).
        let canvas = batch.masked_canvas(canvas_cells(&image, &crops, &device), &config.input);
        let (canvas, pixels, masks): (Vec<f32>, Vec<f32>, Vec<f32>) = (
            canvas.try_to_vec_as().unwrap(),
            batch.pixels.try_to_vec_as().unwrap(),
            batch.masks.try_to_vec_as().unwrap(),
        );
        let cells = 16 * 16;
        for (index, (&drawn, &target)) in canvas.iter().zip(&pixels).enumerate() {
            let mask = masks[(index / (3 * cells)) * cells + index % cells];
            if mask == 0.0 {
                assert_eq!((drawn, target), (-1.0, -1.0));
            }
        }
    }
}
