//! Adam on paths' parameters outside burn: the optimizer of paths moved by the exact
//! rasterizer's gradient ([`crate::Window`]), one owner for every place that does so.

use crate::path::{COORDS, PARAMS};

/// Adam with burn's defaults (β₁ 0.9, β₂ 0.999, ε 1e-5) on paths' parameters, which stay in
/// [0, 1] (coordinates in the canvas, colours, opacity): what moves paths down
/// [`crate::Window`]'s gradient, in SuperSVG-F and wherever paths are optimized one by one.
pub struct PathAdam {
    moments: Vec<([f32; PARAMS], [f32; PARAMS])>,
    steps: i32,
}

impl PathAdam {
    const BETAS: (f32, f32) = (0.9, 0.999);
    const EPSILON: f32 = 1e-5;

    /// The optimizer of `paths` paths, its moments at zero.
    pub fn new(paths: usize) -> Self {
        Self { moments: vec![([0.0; PARAMS], [0.0; PARAMS]); paths], steps: 0 }
    }

    /// One step with rate `lr.0` for coordinates and `lr.1` for colour and opacity.
    pub fn step(&mut self, lr: (f32, f32), params: &mut [[f32; PARAMS]], gradients: &[[f32; PARAMS]]) {
        self.steps += 1;
        let (b1, b2) = Self::BETAS;
        let (c1, c2) = (1.0 - b1.powi(self.steps), 1.0 - b2.powi(self.steps));
        for ((values, gradient), (first, second)) in params.iter_mut().zip(gradients).zip(&mut self.moments) {
            for i in 0..PARAMS {
                // A non-finite gradient (a degenerate outline) moves nothing rather than poison
                // the path with NaN.
                let g = if gradient[i].is_finite() { gradient[i] } else { 0.0 };
                first[i] = b1 * first[i] + (1.0 - b1) * g;
                second[i] = b2 * second[i] + (1.0 - b2) * g * g;
                let rate = if i < COORDS { lr.0 } else { lr.1 };
                let update = rate * (first[i] / c1) / ((second[i] / c2).sqrt() + Self::EPSILON);
                values[i] = (values[i] - update).clamp(0.0, 1.0);
            }
        }
    }
}
