//! Where paths start: a learnable per-path offset of the head's logits.

use burn::module::Param;
use burn::nn::Initializer;
use burn::tensor::{Device, Tensor, TensorData};
use raster::{COORDS, POINTS};

/// `[paths, width]` logits placing path i, before any training, as a small circle in cell i of
/// a ⌈√n⌉ × ⌈√n⌉ grid over the crop, mid-grey, and (for a visibility column) visible with
/// probability ½.
///
/// Added to the output head's logits (whose initial weights are small), it gives every path its
/// own part of the crop from the first step. Without it all paths start as the same centred
/// shape: the top one hides the others, which then get no gradient, and training has to break
/// that symmetry on its own — slowly, on a CPU budget. The offsets are trained with the rest.
pub fn grid_prior(paths: usize, width: usize, device: &Device) -> Param<Tensor<2>> {
    let radius = 0.4 / grid_side(paths) as f32;
    // Cubic circle: four anchors at 90° with handles along the tangent, κ = 0.5523.
    let kappa = 0.5523 * radius;
    let mut values = vec![0.0f32; paths * width];
    for path in 0..paths {
        let center = cell_center(path, paths);
        let row = &mut values[path * width..(path + 1) * width];
        for anchor in 0..4 {
            let angle = anchor as f32 * std::f32::consts::FRAC_PI_2;
            let (sin, cos) = angle.sin_cos();
            let point = [center[0] + radius * cos, center[1] + radius * sin];
            let tangent = [-sin * kappa, cos * kappa];
            let points = [point, [point[0] + tangent[0], point[1] + tangent[1]]];
            let before = [point[0] - tangent[0], point[1] - tangent[1]];
            for (slot, p) in [
                (3 * anchor, points[0]),
                (3 * anchor + 1, points[1]),
                ((3 * anchor + POINTS - 1) % POINTS, before),
            ] {
                row[2 * slot] = logit(p[0]);
                row[2 * slot + 1] = logit(p[1]);
            }
        }
        debug_assert!(row[COORDS..].iter().all(|&v| v == 0.0), "colour and visibility start at σ(0) = ½");
    }
    Param::from_tensor(Tensor::from_data(TensorData::new(values, [paths, width]), device))
}

/// Side of the grid that gives each of `paths` paths a cell.
fn grid_side(paths: usize) -> usize {
    (paths as f32).sqrt().ceil() as usize
}

/// Centre of path `path`'s cell in the crop's unit square (row-major cells).
pub fn cell_center(path: usize, paths: usize) -> [f32; 2] {
    let side = grid_side(paths) as f32;
    [((path % grid_side(paths)) as f32 + 0.5) / side, ((path / grid_side(paths)) as f32 + 0.5) / side]
}

/// Initial weights of the output heads: small (Xavier with gain 0.1, logits of std ≈ 0.1 for
/// unit-variance features), so the prior decides where paths start and the image moves them.
pub fn small_head() -> Initializer {
    Initializer::XavierUniform { gain: 0.1 }
}

fn logit(p: f32) -> f32 {
    (p / (1.0 - p)).ln()
}

#[cfg(test)]
mod tests {
    use burn::tensor::activation::sigmoid;

    use super::*;

    #[test]
    fn paths_start_as_separate_circles_in_their_cells() {
        let prior = grid_prior(32, 28, &Device::flex());
        let values: Vec<f32> = sigmoid(prior.val()).try_to_vec_as().unwrap();
        let side = 6;
        for path in 0..32 {
            let row = &values[path * 28..(path + 1) * 28];
            let (cx, cy) = (((path % side) as f32 + 0.5) / 6.0, ((path / side) as f32 + 0.5) / 6.0);
            for point in row[..24].chunks(2) {
                let distance = ((point[0] - cx).powi(2) + (point[1] - cy).powi(2)).sqrt();
                assert!(distance < 0.5 / side as f32, "path {path} leaves its cell");
            }
            // P0 and P3 are anchors on the circle; P11 closes back to P0's tangent.
            let r0 = ((row[0] - cx).powi(2) + (row[1] - cy).powi(2)).sqrt();
            assert!((r0 - 0.4 / 6.0).abs() < 1e-4);
            assert_eq!(&row[24..], &[0.5; 4]);
        }
    }
}
