//! A batch of path sets painted exactly over their canvases, with the backward pass of any
//! loss of the render: training on the exact render, where the soft rasterizer's autodiff graph
//! costs paths × pixels. One [`Window`] per sample, on the CPU; what crosses into burn is the
//! render, the union and, after the loss is known, the gradient by the paths' parameters.

use burn::tensor::{Device, Tensor, TensorData};
use rayon::prelude::*;

use crate::gradient::Window;
use crate::path::{PARAMS, Path, PathBatch};

/// `paths` painted exactly over `canvas`, sample by sample, with what the gradient needs.
pub struct ExactBatch {
    windows: Vec<Window>,
    scenes: Vec<Vec<Path>>,
    /// `[batch, paths, height, width]`.
    dims: [usize; 4],
    render: Vec<f32>,
    union: Vec<f32>,
}

impl ExactBatch {
    /// Paints `paths` (`[B, P]`, coordinates in each sample's unit square) over `canvas`
    /// (`[B, 3, H, W]`), in painter's order. Only values are read: nothing is tracked.
    ///
    /// # Panics
    /// If the canvas and the paths disagree on the batch size, or the canvas is empty.
    pub fn paint(canvas: &Tensor<4>, paths: &PathBatch) -> Self {
        let [batch, _, height, width] = canvas.dims();
        let [path_batch, count] = paths.dims();
        assert_eq!(batch, path_batch, "one canvas per sample");
        let values: Vec<f32> = canvas.try_to_vec_as().expect("the canvas is readable");
        let scenes = paths.to_scenes();
        let plane = 3 * height * width;
        let windows: Vec<Window> = values
            .chunks_exact(plane.max(1))
            .map(|canvas| {
                // The target is what `Window::l2` scores against; gradients here come from the
                // loss the caller computes, so any buffer of the right size will do.
                Window::new(width as u32, height as u32, canvas.to_vec(), canvas.to_vec())
                    .expect("a non-empty canvas of 3 × height × width values")
            })
            .collect();
        let drawn: Vec<(Vec<f32>, Vec<f32>)> =
            windows.par_iter().zip(&scenes).map(|(window, scene)| window.render_with_union(scene)).collect();
        let (render, union) = drawn.into_iter().fold(
            (Vec::with_capacity(batch * plane), Vec::with_capacity(batch * height * width)),
            |(mut render, mut union), (r, u)| {
                render.extend(r);
                union.extend(u);
                (render, union)
            },
        );
        Self { windows, scenes, dims: [batch, count, height, width], render, union }
    }

    /// The render `[B, 3, H, W]`, a leaf tensor on `device`.
    pub fn render(&self, device: &Device) -> Tensor<4> {
        let [batch, _, height, width] = self.dims;
        Tensor::from_data(TensorData::new(self.render.clone(), [batch, 3, height, width]), device)
    }

    /// The union of each sample's path coverages `[B, 1, H, W]` (opacity ignored, as
    /// [`crate::paint_soft_with_union`]'s), a leaf tensor on `device`.
    pub fn union(&self, device: &Device) -> Tensor<4> {
        let [batch, _, height, width] = self.dims;
        Tensor::from_data(TensorData::new(self.union.clone(), [batch, 1, height, width]), device)
    }

    /// The gradient `[B, P, 28]` by the paths' parameters of a loss whose derivatives by the
    /// render (`[B, 3, H, W]`) and by the union (`[B, 1, H, W]`) are given (`None`: the loss
    /// does not read it), on `device`.
    ///
    /// # Panics
    /// If a derivative does not have the render's or the union's shape.
    pub fn gradient(
        &self,
        by_render: Option<&Tensor<4>>,
        by_union: Option<&Tensor<4>>,
        device: &Device,
    ) -> Tensor<3> {
        let [batch, count, height, width] = self.dims;
        let read = |tensor: Option<&Tensor<4>>, channels: usize| -> Option<Vec<f32>> {
            tensor.map(|t| {
                assert_eq!(t.dims(), [batch, channels, height, width], "a derivative has its value's shape");
                t.try_to_vec_as().expect("derivatives are readable")
            })
        };
        let (by_render, by_union) = (read(by_render, 3), read(by_union, 1));
        let plane = height * width;
        let values: Vec<f32> = (0..batch)
            .into_par_iter()
            .flat_map_iter(|b| {
                let render = by_render.as_deref().map(|g| &g[3 * plane * b..3 * plane * (b + 1)]);
                let union = by_union.as_deref().map(|g| &g[plane * b..plane * (b + 1)]);
                self.windows[b].gradient(&self.scenes[b], render, union).into_iter().flatten()
            })
            .collect();
        Tensor::from_data(TensorData::new(values, [batch, count, PARAMS]), device)
    }
}

#[cfg(test)]
mod tests {
    use burn::tensor::Device;
    use rand::SeedableRng;

    use super::*;
    use crate::shapes::random_scene;
    use crate::soft::{SoftRasterOptions, paint_soft_with_union};

    /// The exact batch's render and union are the soft rasterizer's up to anti-aliasing, and
    /// the gradient of a loss of both (computed by burn from the exact values) points where the
    /// soft rasterizer's autodiff gradient of the same loss points (measured on E_c's first
    /// paths over a training batch: cosine 0.97 for the masked L2, 0.995 for the boundary term;
    /// 0.34 for the opacities while hidden paths got no coverage).
    #[test]
    fn agrees_with_the_soft_rasterizer() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(29);
        let device = Device::flex().autodiff();
        let (batch, size) = (3, 32);
        // One path of each scene hidden: it still reaches the union and has an opacity gradient
        // (what a straight-through visibility needs to turn it back on).
        let scenes: Vec<Vec<Path>> = (0..batch)
            .map(|_| {
                let mut scene = random_scene(&mut rng, 4);
                scene[1].alpha = 0.0;
                scene
            })
            .collect();
        let canvas = Tensor::<4>::full([batch, 3, size, size], 0.5, &device);
        let target = Tensor::<4>::random(
            [batch, 3, size, size],
            burn::tensor::Distribution::Uniform(0.0, 1.0),
            &device,
        );
        let mask = Tensor::<4>::random(
            [batch, 1, size, size],
            burn::tensor::Distribution::Uniform(0.0, 1.0),
            &device,
        );
        // A loss of the render and of the union.
        let loss = |render: Tensor<4>, union: Tensor<4>| {
            (render - target.clone()).square().mean() + (union * mask.clone()).mean() * 0.1
        };

        let params = PathBatch::from_scenes(&scenes, &device).into_params().require_grad();
        let paths = PathBatch::new(params.clone());
        let (render, union) = paint_soft_with_union(canvas.clone(), &paths, &SoftRasterOptions::default());
        let soft_loss = loss(render.clone(), union.clone());
        let soft: Vec<f32> = params.grad(&soft_loss.clone().backward()).unwrap().try_to_vec_as().unwrap();

        let exact = ExactBatch::paint(&canvas, &paths);
        let (leaf_render, leaf_union) =
            (exact.render(&device).require_grad(), exact.union(&device).require_grad());
        let close = |a: Tensor<4>, b: Tensor<4>| (a - b).abs().mean().into_scalar::<f32>();
        assert!(close(leaf_render.clone(), render) < 0.02);
        assert!(close(leaf_union.clone(), union) < 0.02);
        let exact_loss = loss(leaf_render.clone(), leaf_union.clone());
        let grads = exact_loss.backward();
        let (by_render, by_union) = (leaf_render.grad(&grads).unwrap(), leaf_union.grad(&grads).unwrap());
        let gradient = exact.gradient(Some(&by_render), Some(&by_union), &device.clone().inner());
        let exact: Vec<f32> = gradient.try_to_vec_as().unwrap();
        let dot: f32 = soft.iter().zip(&exact).map(|(a, b)| a * b).sum();
        let norm = |v: &[f32]| v.iter().map(|x| x * x).sum::<f32>().sqrt();
        let cosine = dot / (norm(&soft) * norm(&exact));
        assert!(cosine > 0.95, "cosine {cosine}");

        // The union's share alone: the colours get nothing from it.
        let only_union = ExactBatch::paint(&canvas, &paths).gradient(None, Some(&by_union), &device.inner());
        let colors: Vec<f32> = PathBatch::new(only_union).colors().try_to_vec_as().unwrap();
        assert!(colors.iter().all(|c| *c == 0.0));
    }
}
