//! The exact optimizer as E_r's teacher (`loss.teacher = "optimizer"`): for every sample, the
//! paths [`PathOptimizer`] places on its canvas. E_r proposes its paths in one pass; these are
//! the paths the optimizer finds in their place, and the guidance pulls E_r's towards them.

use burn::tensor::{Tensor, TensorData};
use model::PathOptimizer;
use raster::{PARAMS, Path, PathBatch};

/// The teacher's paths `[B, paths]` for the canvases `[B, 3, S, S]` E_r draws over and the
/// targets `[B, 3, S, S]` it draws towards (coordinates in each box's unit square). A sample
/// whose canvas is right everywhere has nothing to place: its paths are invisible (α = 0), which
/// guidance skips.
pub fn teach(optimizer: PathOptimizer, canvas: &Tensor<4>, target: &Tensor<4>) -> PathBatch {
    let [batch, ..] = canvas.dims();
    let values: Vec<f32> =
        optimizer.place_batch(canvas, target).into_iter().flatten().flat_map(Path::to_params).collect();
    PathBatch::new(Tensor::from_data(
        TensorData::new(values, [batch, optimizer.paths, PARAMS]),
        &canvas.device(),
    ))
}
