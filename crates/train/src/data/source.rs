//! What a training batch is, and how batch `i` is made from the seed alone.

use std::path::PathBuf;
use std::sync::Arc;

use burn::tensor::{Device, Tensor, TensorData};
use image::Rgb32FImage;
use infer::Scene;
use infer::stages::{Segmented, Style, hierarchy, max_regions};
use model::{CropBatch, MIN_REGION_PIXELS, ModelConfig};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use superpixel::{RegionCrop, Segmentation, SlicError, resample_area, segment, worst_first};

use super::images::{EXTENSIONS, ImageSet};
use super::synthetic::synthetic_scene;
use crate::config::{DataConfig, RegionPick, SampleCanvas};

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

/// The drawing under a sample's box and the image under it (`data.canvas = "fallback"`), both
/// `[3, S, S]` planar, area-resampled onto the crop's cells like the canvas inference cuts
/// for E_r ([`model::canvas_cells`]), unmasked: what inference's acceptance test compares.
#[derive(Clone, Debug, PartialEq)]
pub struct DrawnBox {
    /// What is drawn so far under the box.
    pub canvas: Vec<f32>,
    /// The image under the box.
    pub target: Vec<f32>,
}

/// Region crops of one step, on the CPU.
#[derive(Clone, Debug, PartialEq)]
pub struct Batch {
    /// Index of the batch in the data stream (the step it is for).
    pub index: u64,
    /// The samples, cut by the model's input contract ([`ModelConfig::region_crop`]).
    pub crops: Vec<RegionCrop>,
    /// One per crop with `data.canvas = "fallback"`; empty otherwise.
    pub drawn: Vec<DrawnBox>,
}

/// A batch as tensors: what an objective's step reads.
#[derive(Clone, Debug)]
pub struct Samples {
    /// The crops and masks.
    pub crops: CropBatch,
    /// With `data.canvas = "fallback"`: `[B, 3, S, S]` each, what is drawn under each crop's
    /// box and the image under it.
    pub drawn: Option<DrawnBoxes>,
}

/// [`DrawnBox`]es stacked as tensors.
#[derive(Clone, Debug)]
pub struct DrawnBoxes {
    /// `[B, 3, S, S]`: the drawing under each box.
    pub canvas: Tensor<4>,
    /// `[B, 3, S, S]`: the image under each box.
    pub target: Tensor<4>,
}

impl Batch {
    /// The batch as tensors on `device`.
    pub fn tensors(&self, device: &Device) -> Samples {
        let crops = CropBatch::new(&self.crops, device);
        let drawn = (!self.drawn.is_empty()).then(|| {
            let [count, _, size, _] = crops.pixels.dims();
            let stack = |part: fn(&DrawnBox) -> &[f32]| {
                let values: Vec<f32> = self.drawn.iter().flat_map(|d| part(d).iter().copied()).collect();
                Tensor::from_data(TensorData::new(values, [count, 3, size, size]), device)
            };
            DrawnBoxes { canvas: stack(|d| &d.canvas), target: stack(|d| &d.target) }
        });
        Samples { crops, drawn }
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
        let (mut crops, mut drawn) = (Vec::with_capacity(self.batch_size), Vec::new());
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
            let room = self.batch_size - crops.len();
            let taken = match self.config.canvas {
                SampleCanvas::None => {
                    let segmentation = segment(&scene, count, &self.config.segment_options())
                        .map_err(|source| DataError::Segment { index, source })?;
                    let errors = || segmentation.flat_errors(&scene);
                    let regions = pick_regions(&segmentation, self.config.pick, errors, &mut rng);
                    let take = regions.len().min(self.config.regions_per_scene).min(room);
                    crops.extend(regions[..take].iter().map(|&r| self.sample(&scene, &segmentation, r)));
                    take
                }
                SampleCanvas::Fallback => {
                    let samples = self
                        .drawn_samples(scene, count, room, &mut rng)
                        .map_err(|source| DataError::Segment { index, source })?;
                    let take = samples.len();
                    for (crop, box_) in samples {
                        crops.push(crop);
                        drawn.push(box_);
                    }
                    take
                }
            };
            barren = if taken == 0 { barren + 1 } else { 0 };
        }
        Ok(Batch { index, crops, drawn })
    }

    /// Up to `room` samples (at most `regions_per_scene`) of `scene` cut into `count` of
    /// inference's regions, each with the fallback drawing inference makes of them under its box
    /// ([`SampleCanvas::Fallback`]), in the order `pick` takes them.
    fn drawn_samples(
        &self,
        scene: Rgb32FImage,
        count: usize,
        room: usize,
        rng: &mut ChaCha8Rng,
    ) -> Result<Vec<(RegionCrop, DrawnBox)>, SlicError> {
        let count = count.min(max_regions(scene.width(), scene.height()));
        let target = Arc::new(scene);
        let tree = hierarchy(&target, count, self.config.compactness)?;
        let Segmented { segmentation, fallback, .. } = Segmented::new(&target, tree, count, Style::default());
        let drawing = Scene::drawn(target.clone(), segmentation.clone(), fallback.placed(), fallback.canvas);
        let regions = pick_regions(&segmentation, self.config.pick, || drawing.region_errors(), rng);
        let canvas = drawing.canvas_image();
        let take = regions.len().min(self.config.regions_per_scene).min(room);
        Ok(regions[..take]
            .iter()
            .map(|&region| {
                let crop = self.sample(&target, &segmentation, region);
                let drawn = DrawnBox {
                    canvas: resample_area(&canvas, &crop.transform, crop.size),
                    target: resample_area(&target, &crop.transform, crop.size),
                };
                (crop, drawn)
            })
            .collect())
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

/// The regions of `segmentation` large enough to be a sample ([`MIN_REGION_PIXELS`]), in the
/// order `pick` takes them: `Worst` ranks them by `errors` (one per region, largest first).
fn pick_regions(
    segmentation: &Segmentation,
    pick: RegionPick,
    errors: impl FnOnce() -> Vec<f64>,
    rng: &mut ChaCha8Rng,
) -> Vec<u32> {
    let mut regions: Vec<u32> = (0..segmentation.regions.len() as u32)
        .filter(|&r| segmentation.regions[r as usize].pixels >= MIN_REGION_PIXELS)
        .collect();
    match pick {
        RegionPick::Random => regions.shuffle(rng),
        RegionPick::Worst => worst_first(&mut regions, &errors()),
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
        let worst = pick_regions(&segmentation, RegionPick::Worst, || errors.clone(), &mut rng);
        assert!(worst.len() > 4);
        assert!(worst.windows(2).all(|w| errors[w[0] as usize] >= errors[w[1] as usize]));
        let mut random = pick_regions(&segmentation, RegionPick::Random, || errors.clone(), &mut rng);
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
    fn fallback_samples_carry_inferences_drawing_under_their_box() {
        let dir = std::env::temp_dir().join(format!("supersvg-drawn-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        // Four flat quadrants, then a ramp: the regions' polygons in their mean colours draw the
        // first exactly and the second only roughly.
        image::RgbImage::from_fn(64, 64, |x, y| {
            image::Rgb(match (x < 32, y < 32) {
                (true, true) => [230, 40, 40],
                (false, true) => [20, 40, 200],
                (true, false) => [250, 220, 10],
                (false, false) => [10, 120, 30],
            })
        })
        .save(dir.join("a.png"))
        .unwrap();
        let model = ModelConfig { input_size: 16, ..ModelConfig::preset(model::Preset::Cpu) };
        let config = DataConfig {
            images: Some(dir.clone()),
            synthetic: false,
            image_size: 64,
            segments: [4, 4],
            canvas: SampleCanvas::Fallback,
            pick: RegionPick::Worst,
            ..Default::default()
        };
        let batch = DataSource::new(&config, &model, 3, 0).unwrap().batch(0).unwrap();
        assert_eq!((batch.crops.len(), batch.drawn.len()), (3, 3));
        for (crop, drawn) in batch.crops.iter().zip(&batch.drawn) {
            let cells = crop.size * crop.size;
            for (index, (&canvas, &target)) in drawn.canvas.iter().zip(&drawn.target).enumerate() {
                assert!((canvas - target).abs() < 1e-2, "cell {index}: drew {canvas}, image {target}");
                if crop.mask[index % cells] == 1.0 {
                    assert!((crop.pixels[index] - target).abs() < 1e-5, "the box holds the crop");
                }
            }
        }
        let samples = batch.tensors(&Device::flex());
        let drawn = samples.drawn.expect("the boxes come as tensors");
        assert_eq!(drawn.canvas.dims(), [3, 3, 16, 16]);

        image::RgbImage::from_fn(64, 64, |x, y| image::Rgb([(x * 4) as u8, (y * 4) as u8, 90]))
            .save(dir.join("a.png"))
            .unwrap();
        let batch = DataSource::new(&config, &model, 3, 0).unwrap().batch(0).unwrap();
        for (crop, drawn) in batch.crops.iter().zip(&batch.drawn) {
            let error: f32 = drawn.canvas.iter().zip(&drawn.target).map(|(a, b)| (a - b).powi(2)).sum();
            assert!(error > 0.05, "a flat region cannot draw a ramp exactly ({error})");
            // Inside the region the drawing is its flat polygon: one colour on the cells whose
            // pixels are all the region's (the mask's cells away from its edge), but where a
            // neighbour's anti-aliased edge reaches in; the image's ramp differs on every cell.
            let cells = crop.size * crop.size;
            let inner: Vec<usize> = (0..cells)
                .filter(|&i| {
                    let (x, y) = (i % crop.size, i / crop.size);
                    (x > 0 && y > 0 && x + 1 < crop.size && y + 1 < crop.size)
                        && [i - 1, i + 1, i - crop.size, i + crop.size, i]
                            .iter()
                            .all(|&j| crop.mask[j] == 1.0)
                })
                .collect();
            let red: Vec<f32> = inner.iter().map(|&i| drawn.canvas[i]).collect();
            let flat = red.iter().filter(|&&v| (v - red[red.len() / 2]).abs() < 1e-2).count();
            assert!(inner.len() > 20 && flat * 10 >= 9 * inner.len(), "{red:?}");
            let image: Vec<f32> = inner.iter().map(|&i| drawn.target[i]).collect();
            let same = image.iter().filter(|&&v| (v - image[image.len() / 2]).abs() < 1e-2).count();
            assert!(same * 2 < inner.len(), "the image is a ramp under the same cells: {image:?}");
        }
        let coarse =
            DataSource::new(&DataConfig { canvas: SampleCanvas::None, ..config }, &model, 3, 0).unwrap();
        assert!(coarse.batch(0).unwrap().drawn.is_empty(), "only with data.canvas");
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
