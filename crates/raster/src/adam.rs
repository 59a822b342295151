//! Adam on paths' parameters outside burn: the optimizer of paths moved by the exact
//! rasterizer's gradient ([`crate::Window`]), one owner for every place that does so.

use crate::fill::{RAMP_COORDS, RAMP_PARAMS};
use crate::path::{COORDS, PARAMS};

/// Adam with burn's defaults (β₁ 0.9, β₂ 0.999, ε 1e-5) on `N` parameters a shape, of which the
/// first `C` are coordinates in the canvas and the rest colours or opacity, all kept in [0, 1].
pub struct Adam<const N: usize, const C: usize> {
    moments: Vec<([f32; N], [f32; N])>,
    steps: i32,
}

/// Adam on paths ([`crate::Path::to_params`]): what moves paths down [`crate::Window`]'s
/// gradient, in SuperSVG-F and wherever paths are optimized one by one.
pub type PathAdam = Adam<PARAMS, COORDS>;

/// Adam on ramps ([`crate::ramp_params`]): what moves a ramped path's fill beside its outline.
pub type RampAdam = Adam<RAMP_PARAMS, RAMP_COORDS>;

impl<const N: usize, const C: usize> Adam<N, C> {
    const BETAS: (f32, f32) = (0.9, 0.999);
    const EPSILON: f32 = 1e-5;

    /// The optimizer of `shapes` shapes, its moments at zero.
    pub fn new(shapes: usize) -> Self {
        Self { moments: vec![([0.0; N], [0.0; N]); shapes], steps: 0 }
    }

    /// One step with rate `lr.0` for coordinates and `lr.1` for colour and opacity.
    pub fn step(&mut self, lr: (f32, f32), params: &mut [[f32; N]], gradients: &[[f32; N]]) {
        self.steps += 1;
        let (b1, b2) = Self::BETAS;
        let (c1, c2) = (1.0 - b1.powi(self.steps), 1.0 - b2.powi(self.steps));
        for ((values, gradient), (first, second)) in params.iter_mut().zip(gradients).zip(&mut self.moments) {
            for i in 0..N {
                // A non-finite gradient (a degenerate outline) moves nothing rather than poison
                // the path with NaN.
                let g = if gradient[i].is_finite() { gradient[i] } else { 0.0 };
                first[i] = b1 * first[i] + (1.0 - b1) * g;
                second[i] = b2 * second[i] + (1.0 - b2) * g * g;
                let rate = if i < C { lr.0 } else { lr.1 };
                let update = rate * (first[i] / c1) / ((second[i] / c2).sqrt() + Self::EPSILON);
                values[i] = (values[i] - update).clamp(0.0, 1.0);
            }
        }
    }
}
