//! Random closed shapes: test scenes for the renderers and the synthetic training data.

use rand::Rng;

use crate::path::{POINTS, Path, SEGMENTS};

/// A random blob: four anchors around a centre at jittered angles and radii, joined by cubics
/// whose handles follow the tangent, so the outline is smooth, mostly convex and sometimes
/// pinched. `radius` is in the unit square; the colour is random and α = 1.
pub fn random_blob(rng: &mut impl Rng, center: [f32; 2], radius: f32) -> Path {
    let rotation = rng.random_range(0.0..std::f32::consts::TAU);
    let anchors: Vec<([f32; 2], [f32; 2])> = (0..SEGMENTS)
        .map(|j| {
            let angle = rotation + j as f32 * std::f32::consts::FRAC_PI_2 + rng.random_range(-0.4..0.4);
            let r = radius * rng.random_range(0.6..1.2);
            let (sin, cos) = angle.sin_cos();
            let anchor = [center[0] + r * cos, center[1] + r * sin];
            // Tangent handle length ≈ 0.55·r makes a quarter of a circle; jitter it.
            let handle = r * rng.random_range(0.3..0.8);
            (anchor, [-sin * handle, cos * handle])
        })
        .collect();
    let mut points = [[0.0; 2]; POINTS];
    for j in 0..SEGMENTS {
        let (start, tangent) = anchors[j];
        let (end, end_tangent) = anchors[(j + 1) % SEGMENTS];
        points[3 * j] = start;
        points[3 * j + 1] = [start[0] + tangent[0], start[1] + tangent[1]];
        points[3 * j + 2] = [end[0] - end_tangent[0], end[1] - end_tangent[1]];
    }
    Path { points, color: [rng.random(), rng.random(), rng.random()], alpha: 1.0 }
}

/// A random scene of `count` blobs of radius 0.05–0.35 anywhere on the canvas.
pub fn random_scene(rng: &mut impl Rng, count: usize) -> Vec<Path> {
    (0..count)
        .map(|_| {
            let center = [rng.random_range(0.1..0.9), rng.random_range(0.1..0.9)];
            let radius = rng.random_range(0.05..0.35);
            random_blob(rng, center, radius)
        })
        .collect()
}
