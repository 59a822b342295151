//! Reconstruction losses inside a superpixel mask.

use burn::tensor::Tensor;
use burn::tensor::module::avg_pool2d;
use burn::tensor::ops::AvgPoolOptions;

/// Normalized L2: the mean squared error per masked pixel-channel, averaged over the batch.
///
/// `render` and `target` are `[B, C, H, W]`, `mask` is `[B, 1, H, W]` with 1 inside the
/// superpixel. Per sample, `L2 = Σ_p mask(p) · ‖x̂(p) − x(p)‖² / (C · Σ_p mask(p))`: the paper's
/// `‖x̂ − x‖² · (w·h) / Σ mask` with the norm taken as a mean over all pixels, which makes small
/// and large superpixels weigh the same. A mask without pixels gives 0, not a division by zero.
pub fn masked_l2(render: Tensor<4>, target: Tensor<4>, mask: Tensor<4>) -> Tensor<1> {
    multiscale_masked_l2(render, target, mask, 1)
}

/// Multi-scale normalized L2: the error of [`masked_l2`] measured on the masked images
/// average-pooled by 1, 2, 4, … (`levels` scales, stopping at the image size), weighted
/// 1, ½, ¼, … and normalized by the sum of the weights (so one level is exactly [`masked_l2`]).
///
/// A path far from where it should be changes no pixel it would need at full resolution but does
/// change the pooled images, so the coarser scales widen the basin of attraction. In a pooled
/// cell with mask mass μ (the fraction of its pixels inside the mask), the error is μ times the
/// squared difference of the mean masked colours, `(pool(x̂·m) − pool(x·m))² / μ`, normalized
/// by the total mass, which reduces to [`masked_l2`] at full resolution.
pub fn multiscale_masked_l2(
    render: Tensor<4>,
    target: Tensor<4>,
    mask: Tensor<4>,
    levels: usize,
) -> Tensor<1> {
    let [_, _, height, width] = render.dims();
    let difference = (render - target) * mask.clone();
    let mut total = normalized_error(difference.clone(), mask.clone());
    let mut weight_sum = 1.0;
    for level in 1..levels {
        let factor = 1 << level;
        if factor > height.min(width) {
            break;
        }
        let pool =
            |t: Tensor<4>| avg_pool2d(t, AvgPoolOptions::new([factor, factor]).with_stride([factor, factor]));
        let weight = 0.5f32.powi(level as i32);
        total = total + normalized_error(pool(difference.clone()), pool(mask.clone())) * weight;
        weight_sum += weight;
    }
    total / weight_sum
}

/// Batch mean of `Σ difference² / μ` over `C · Σ μ`, for a mask-weighted `difference` and the
/// mask mass `μ` of each cell.
fn normalized_error(difference: Tensor<4>, mass: Tensor<4>) -> Tensor<1> {
    let [batch, channels, _, _] = difference.dims();
    let per_sample = |t: Tensor<4>| t.reshape([batch as i64, -1]).sum_dim(1);
    let error = per_sample(difference.square() / mass.clone().clamp_min(1e-6));
    let mass = per_sample(mass) * channels as f32;
    (error / mass.clamp_min(1e-6)).mean()
}

#[cfg(test)]
mod tests {
    use burn::tensor::{Device, Distribution, TensorData};

    use super::*;

    #[test]
    fn equals_masked_mean_squared_error() {
        let device = Device::flex();
        let render = Tensor::<4>::random([2, 3, 5, 4], Distribution::Default, &device);
        let target = Tensor::<4>::random([2, 3, 5, 4], Distribution::Default, &device);
        let mask =
            Tensor::<4>::random([2, 1, 5, 4], Distribution::Default, &device).greater_elem(0.5).float();
        let got: f32 = masked_l2(render.clone(), target.clone(), mask.clone()).into_scalar();

        let (r, t, m): (Vec<f32>, Vec<f32>, Vec<f32>) =
            (render.try_to_vec_as().unwrap(), target.try_to_vec_as().unwrap(), mask.try_to_vec_as().unwrap());
        let mut expected = 0.0;
        for b in 0..2 {
            let (mut error, mut count) = (0.0, 0.0);
            for c in 0..3 {
                for p in 0..20 {
                    let inside = m[b * 20 + p];
                    let i = (b * 3 + c) * 20 + p;
                    error += inside * (r[i] - t[i]).powi(2);
                    count += inside;
                }
            }
            expected += if count > 0.0 { error / count } else { 0.0 } / 2.0;
        }
        assert!((got - expected).abs() < 1e-5, "{got} vs {expected}");
    }

    #[test]
    fn empty_mask_gives_zero_loss_and_zero_gradient() {
        let device = Device::flex().autodiff();
        let render = Tensor::<4>::ones([1, 3, 4, 4], &device).require_grad();
        let target = Tensor::<4>::zeros([1, 3, 4, 4], &device);
        let mask = Tensor::<4>::zeros([1, 1, 4, 4], &device);
        let loss = multiscale_masked_l2(render.clone(), target, mask, 3);
        assert_eq!(loss.clone().into_scalar::<f32>(), 0.0);
        let grad: Vec<f32> = render.grad(&loss.backward()).unwrap().try_to_vec_as().unwrap();
        assert!(grad.iter().all(|&g| g == 0.0));
    }

    #[test]
    fn coarse_levels_see_a_misplaced_blob_that_full_resolution_does_not_rank() {
        // A one-pixel dot compared with a target dot 1 or 3 pixels away: the full-resolution
        // error is the same for both, the multi-scale error prefers the nearer one.
        let device = Device::flex();
        let dot = |x: usize| {
            let mut values = vec![0.0f32; 16];
            values[4 + x] = 1.0;
            Tensor::<4>::from_data(TensorData::new(values, [1, 1, 4, 4]), &device)
        };
        let mask = Tensor::<4>::ones([1, 1, 4, 4], &device);
        let single = |x| masked_l2(dot(x), dot(0), mask.clone()).into_scalar::<f32>();
        assert_eq!(single(1), single(3));
        let multi = |x| multiscale_masked_l2(dot(x), dot(0), mask.clone(), 3).into_scalar::<f32>();
        assert!(multi(1) < multi(3), "{} vs {}", multi(1), multi(3));
        assert!((multiscale_masked_l2(dot(2), dot(2), mask, 3).into_scalar::<f32>()).abs() < 1e-9);
    }
}
