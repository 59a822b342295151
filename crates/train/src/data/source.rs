//! What a training batch is, and how batch `i` is made from the seed alone.

use std::path::PathBuf;

use burn::tensor::Device;
use image::Rgb32FImage;
use model::{CropBatch, MIN_REGION_PIXELS, ModelConfig};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use superpixel::{RegionCrop, Segmentation, SlicError, segment, worst_first};

use super::images::{EXTENSIONS, ImageSet};
use super::synthetic::synthetic_scene;
use crate::config::{DataConfig, RegionPick};

/// A data problem: a folder that cannot be used (missing, no images…), or a batch that could not
/// be made.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    /// An image folder (`data.images`, `validation.images`) is not a folder.
    #[error("{}: not a folder", .0.display())]
    NotAFolder(PathBuf),
    /// An image folder holds no image that decodes.
    #[error("{}: no readable image (looked for {})", .0.display(), EXTENSIONS.join(", "))]
    NoImages(PathBuf),
    /// A validation image could not be segmented.
    #[error("validation: {}: {source}", path.display())]
    ValidationSegment {
        /// The validation folder.
        path: PathBuf,
        /// SLIC's reason.
        source: SlicError,
    },
    /// A validation folder whose images give no region large enough to score.
    #[error(
        "validation: {}: no region of {min} pixels or more in any image at the validation size; \
         use larger images or a larger validation.image_size",
        path.display()
    )]
    NoValidationCrops {
        /// The validation folder.
        path: PathBuf,
        /// The smallest region a crop is cut from.
        min: usize,
    },
    /// A scene of batch `index` could not be segmented (an option out of SLIC's range).
    #[error("batch {index}: a scene could not be segmented: {source}")]
    Segment {
        /// The batch.
        index: u64,
        /// SLIC's reason.
        source: SlicError,
    },
    /// A data thread stopped before delivering its batches (it panicked).
    #[error("the data thread preparing batch {0} stopped")]
    WorkerStopped(u64),
    /// Scene after scene held no region large enough to be a sample: the images (or the
    /// region counts of `[data] segments`) are too small for the model's crops.
    #[error(
        "batch {index}: {tried} scenes in a row gave no region of {min} pixels or more{}; use larger images, \
         a larger data.image_size or fewer data.segments",
        folder.as_ref().map(|f| format!(" (images from {})", f.display())).unwrap_or_default()
    )]
    NoUsableRegions {
        /// The batch being made.
        index: u64,
        /// Scenes tried.
        tried: usize,
        /// The smallest region a sample is cut from.
        min: usize,
        /// The image folder, when scenes came from one.
        folder: Option<PathBuf>,
    },
    /// Ctrl-C or SIGTERM while a folder was being read.
    #[error("{}: interrupted while reading the images", .0.display())]
    Interrupted(PathBuf),
}

/// How many scenes in a row may give no sample before a batch gives up: a folder of images too
/// small for any region would otherwise keep the data thread (and the trainer waiting on it)
/// busy for ever.
const BARREN_SCENES: usize = 256;

/// Region crops of one step, on the CPU.
#[derive(Clone, Debug, PartialEq)]
pub struct Batch {
    /// Index of the batch in the data stream (the step it is for).
    pub index: u64,
    /// The samples, cut by the model's input contract ([`ModelConfig::region_crop`]).
    pub crops: Vec<RegionCrop>,
}

impl Batch {
    /// The crops and masks as tensors on `device`.
    pub fn tensors(&self, device: &Device) -> CropBatch {
        CropBatch::new(&self.crops, device)
    }
}

/// Where samples come from: generated scenes, an image folder, or both.
pub struct DataSource {
    config: DataConfig,
    images: Option<ImageSet>,
    model: ModelConfig,
    batch_size: usize,
    seed: u64,
}

impl DataSource {
    /// Opens the sources of `config` (reading the image folder, if any) for a model of
    /// configuration `model` (whose input contract cuts the crops).
    pub fn new(
        config: &DataConfig,
        model: &ModelConfig,
        batch_size: usize,
        seed: u64,
    ) -> Result<Self, DataError> {
        let images =
            config.images.as_deref().map(|folder| ImageSet::load(folder, config.image_size)).transpose()?;
        if let (Some(folder), Some(images)) = (&config.images, &images)
            && !config.synthetic
            && images.largest_pixels() < MIN_REGION_PIXELS
        {
            let tried = images.len();
            return Err(DataError::NoUsableRegions {
                index: 0,
                tried,
                min: MIN_REGION_PIXELS,
                folder: Some(folder.clone()),
            });
        }
        Ok(Self { config: config.clone(), images, model: model.clone(), batch_size, seed })
    }

    /// Region `region` of `scene` as a training sample: exactly the model input inference
    /// builds for the same region of the same image.
    pub fn sample(&self, scene: &Rgb32FImage, segmentation: &Segmentation, region: u32) -> RegionCrop {
        self.model.region_crop(segmentation, scene, region)
    }

    /// Batch `index` of the stream: a pure function of the seed and the index, so a resumed run
    /// sees exactly the batches an uninterrupted one would (with `fixed_batch`, batch 0's
    /// content every time). Fails only when the segmentation options are out of SLIC's range.
    pub fn batch(&self, index: u64) -> Result<Batch, DataError> {
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        rng.set_stream(if self.config.fixed_batch { 0 } else { index });
        let mut crops = Vec::with_capacity(self.batch_size);
        let mut barren = 0;
        while crops.len() < self.batch_size {
            if barren == BARREN_SCENES {
                let folder = self.config.images.clone();
                return Err(DataError::NoUsableRegions {
                    index,
                    tried: barren,
                    min: MIN_REGION_PIXELS,
                    folder,
                });
            }
            let whole = self.scene(&mut rng);
            let [low, high] = self.config.segments;
            let count = rng.random_range(low..=high);
            // Regions as large as the count makes them on the whole scene, cut from a window.
            let scene = window(&whole, self.config.window, &mut rng);
            let share = (scene.width() * scene.height()) as f64 / (whole.width() * whole.height()) as f64;
            let count =
                ((count as f64 * share).round() as usize).clamp(1, (scene.width() * scene.height()) as usize);
            let segmentation = segment(&scene, count, &self.config.segment_options())
                .map_err(|source| DataError::Segment { index, source })?;
            let regions = pick_regions(&scene, &segmentation, self.config.pick, &mut rng);
            barren = if regions.is_empty() { barren + 1 } else { 0 };
            for &region in regions.iter().take(self.config.regions_per_scene) {
                if crops.len() == self.batch_size {
                    break;
                }
                crops.push(self.sample(&scene, &segmentation, region));
            }
        }
        Ok(Batch { index, crops })
    }

    /// A scene to take regions from: generated or from the folder, by `synthetic_weight`.
    fn scene(&self, rng: &mut ChaCha8Rng) -> Rgb32FImage {
        let synthetic = match (&self.images, self.config.synthetic) {
            (None, _) => true,
            (Some(_), false) => false,
            (Some(_), true) => rng.random_bool(self.config.synthetic_weight as f64),
        };
        match &self.images {
            Some(images) if !synthetic => images.get(rng.random_range(0..images.len())).clone(),
            _ => synthetic_scene(rng, self.config.image_size),
        }
    }
}

/// The regions of `segmentation` (of `scene`) worth a sample, in the order `pick` takes them.
fn pick_regions(
    scene: &Rgb32FImage,
    segmentation: &Segmentation,
    pick: RegionPick,
    rng: &mut ChaCha8Rng,
) -> Vec<u32> {
    let mut regions: Vec<u32> = (0..segmentation.regions.len() as u32)
        .filter(|&r| segmentation.regions[r as usize].pixels >= MIN_REGION_PIXELS)
        .collect();
    match pick {
        RegionPick::Random => regions.shuffle(rng),
        RegionPick::Worst => worst_first(&mut regions, &segmentation.flat_errors(scene)),
    }
    regions
}

/// A random `side × side` window of `scene` (the whole scene if it is not larger; 0 means the
/// whole scene).
fn window(scene: &Rgb32FImage, side: u32, rng: &mut ChaCha8Rng) -> Rgb32FImage {
    let (width, height) = scene.dimensions();
    if side == 0 || (width <= side && height <= side) {
        return scene.clone();
    }
    let (w, h) = (side.min(width), side.min(height));
    let (x, y) = (rng.random_range(0..=width - w), rng.random_range(0..=height - h));
    image::imageops::crop_imm(scene, x, y, w, h).to_image()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_segmentation_option_out_of_range_is_an_error_not_a_panic() {
        // Config files are checked on load; a config built in code is not.
        let config = DataConfig { image_size: 32, segments: [2, 4], oversegment: 0.5, ..Default::default() };
        let model = ModelConfig { input_size: 16, ..ModelConfig::preset(model::Preset::Cpu) };
        let source = DataSource::new(&config, &model, 2, 0).unwrap();
        let err = source.batch(4).unwrap_err();
        assert!(matches!(err, DataError::Segment { index: 4, .. }), "{err}");
        assert!(err.to_string().starts_with("batch 4: a scene could not be segmented"), "{err}");
    }

    #[test]
    fn picking_the_worst_takes_what_a_flat_fill_gets_most_wrong_first() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let scene = synthetic_scene(&mut rng, 96);
        let segmentation = segment(&scene, 24, &DataConfig::default().segment_options()).unwrap();
        let errors = segmentation.flat_errors(&scene);
        let worst = pick_regions(&scene, &segmentation, RegionPick::Worst, &mut rng);
        assert!(worst.len() > 4);
        assert!(worst.windows(2).all(|w| errors[w[0] as usize] >= errors[w[1] as usize]));
        let mut random = pick_regions(&scene, &segmentation, RegionPick::Random, &mut rng);
        assert_ne!(random, worst, "a shuffle of {} regions came out sorted", worst.len());
        random.sort();
        let mut same = worst.clone();
        same.sort();
        assert_eq!(random, same, "both picks choose among the same regions");
    }

    #[test]
    fn images_too_small_for_a_region_are_refused_and_never_hang() {
        let dir = std::env::temp_dir().join(format!("supersvg-tiny-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let model = ModelConfig { input_size: 16, ..ModelConfig::preset(model::Preset::Cpu) };
        // 3 × 3 images: no region of 16 pixels can exist, said when the source is built.
        image::RgbImage::from_pixel(3, 3, image::Rgb([9, 9, 9])).save(dir.join("a.png")).unwrap();
        let config =
            DataConfig { images: Some(dir.clone()), synthetic: false, image_size: 64, ..Default::default() };
        let err = DataSource::new(&config, &model, 2, 0).err().expect("refused");
        assert!(matches!(&err, DataError::NoUsableRegions { folder: Some(f), .. } if *f == dir), "{err}");
        // 8 × 8 images cut into 16 regions: each region has 4 pixels, which a batch finds out.
        image::RgbImage::from_fn(8, 8, |x, y| image::Rgb([(x * 30) as u8, (y * 30) as u8, 0]))
            .save(dir.join("a.png"))
            .unwrap();
        let config = DataConfig { segments: [16, 16], window: 0, ..config };
        let source = DataSource::new(&config, &model, 2, 0).unwrap();
        let err = source.batch(0).err().expect("no batch");
        assert!(err.to_string().contains("gave no region of 16 pixels"), "{err}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn batches_depend_only_on_seed_and_index() {
        let config = DataConfig { image_size: 64, segments: [4, 8], ..Default::default() };
        let model = ModelConfig { input_size: 16, ..ModelConfig::preset(model::Preset::Cpu) };
        let source = DataSource::new(&config, &model, 5, 7).unwrap();
        let batch = source.batch(3).unwrap();
        assert_eq!(batch.crops.len(), 5);
        assert!(batch.crops.iter().all(|crop| crop.size == 16));
        assert_eq!(batch, DataSource::new(&config, &model, 5, 7).unwrap().batch(3).unwrap());
        assert_ne!(batch, source.batch(4).unwrap());
        assert_ne!(batch, DataSource::new(&config, &model, 5, 8).unwrap().batch(3).unwrap());
        // Every crop has some region and fills outside it with −1.
        for crop in &batch.crops {
            assert!(crop.mask.iter().any(|&m| m == 1.0));
            let red = &crop.pixels[..256];
            assert!(crop.mask.iter().zip(red).all(|(&m, &p)| if m == 0.0 {
                p == -1.0
            } else {
                (0.0..=1.0).contains(&p)
            }));
        }
    }
}
