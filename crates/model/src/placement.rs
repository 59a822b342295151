//! The exact optimizer doing E_r's job: paths placed on a canvas where it errs most against the
//! image ([`error_squares`]) and moved down the exact render's gradient ([`Window`],
//! [`PathAdam`]). E_r proposes its paths in one forward pass; these are the paths gradient
//! descent finds in their place. They teach E_r (`loss.teacher = "optimizer"` in training) and,
//! at inference (`infer --refiner optimizer`), stand in for it: what a trained E_r could add at
//! best in its role.

use burn::tensor::Tensor;
use raster::{PARAMS, Path, PathAdam, Window};
use rayon::prelude::*;

use crate::prior::error_squares;

/// Adam's rates for coordinates and for colour and opacity. Coordinates at 4e-3 of the box move
/// a quarter of a pixel a step in a 64-px crop (SuperSVG-F moves half a pixel at 512 px, on paths
/// that start where they belong); colours as SuperSVG-F's.
const RATES: (f32, f32) = (4e-3, 3e-2);

/// How many paths the optimizer places in each crop, and how long it moves them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PathOptimizer {
    /// Paths per crop (E_r's `refine_paths`).
    pub paths: usize,
    /// Adam steps on all of a crop's paths at once.
    pub steps: usize,
}

impl PathOptimizer {
    /// Each crop's `paths` paths (coordinates in its unit square) for the canvases `[B, 3, S, S]`
    /// drawn so far and the targets `[B, 3, S, S]` to draw. A crop whose canvas is right
    /// everywhere has nothing to place: its paths are invisible (α = 0). Crops run in parallel.
    pub fn place_batch(&self, canvas: &Tensor<4>, target: &Tensor<4>) -> Vec<Vec<Path>> {
        let [batch, _, height, width] = canvas.dims();
        let read = |tensor: &Tensor<4>| -> Vec<f32> { tensor.try_to_vec_as().expect("crops are readable") };
        let (canvas, target) = (read(canvas), read(target));
        let plane = 3 * height * width;
        (0..batch)
            .into_par_iter()
            .map(|b| {
                let samples = plane * b..plane * (b + 1);
                let (canvas, target) = (canvas[samples.clone()].to_vec(), target[samples].to_vec());
                self.place(width as u32, height as u32, canvas, target)
            })
            .collect()
    }

    /// One crop's paths, from planar RGB buffers of `width × height`: seeded at
    /// [`error_squares`], then optimized together; the best state seen.
    pub fn place(&self, width: u32, height: u32, canvas: Vec<f32>, target: Vec<f32>) -> Vec<Path> {
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
    use burn::tensor::{Device, TensorData};

    use super::*;

    const SIZE: usize = 32;

    /// A grey canvas and the image: the grey with a green 10-px square.
    fn square() -> (Vec<f32>, Vec<f32>) {
        let canvas = vec![0.5f32; 3 * SIZE * SIZE];
        let mut target = canvas.clone();
        let green = [0.1, 0.8, 0.2];
        for (y, x) in (12..22).flat_map(|y| (10..20).map(move |x| (y, x))) {
            for (c, value) in green.iter().enumerate() {
                target[(c * SIZE + y) * SIZE + x] = *value;
            }
        }
        (canvas, target)
    }

    /// On a square larger than a seed, the optimizer grows the seed over it: the error falls
    /// to under a fifth of the seed's.
    #[test]
    fn the_optimizer_improves_on_its_seeds() {
        let (canvas, target) = square();
        let optimizer = PathOptimizer { paths: 1, steps: 150 };
        let window = Window::new(SIZE as u32, SIZE as u32, canvas.clone(), target.clone()).unwrap();
        let seeded = window.l2(&error_squares(SIZE, SIZE, &canvas, &target, 1));
        let placed = window.l2(&optimizer.place(SIZE as u32, SIZE as u32, canvas, target));
        assert!(placed < 0.2 * seeded, "{placed} against {seeded}");
    }

    /// A batch places each crop's paths as that crop alone would have them, in order; a crop
    /// with nothing to draw gets invisible paths.
    #[test]
    fn a_batch_places_each_crop_on_its_own() {
        let (canvas, target) = square();
        let device = Device::flex();
        let stack = |first: &[f32], second: &[f32]| {
            let values = [first, second].concat();
            Tensor::<4>::from_data(TensorData::new(values, [2, 3, SIZE, SIZE]), &device)
        };
        let optimizer = PathOptimizer { paths: 2, steps: 20 };
        let placed = optimizer.place_batch(&stack(&canvas, &canvas), &stack(&target, &canvas));
        assert_eq!(placed[0], optimizer.place(SIZE as u32, SIZE as u32, canvas.clone(), target));
        assert_eq!(placed[1].len(), 2);
        assert!(!placed[1].iter().any(Path::is_visible), "nothing to draw on the second crop");
    }
}
