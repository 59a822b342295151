//! Every loss gives the same values and gradients on every backend.

use burn::tensor::{Device, Tensor, TensorData};
use dpw::{BoundaryOptions, PathDistance, boundary_loss, dpw, multiscale_masked_l2};
use rand::{Rng, SeedableRng};
use raster::{Backend, PathBatch, SoftRasterOptions, random_scene, render_soft};

fn fixed(values: &[f32], dims: [usize; 4], device: &Device) -> Tensor<4> {
    Tensor::from_data(TensorData::new(values.to_vec(), dims), device)
}

/// Values of the three image losses and DPW, and the gradient of their sum.
fn losses(device: &Device) -> (Vec<f32>, Vec<f32>) {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(31);
    let size = 16;
    let scenes = vec![random_scene(&mut rng, 5), random_scene(&mut rng, 5)];
    let target: Vec<f32> = (0..2 * 3 * size * size).map(|_| rng.random()).collect();
    let mask: Vec<f32> = (0..2 * size * size)
        .map(|i| if (i % size) > 3 && (i / size) % size > 5 { 1.0 } else { 0.0 })
        .collect();
    let params = PathBatch::from_scenes(&scenes, device).into_params().require_grad();
    let paths = PathBatch::new(params.clone());
    let target = fixed(&target, [2, 3, size, size], device);
    let mask = fixed(&mask, [2, 1, size, size], device);
    let render = render_soft(&paths, size, size, &SoftRasterOptions::default());
    let l2 = multiscale_masked_l2(render, target, mask.clone(), 3);
    let bound = boundary_loss(&paths, mask, &BoundaryOptions::default());
    let distances = PathDistance::default().between(&paths.narrow(0, 2), &paths.narrow(1, 4));
    let warp = dpw(distances, 0.01).mean();
    let total = l2.clone() + bound.clone() + warp.clone();
    let grad = params.grad(&total.backward()).unwrap().try_to_vec_as().unwrap();
    let values = [l2, bound, warp].into_iter().map(|t| t.into_scalar::<f32>()).collect();
    (values, grad)
}

#[test]
fn backends_agree_on_losses_and_gradients() {
    let (values, grad) = losses(&Backend::Flex.autodiff_device().unwrap());
    let scale = grad.iter().fold(1.0f32, |m, g| m.max(g.abs()));
    // The backends this build promises: ndarray always (a dev-dependency), wgpu with the crate's
    // `wgpu` feature. None is skipped: one that cannot be created fails the test.
    let promised = [Backend::Ndarray].into_iter().chain(cfg!(feature = "wgpu").then_some(Backend::Wgpu));
    for backend in promised {
        let (other_values, other_grad) =
            losses(&backend.autodiff_device().unwrap_or_else(|err| panic!("{backend}: {err}")));
        assert_eq!((values.len(), grad.len()), (other_values.len(), other_grad.len()), "{backend}");
        for (a, b) in values.iter().zip(&other_values) {
            assert!((a - b).abs() <= 1e-4 * a.abs().max(1.0), "{backend}: loss {a} vs {b}");
        }
        let gap = grad.iter().zip(&other_grad).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max) / scale;
        assert!(gap <= 1e-4, "{backend}: gradients differ by {gap} (relative to the largest)");
    }
}
