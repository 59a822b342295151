//! The boundary loss: how much of the predicted paths lies outside the superpixel.

use burn::tensor::Tensor;
use burn::tensor::module::max_pool2d;
use burn::tensor::ops::MaxPoolOptions;
use raster::{PathBatch, SoftRasterOptions, render_soft_with_union};

/// How far (pixels) a path may reach past its superpixel before the boundary loss counts it:
/// the reference's 2, room for a path to cover the superpixel's edge and anti-alias it. What
/// training uses by default and evaluation measures spill against.
pub const BOUNDARY_DILATION: usize = 2;

/// Options of [`boundary_loss`].
#[derive(Clone, Debug)]
pub struct BoundaryOptions {
    /// The mask is dilated by this many pixels first (a (2r+1)² max filter;
    /// [`BOUNDARY_DILATION`] by default), so paths may overlap the superpixel's edge slightly.
    pub dilation: usize,
    /// How the white paths are rasterized (the background is ignored: black is used).
    pub raster: SoftRasterOptions,
}

impl Default for BoundaryOptions {
    fn default() -> Self {
        Self { dilation: BOUNDARY_DILATION, raster: SoftRasterOptions::default() }
    }
}

/// Dilates a `[B, 1, H, W]` mask by `radius` pixels (max filter over a (2r+1)² square).
pub fn dilate(mask: Tensor<4>, radius: usize) -> Tensor<4> {
    if radius == 0 {
        return mask;
    }
    let size = 2 * radius + 1;
    max_pool2d(mask, MaxPoolOptions::new([size, size]).with_stride([1, 1]).with_padding([radius, radius]))
}

/// `L_bound = Σ_p c(p)·(1 − mask'(p)) / Σ_p (1 − mask'(p))`, averaged over the batch.
///
/// `c` is the coverage of all paths painted white at full opacity on black — visible or not,
/// so invisible paths are kept inside too — and `mask'` the `[B, 1, H, W]` mask dilated by
/// `options.dilation`. Zero when every path stays inside the dilated mask; it grows with the
/// covered area outside. A mask that covers the whole crop has no outside and gives 0.
///
/// Renders the paths' coverage itself; a training step that renders the paths anyway takes it
/// from [`raster::paint_soft_with_union`] and calls [`boundary_loss_of_union`].
pub fn boundary_loss(paths: &PathBatch, mask: Tensor<4>, options: &BoundaryOptions) -> Tensor<1> {
    let [_, _, height, width] = mask.dims();
    let (_, union) = render_soft_with_union(paths, height, width, &options.raster);
    boundary_loss_of_union(union, mask, options.dilation)
}

/// [`boundary_loss`] from the union of the paths' coverage `[B, 1, H, W]` (what painting every
/// path white at full opacity over black gives) and the mask dilated by `dilation` pixels.
pub fn boundary_loss_of_union(union: Tensor<4>, mask: Tensor<4>, dilation: usize) -> Tensor<1> {
    let [batch, _, _, _] = mask.dims();
    let outside = dilate(mask, dilation).neg() + 1.0;
    let per_sample = |t: Tensor<4>| t.reshape([batch as i64, -1]).sum_dim(1);
    let area_outside = per_sample(union * outside.clone());
    (area_outside / per_sample(outside).clamp_min(1.0)).mean()
}

#[cfg(test)]
mod tests {
    use burn::tensor::{Device, TensorData};
    use raster::Path;

    use super::*;

    /// A square path from `lo` to `hi` (unit square), straight sides.
    fn square(lo: f32, hi: f32) -> Path {
        Path::quadrilateral([[lo, lo], [hi, lo], [hi, hi], [lo, hi]], [0.3, 0.2, 0.1], 0.0)
    }

    /// A 32×32 mask that is 1 on columns and rows 8..24.
    fn centre_mask(device: &Device) -> Tensor<4> {
        let values = (0..32 * 32)
            .map(|i| if (8..24).contains(&(i % 32)) && (8..24).contains(&(i / 32)) { 1.0 } else { 0.0 })
            .collect();
        Tensor::from_data(TensorData::new(values, [1, 1, 32, 32]), device)
    }

    fn loss_of(path: Path, device: &Device) -> f32 {
        let paths = PathBatch::from_scenes(&[vec![path]], device);
        boundary_loss(&paths, centre_mask(device), &BoundaryOptions::default()).into_scalar()
    }

    #[test]
    fn zero_inside_and_growing_with_the_area_outside() {
        let device = Device::flex();
        // Inside the mask (and α = 0: invisible paths count too).
        assert!(loss_of(square(0.3, 0.7), &device).abs() < 1e-7);
        // Inside the dilated mask only: still zero.
        assert!(loss_of(square(0.2, 0.8), &device).abs() < 1e-7);
        let mut last = 0.0;
        for hi in [0.85, 0.9, 0.95, 1.0] {
            let loss = loss_of(square(0.3, hi), &device);
            assert!(loss > last, "outside up to {hi}: {loss} after {last}");
            last = loss;
        }
        // The whole canvas covered: every pixel outside the dilated mask is covered.
        assert!((loss_of(square(0.0, 1.0), &device) - 1.0).abs() < 1e-5);
    }

    #[test]
    fn dilation_grows_the_mask() {
        let device = Device::flex();
        let grown: Vec<f32> = dilate(centre_mask(&device), 2).try_to_vec_as().unwrap();
        assert_eq!(grown[6 * 32 + 6], 1.0);
        assert_eq!(grown[5 * 32 + 16], 0.0);
        assert_eq!(grown.iter().sum::<f32>(), 20.0 * 20.0);
    }

    #[test]
    fn gradient_matches_finite_differences() {
        let device = Device::flex().autodiff();
        let base = square(0.3, 0.93);
        let params = PathBatch::from_scenes(&[vec![base]], &device).into_params();
        let loss = |p: Tensor<3>| {
            boundary_loss(&PathBatch::new(p), centre_mask(&device), &BoundaryOptions::default())
        };
        let tracked = params.clone().require_grad();
        let analytic: Vec<f32> =
            tracked.grad(&loss(tracked.clone()).backward()).unwrap().try_to_vec_as().unwrap();
        let values: Vec<f32> = params.try_to_vec_as().unwrap();
        let h = 1e-3;
        let mut checked = 0;
        for (index, &grad) in analytic.iter().enumerate() {
            if grad.abs() < 0.05 {
                continue;
            }
            let shifted = |delta: f32| {
                let mut v = values.clone();
                v[index] += delta;
                loss(Tensor::from_data(TensorData::new(v, [1, 1, 28]), &device)).into_scalar::<f32>()
            };
            let numeric = (shifted(h) - shifted(-h)) / (2.0 * h);
            assert!((numeric - grad).abs() < 0.05 * grad.abs(), "param {index}: {grad} vs {numeric}");
            checked += 1;
        }
        assert!(checked >= 4, "{checked} parameters checked");
    }
}
