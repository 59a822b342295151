//! The input contract: training and inference cut a region into exactly the same model input.

use burn::tensor::Device;
use image::{Rgb, Rgb32FImage};
use supersvg::infer::Scene;
use supersvg::model::{CropBatch, InputSpec, ModelConfig, Preset};
use supersvg::superpixel::{SegmentOptions, segment};
use supersvg::train::DataSource;
use supersvg::train::config::DataConfig;

fn photo() -> Rgb32FImage {
    Rgb32FImage::from_fn(80, 56, |x, y| {
        let wave = ((x as f32 / 7.0).sin() * (y as f32 / 5.0).cos()) * 0.4 + 0.5;
        Rgb([wave, x as f32 / 80.0, if (x / 20 + y / 14) % 2 == 0 { 0.85 } else { 0.15 }])
    })
}

#[test]
fn training_and_inference_build_identical_region_inputs() {
    let image = photo();
    let segmentation =
        segment(&image, 12, &SegmentOptions { oversegment: 3.0, ..Default::default() }).unwrap();
    // A contract that differs from the defaults, so a path that ignored it would show.
    let config = ModelConfig {
        input_size: 16,
        patch_size: 8,
        input: InputSpec { padding: 5, fill: -0.5 },
        ..ModelConfig::preset(Preset::Cpu)
    };
    let data = DataConfig { image_size: 80, ..Default::default() };
    let source = DataSource::new(&data, &config, 1, 0).unwrap();
    let scene = Scene::new(image.clone(), segmentation.clone());
    let device = Device::flex();
    for region in 0..segmentation.regions.len() as u32 {
        let trained = source.sample(&image, &segmentation, region);
        let inferred = scene.region_crop(&config, region);
        assert_eq!(trained, inferred, "region {region}");
        let (a, b) = (CropBatch::new([&trained], &device), CropBatch::new([&inferred], &device));
        let values = |t: burn::tensor::Tensor<4>| t.try_to_vec_as::<f32>().unwrap();
        assert_eq!(values(a.pixels), values(b.pixels));
        assert_eq!(values(a.masks), values(b.masks));
        // The contract's settings were applied: the crop's rectangle holds the padding and
        // cells outside the region hold the fill.
        let bbox = segmentation.regions[region as usize].bbox.padded(5, 80, 56);
        assert_eq!(inferred.transform.x, bbox.x0() as f32);
        assert!(inferred.mask.iter().zip(&inferred.pixels).all(|(&m, &p)| m == 1.0 || p == -0.5));
    }
}
