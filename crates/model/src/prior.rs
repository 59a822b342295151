//! Where paths start: a learnable per-path offset of the head's logits.

use burn::module::Param;
use burn::nn::Initializer;
use burn::tensor::{Device, Tensor, TensorData};
use raster::{COORDS, POINTS, Path};

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

/// Side of an error anchor, in the crop's unit square: an eighth, 8 pixels of a 64-px crop,
/// about the size of the detail the fallback drawing's regions leave out.
pub const ANCHOR_SIDE: f32 = 0.125;

/// `[B, paths, width]` logits of [`error_squares`] for each sample of `targets` and `canvas`
/// (`[B, 3, S, S]`, masked alike, so nothing outside the mask errs), colour and visibility at
/// σ(0): what [`crate::RefineModel`] adds its head's logits to when it is anchored at errors.
/// Read on the CPU, not differentiated.
pub fn error_anchors(targets: &Tensor<4>, canvas: &Tensor<4>, paths: usize, width: usize) -> Tensor<3> {
    let [batch, _, height, side] = targets.dims();
    let read = |tensor: &Tensor<4>| -> Vec<f32> { tensor.try_to_vec_as().expect("crops are readable") };
    let (targets_values, canvas_values) = (read(targets), read(canvas));
    let plane = 3 * height * side;
    let mut values = Vec::with_capacity(batch * paths * width);
    for b in 0..batch {
        let samples = plane * b..plane * (b + 1);
        let squares =
            error_squares(side, height, &canvas_values[samples.clone()], &targets_values[samples], paths);
        for square in squares {
            let mut row = vec![0.0f32; width];
            for (slot, value) in square.points.iter().flatten().enumerate() {
                row[slot] = logit(value.clamp(1e-3, 1.0 - 1e-3));
            }
            values.extend(row);
        }
    }
    Tensor::from_data(TensorData::new(values, [batch, paths, width]), &targets.device())
}

/// `count` squares of side [`ANCHOR_SIDE`] in the target's mean colour under them, each where
/// it covers the most squared error of `canvas` against `target` (planar RGB, `width × height`)
/// not yet covered by an earlier one; invisible padding once no error is left. Where E_r's
/// paths start ([`crate::config::RefineAnchor::Errors`]) and where the optimizer that teaches
/// it starts its own.
pub fn error_squares(width: usize, height: usize, canvas: &[f32], target: &[f32], count: usize) -> Vec<Path> {
    let pixels = width * height;
    let mut error: Vec<f64> = (0..pixels)
        .map(|i| (0..3).map(|c| f64::from(target[c * pixels + i] - canvas[c * pixels + i]).powi(2)).sum())
        .collect();
    let side = ((ANCHOR_SIDE * width.min(height) as f32).round() as usize).clamp(1, width.min(height));
    let padding = Path { points: [[0.5; 2]; POINTS], color: [0.0; 3], alpha: 0.0 };
    let mut seeds = Vec::with_capacity(count);
    for _ in 0..count {
        // Sums over every side × side square, from the summed-area table.
        let mut table = vec![0.0f64; (width + 1) * (height + 1)];
        for y in 0..height {
            let mut row = 0.0;
            for x in 0..width {
                row += error[y * width + x];
                table[(y + 1) * (width + 1) + x + 1] = table[y * (width + 1) + x + 1] + row;
            }
        }
        let sum = |x: usize, y: usize| {
            let at = |x: usize, y: usize| table[y * (width + 1) + x];
            at(x + side, y + side) - at(x, y + side) - at(x + side, y) + at(x, y)
        };
        let (x0, y0, most) = (0..=height - side)
            .flat_map(|y| (0..=width - side).map(move |x| (x, y)))
            .map(|(x, y)| (x, y, sum(x, y)))
            .fold((0, 0, 0.0), |best, next| if next.2 > best.2 { next } else { best });
        if most <= 0.0 {
            seeds.push(padding);
            continue;
        }
        let mut color = [0.0f64; 3];
        for y in y0..y0 + side {
            for x in x0..x0 + side {
                for (c, value) in color.iter_mut().enumerate() {
                    *value += f64::from(target[c * pixels + y * width + x]);
                }
                error[y * width + x] = 0.0;
            }
        }
        let (w, h) = (width as f32, height as f32);
        let (left, top, right, bottom) =
            (x0 as f32 / w, y0 as f32 / h, (x0 + side) as f32 / w, (y0 + side) as f32 / h);
        let color = color.map(|v| (v / (side * side) as f64) as f32);
        seeds.push(Path::quadrilateral(
            [[left, top], [right, top], [right, bottom], [left, bottom]],
            color,
            1.0,
        ));
    }
    seeds
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

    const SIZE: usize = 32;

    /// A grey canvas, and the image: the grey with `squares` (top-left corner, side, colour).
    fn scene(squares: &[((usize, usize), usize, [f32; 3])]) -> (Vec<f32>, Vec<f32>) {
        let pixels = SIZE * SIZE;
        let canvas = vec![0.5f32; 3 * pixels];
        let mut target = canvas.clone();
        for &((x0, y0), side, color) in squares {
            for y in y0..y0 + side {
                for x in x0..x0 + side {
                    for (c, value) in color.iter().enumerate() {
                        target[c * pixels + y * SIZE + x] = *value;
                    }
                }
            }
        }
        (canvas, target)
    }

    /// Squares cover the squares the canvas misses, in their colours, largest error first; with
    /// no error left, the rest are invisible.
    #[test]
    fn seeds_go_where_the_error_is() {
        // Squares are 4 px in a 32-px crop; red errs more than blue on grey.
        let (canvas, target) = scene(&[((20, 16), 4, [0.0, 0.0, 1.0]), ((4, 8), 4, [1.0, 0.0, 0.0])]);
        let squares = error_squares(SIZE, SIZE, &canvas, &target, 4);
        let corner = |path: &Path| path.points[0].map(|v| (v * SIZE as f32).round() as usize);
        assert_eq!((corner(&squares[0]), squares[0].color), ([4, 8], [1.0, 0.0, 0.0]));
        assert_eq!((corner(&squares[1]), squares[1].color), ([20, 16], [0.0, 0.0, 1.0]));
        assert!(squares[..2].iter().all(Path::is_visible) && !squares[2..].iter().any(Path::is_visible));
    }

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
