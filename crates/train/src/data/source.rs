//! What a training batch is, and how batch `i` is made from the seed alone.

use burn::tensor::{Device, Tensor, TensorData};
use image::Rgb32FImage;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use superpixel::{CropOptions, SlicOptions, slic};

use super::images::ImageSet;
use super::synthetic::synthetic_scene;
use crate::config::DataConfig;

/// A data problem (missing folder, no images…), with a message naming the setting.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct DataError(String);

impl DataError {
    pub(crate) fn new(message: String) -> Self {
        Self(message)
    }
}

/// Region crops and masks of one step, on the CPU.
#[derive(Clone, Debug, PartialEq)]
pub struct Batch {
    /// Index of the batch in the data stream (the step it is for).
    pub index: u64,
    /// Samples in the batch.
    pub size: usize,
    /// Side of every crop.
    pub crop: usize,
    /// `[B, 3, S, S]`: colours inside the region, −1 outside (model input and target).
    pub pixels: Vec<f32>,
    /// `[B, 1, S, S]`: 1 inside the region.
    pub masks: Vec<f32>,
}

impl Batch {
    /// The crops and masks as tensors on `device`.
    pub fn tensors(&self, device: &Device) -> (Tensor<4>, Tensor<4>) {
        let (b, s) = (self.size, self.crop);
        let pixels = Tensor::from_data(TensorData::new(self.pixels.clone(), [b, 3, s, s]), device);
        let masks = Tensor::from_data(TensorData::new(self.masks.clone(), [b, 1, s, s]), device);
        (pixels, masks)
    }
}

/// Where samples come from: generated scenes, an image folder, or both.
pub struct DataSource {
    config: DataConfig,
    images: Option<ImageSet>,
    crop: CropOptions,
    batch_size: usize,
    seed: u64,
}

/// Regions cut from one segmented scene before moving to the next (SLIC is the costly part).
const REGIONS_PER_SCENE: usize = 4;
/// Regions smaller than this many pixels are not used as samples (too little to learn from).
const MIN_REGION_PIXELS: usize = 16;

impl DataSource {
    /// Opens the sources of `config` (reading the image folder, if any).
    pub fn new(
        config: &DataConfig,
        crop_size: usize,
        batch_size: usize,
        seed: u64,
    ) -> Result<Self, DataError> {
        let images =
            config.images.as_deref().map(|folder| ImageSet::load(folder, config.image_size)).transpose()?;
        let crop = CropOptions { size: crop_size, padding: config.crop_padding, fill: -1.0 };
        Ok(Self { config: config.clone(), images, crop, batch_size, seed })
    }

    /// Batch `index` of the stream: a pure function of the seed and the index, so a resumed run
    /// sees exactly the batches an uninterrupted one would (with `fixed_batch`, batch 0's
    /// content every time).
    pub fn batch(&self, index: u64) -> Batch {
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        rng.set_stream(if self.config.fixed_batch { 0 } else { index });
        let s = self.crop.size;
        let (mut pixels, mut masks) = (Vec::new(), Vec::new());
        while masks.len() < self.batch_size * s * s {
            let scene = self.scene(&mut rng);
            let [low, high] = self.config.segments;
            let options = SlicOptions {
                n_segments: rng.random_range(low..=high).min((scene.width() * scene.height()) as usize),
                compactness: self.config.compactness,
                ..Default::default()
            };
            let segmentation =
                slic(&scene, &options).expect("generated and loaded scenes are valid SLIC inputs");
            let mut regions: Vec<u32> = (0..segmentation.regions.len() as u32)
                .filter(|&r| segmentation.regions[r as usize].pixels >= MIN_REGION_PIXELS)
                .collect();
            regions.shuffle(&mut rng);
            for &region in regions.iter().take(REGIONS_PER_SCENE) {
                if masks.len() == self.batch_size * s * s {
                    break;
                }
                let crop = segmentation.crop(&scene, region, &self.crop);
                pixels.extend(crop.pixels);
                masks.extend(crop.mask);
            }
        }
        Batch { index, size: self.batch_size, crop: s, pixels, masks }
    }

    /// A scene to cut regions from: generated or from the folder, by `synthetic_weight`.
    fn scene(&self, rng: &mut ChaCha8Rng) -> Rgb32FImage {
        let synthetic = match (&self.images, self.config.synthetic) {
            (None, _) => true,
            (Some(_), false) => false,
            (Some(_), true) => rng.random_bool(self.config.synthetic_weight as f64),
        };
        match &self.images {
            Some(images) if !synthetic => images.get(rng.random_range(0..images.len())),
            _ => synthetic_scene(rng, self.config.image_size),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn batches_depend_only_on_seed_and_index() {
        let config = DataConfig { image_size: 64, segments: [4, 8], ..Default::default() };
        let source = DataSource::new(&config, 16, 5, 7).unwrap();
        let batch = source.batch(3);
        assert_eq!(batch.pixels.len(), 5 * 3 * 16 * 16);
        assert_eq!(batch.masks.len(), 5 * 16 * 16);
        assert_eq!(batch, DataSource::new(&config, 16, 5, 7).unwrap().batch(3));
        assert_ne!(batch, source.batch(4));
        assert_ne!(batch, DataSource::new(&config, 16, 5, 8).unwrap().batch(3));
        // Every crop has some region and fills outside it with −1.
        for sample in 0..5 {
            let mask = &batch.masks[sample * 256..(sample + 1) * 256];
            assert!(mask.iter().any(|&m| m == 1.0));
            let red = &batch.pixels[sample * 3 * 256..sample * 3 * 256 + 256];
            assert!(mask.iter().zip(red).all(|(&m, &p)| if m == 0.0 {
                p == -1.0
            } else {
                (0.0..=1.0).contains(&p)
            }));
        }
    }
}
