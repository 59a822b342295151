//! The same scene gives the same image and gradients on every backend.

use burn::tensor::{Device, Tensor, TensorData};
use rand::SeedableRng;
use raster::{Backend, PathBatch, SoftRasterOptions, random_scene, render_soft};

/// Renders a small fixed scene on `device` and returns the image and the gradient of a weighted
/// sum of it with respect to the path parameters.
fn image_and_gradient(device: &Device) -> (Vec<f32>, Vec<f32>) {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(21);
    let scenes = vec![random_scene(&mut rng, 4), random_scene(&mut rng, 4)];
    let params = PathBatch::from_scenes(&scenes, device).into_params().require_grad();
    let size = 24;
    let weights: Vec<f32> = (0..2 * 3 * size * size).map(|i| ((i * 37) % 101) as f32 / 101.0).collect();
    let weights = Tensor::<4>::from_data(TensorData::new(weights, [2, 3, size, size]), device);
    let image = render_soft(&PathBatch::new(params.clone()), size, size, &SoftRasterOptions::default());
    let grads = (image.clone() * weights).sum().backward();
    (image.try_to_vec_as().unwrap(), params.grad(&grads).unwrap().try_to_vec_as().unwrap())
}

fn max_abs_difference(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f32::max)
}

#[test]
fn backends_agree_on_image_and_gradients() {
    let (image, gradient) = image_and_gradient(&Backend::Flex.autodiff_device().unwrap());
    let scale = gradient.iter().fold(1.0f32, |m, g| m.max(g.abs()));
    // The backends this build promises: ndarray always (a dev-dependency), wgpu with the crate's
    // `wgpu` feature. None is skipped: one that cannot be created fails the test.
    let promised = [Backend::Ndarray].into_iter().chain(cfg!(feature = "wgpu").then_some(Backend::Wgpu));
    for backend in promised {
        let device = backend.autodiff_device().unwrap_or_else(|err| panic!("{backend}: {err}"));
        let (other_image, other_gradient) = image_and_gradient(&device);
        assert_eq!((image.len(), gradient.len()), (other_image.len(), other_gradient.len()), "{backend}");
        assert!(max_abs_difference(&image, &other_image) <= 1e-4, "{backend}: images differ");
        let gradient_gap = max_abs_difference(&gradient, &other_gradient) / scale;
        assert!(gradient_gap <= 1e-4, "{backend}: gradients differ by {gradient_gap} (relative)");
    }
}
