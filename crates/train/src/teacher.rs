//! The exact optimizer as E_r's teacher (`loss.teacher = "optimizer"`): for every sample, paths
//! placed where the canvas errs most against the image and moved down the exact render's
//! gradient ([`Window`], [`PathAdam`]). E_r proposes its paths in one pass; these are the paths
//! the optimizer finds in their place, and the guidance pulls E_r's towards them.

use burn::tensor::{Tensor, TensorData};
use model::error_squares;
use raster::{PARAMS, Path, PathAdam, PathBatch, Window};
use rayon::prelude::*;

/// Adam's rates for coordinates and for colour and opacity. Coordinates at 4e-3 of the box move
/// a quarter of a pixel a step in a 64-px crop (SuperSVG-F moves half a pixel at 512 px, on paths
/// that start where they belong); colours as SuperSVG-F's.
const RATES: (f32, f32) = (4e-3, 3e-2);

/// How many paths the teacher places in each sample, and how long it optimizes them.
#[derive(Clone, Copy, Debug)]
pub struct OptimizerTeacher {
    /// Paths per sample (E_r's `refine_paths`).
    pub paths: usize,
    /// Adam steps on all of a sample's paths at once.
    pub steps: usize,
}

impl OptimizerTeacher {
    /// The teacher's paths `[B, paths]` for the canvases `[B, 3, S, S]` E_r draws over and the
    /// targets `[B, 3, S, S]` it draws towards (coordinates in each box's unit square). A
    /// sample whose canvas is right everywhere has nothing to place: its paths are padded with
    /// invisible ones (α = 0), which guidance skips. Samples run in parallel.
    pub fn teach(&self, canvas: &Tensor<4>, target: &Tensor<4>) -> PathBatch {
        let [batch, _, height, width] = canvas.dims();
        let device = canvas.device();
        let read = |tensor: &Tensor<4>| -> Vec<f32> { tensor.try_to_vec_as().expect("crops are readable") };
        let (canvas, target) = (read(canvas), read(target));
        let plane = 3 * height * width;
        let values: Vec<f32> = (0..batch)
            .into_par_iter()
            .flat_map_iter(|b| {
                let samples = plane * b..plane * (b + 1);
                let (canvas, target) = (canvas[samples.clone()].to_vec(), target[samples].to_vec());
                self.sample(width as u32, height as u32, canvas, target).into_iter().flat_map(Path::to_params)
            })
            .collect();
        PathBatch::new(Tensor::from_data(TensorData::new(values, [batch, self.paths, PARAMS]), &device))
    }

    /// One sample's paths, from planar RGB buffers of `width × height`: seeded where E_r's
    /// error anchors start ([`error_squares`]), then optimized together; the best state seen.
    fn sample(&self, width: u32, height: u32, canvas: Vec<f32>, target: Vec<f32>) -> Vec<Path> {
        let seeds = error_squares(width as usize, height as usize, &canvas, &target, self.paths);
        let Some(window) = Window::new(width, height, canvas, target) else {
            return seeds;
        };
        let mut params: Vec<[f32; PARAMS]> = seeds.iter().map(|path| path.to_params()).collect();
        let mut adam = PathAdam::new(params.len());
        let mut best = (window.l2(&seeds), seeds);
        for _ in 0..self.steps {
            let paths: Vec<Path> = params.iter().map(Path::from_params).collect();
            let (loss, gradients) = window.l2_gradient(&paths);
            if loss < best.0 {
                best = (loss, paths);
            }
            adam.step(RATES, &mut params, &gradients);
        }
        let last: Vec<Path> = params.iter().map(Path::from_params).collect();
        if window.l2(&last) < best.0 { last } else { best.1 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a square larger than a seed, the optimizer grows the seed over it: the error falls
    /// to under a fifth of the seed's.
    #[test]
    fn the_optimizer_improves_on_its_seeds() {
        const SIZE: usize = 32;
        let canvas = vec![0.5f32; 3 * SIZE * SIZE];
        let mut target = canvas.clone();
        let green = [0.1, 0.8, 0.2];
        for (y, x) in (12..22).flat_map(|y| (10..20).map(move |x| (y, x))) {
            for (c, value) in green.iter().enumerate() {
                target[(c * SIZE + y) * SIZE + x] = *value;
            }
        }
        let teacher = OptimizerTeacher { paths: 1, steps: 150 };
        let window = Window::new(SIZE as u32, SIZE as u32, canvas.clone(), target.clone()).unwrap();
        let seeded = window.l2(&error_squares(SIZE, SIZE, &canvas, &target, 1));
        let taught = window.l2(&teacher.sample(SIZE as u32, SIZE as u32, canvas, target));
        assert!(taught < 0.2 * seeded, "{taught} against {seeded}");
    }
}
