//! Adam on paths' parameters outside burn: the optimizer of paths moved by the exact
//! rasterizer's gradient ([`crate::Window`]), one owner for every place that does so.

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

impl<const N: usize, const C: usize> Adam<N, C> {
    /// The optimizer of `shapes` shapes, its moments at zero.
    pub fn new(shapes: usize) -> Self {
        Self { moments: vec![([0.0; N], [0.0; N]); shapes], steps: 0 }
    }

    /// One step with rate `lr.0` for coordinates and `lr.1` for colour and opacity.
    pub fn step(&mut self, lr: (f32, f32), params: &mut [[f32; N]], gradients: &[[f32; N]]) {
        self.steps += 1;
        let (b1, b2) = BETAS;
        let (c1, c2) = (1.0 - b1.powi(self.steps), 1.0 - b2.powi(self.steps));
        for ((values, gradient), (first, second)) in params.iter_mut().zip(gradients).zip(&mut self.moments) {
            for i in 0..N {
                let rate = if i < C { lr.0 } else { lr.1 };
                update(&mut values[i], gradient[i], (&mut first[i], &mut second[i]), rate, (c1, c2));
            }
        }
    }
}

/// Adam as [`Adam`] on one list of parameters laid end to end, each with its own rate: shapes
/// with any number of points (outlines), as SuperSVG-F moves them.
pub struct FlatAdam {
    moments: Vec<(f32, f32)>,
    steps: i32,
}

impl FlatAdam {
    /// The optimizer of `len` parameters, its moments at zero.
    pub fn new(len: usize) -> Self {
        Self { moments: vec![(0.0, 0.0); len], steps: 0 }
    }

    /// One step, parameter `i` at rate `rates[i]`.
    ///
    /// # Panics
    /// If `rates`, `params` and `gradients` differ in length from the optimizer.
    pub fn step(&mut self, rates: &[f32], params: &mut [f32], gradients: &[f32]) {
        let len = self.moments.len();
        assert!(rates.len() == len && params.len() == len && gradients.len() == len, "one value a parameter");
        self.steps += 1;
        let (b1, b2) = BETAS;
        let corrections = (1.0 - b1.powi(self.steps), 1.0 - b2.powi(self.steps));
        for (((value, &gradient), (first, second)), &rate) in
            params.iter_mut().zip(gradients).zip(&mut self.moments).zip(rates)
        {
            update(value, gradient, (first, second), rate, corrections);
        }
    }
}

/// burn's defaults: β₁, β₂ and ε.
const BETAS: (f32, f32) = (0.9, 0.999);
const EPSILON: f32 = 1e-5;

/// One parameter's Adam step at `rate` (moments updated in place, `corrections` the bias
/// corrections of the step), the value kept in [0, 1].
fn update(
    value: &mut f32,
    gradient: f32,
    (first, second): (&mut f32, &mut f32),
    rate: f32,
    (c1, c2): (f32, f32),
) {
    let (b1, b2) = BETAS;
    // A non-finite gradient (a degenerate outline) moves nothing rather than poison the shape
    // with NaN.
    let g = if gradient.is_finite() { gradient } else { 0.0 };
    *first = b1 * *first + (1.0 - b1) * g;
    *second = b2 * *second + (1.0 - b2) * g * g;
    let step = rate * (*first / c1) / ((*second / c2).sqrt() + EPSILON);
    *value = (*value - step).clamp(0.0, 1.0);
}
