//! Fitting a path (four cubics, closed) to an outline: the simplest drawing of a shape.

use common::signed_area;

use crate::geometry::{bernstein, cubic_derivative, cubic_point, straight_cubic};
use crate::path::{POINTS, Path, SEGMENTS};

/// Points the outline is resampled to before fitting (16 per cubic): enough to follow a
/// superpixel's outline at the scale one path can, few enough to fit thousands per second.
const SAMPLES: usize = 64;
/// Samples per cubic.
const PER_SEGMENT: usize = SAMPLES / SEGMENTS;
/// Rounds of re-projecting the samples onto the fitted curve and fitting again.
const REPARAMETERIZE: usize = 2;

/// The closed path of four cubics closest (least squares over the outline's points) to the
/// closed polygon `outline`, coordinates in whatever unit the outline uses, filled with `color`
/// at opacity `alpha`.
///
/// The outline is resampled evenly by length; each cubic's two handles are solved for by least
/// squares with its ends (anchors) fixed on the outline and the samples re-projected onto the
/// curve twice. Every rotation of four evenly spaced anchors is tried, and from the best one each
/// anchor slides along the outline, a sample or two at a time, while that lowers the total
/// error. `grow` moves every sample that far along the outline's
/// outward normal first (in the outline's unit), so paths of neighbouring outlines overlap
/// instead of leaving seams. `None` if the outline has fewer than three distinct points, no
/// length, or a non-finite coordinate.
pub fn fit_outline(outline: &[[f32; 2]], grow: f32, color: [f32; 3], alpha: f32) -> Option<Path> {
    if outline.len() < 3 || outline.iter().flatten().any(|v| !v.is_finite()) {
        return None;
    }
    let samples = grown(&resample(outline)?, grow);
    // Evenly spaced anchors at every rotation, then each anchor slid along the outline while
    // that lowers the error: irregular outlines want their anchors where they turn.
    let even = |offset: usize| std::array::from_fn(|j| offset + j * PER_SEGMENT);
    let mut anchors: [usize; SEGMENTS] = (0..PER_SEGMENT)
        .map(even)
        .min_by(|a, b| total_error(&samples, a).total_cmp(&total_error(&samples, b)))
        .expect("at least one rotation");
    let mut errors: [f32; SEGMENTS] = std::array::from_fn(|j| segment_error(&samples, &anchors, j));
    for _ in 0..ANCHOR_ROUNDS {
        let mut moved = false;
        for j in 0..SEGMENTS {
            // Anchor j ends cubic j − 1 and starts cubic j: only those two change.
            let before = (j + SEGMENTS - 1) % SEGMENTS;
            for step in [-2i64, -1, 1, 2] {
                let mut trial = anchors;
                trial[j] = (anchors[j] as i64 + step).rem_euclid(SAMPLES as i64) as usize;
                if !spans_ok(&trial) {
                    continue;
                }
                let (e_before, e_after) =
                    (segment_error(&samples, &trial, before), segment_error(&samples, &trial, j));
                if e_before + e_after < errors[before] + errors[j] {
                    (anchors, errors[before], errors[j], moved) = (trial, e_before, e_after, true);
                }
            }
        }
        if !moved {
            break;
        }
    }
    let mut points = [[0.0; 2]; POINTS];
    for j in 0..SEGMENTS {
        let (control, _) = fit_cubic(&span(&samples, anchors[j], anchors[(j + 1) % SEGMENTS]));
        points[3 * j..3 * j + 3].copy_from_slice(&control[..3]);
    }
    Some(Path { points, color, alpha })
}

/// Rounds of sliding the anchors.
const ANCHOR_ROUNDS: usize = 6;
/// The fewest samples a cubic spans, so no cubic collapses.
const MIN_SPAN: usize = 4;

/// The samples from anchor `from` to anchor `to` along the loop, both included.
fn span(samples: &[[f32; 2]], from: usize, to: usize) -> Vec<[f32; 2]> {
    let length = (to + SAMPLES - from) % SAMPLES;
    (0..=length).map(|i| samples[(from + i) % SAMPLES]).collect()
}

/// Whether consecutive anchors keep their order around the loop with at least [`MIN_SPAN`]
/// samples between them.
fn spans_ok(anchors: &[usize; SEGMENTS]) -> bool {
    let total: usize =
        (0..SEGMENTS).map(|j| (anchors[(j + 1) % SEGMENTS] + SAMPLES - anchors[j]) % SAMPLES).sum();
    total == SAMPLES
        && (0..SEGMENTS).all(|j| (anchors[(j + 1) % SEGMENTS] + SAMPLES - anchors[j]) % SAMPLES >= MIN_SPAN)
}

/// The fitting error of the cubic from anchor `j` to the next.
fn segment_error(samples: &[[f32; 2]], anchors: &[usize; SEGMENTS], j: usize) -> f32 {
    fit_cubic(&span(samples, anchors[j], anchors[(j + 1) % SEGMENTS])).1
}

/// The fitting error of four cubics between consecutive anchors.
fn total_error(samples: &[[f32; 2]], anchors: &[usize; SEGMENTS]) -> f32 {
    (0..SEGMENTS).map(|j| segment_error(samples, anchors, j)).sum()
}

/// `SAMPLES` points evenly spaced along the closed polygon, starting at its first point.
fn resample(outline: &[[f32; 2]]) -> Option<Vec<[f32; 2]>> {
    let n = outline.len();
    let lengths: Vec<f32> = (0..n).map(|i| distance(outline[i], outline[(i + 1) % n])).collect();
    let total: f32 = lengths.iter().sum();
    if total <= f32::EPSILON || outline.iter().filter(|p| **p != outline[0]).count() < 2 {
        return None;
    }
    let step = total / SAMPLES as f32;
    let mut samples = Vec::with_capacity(SAMPLES);
    let (mut edge, mut walked) = (0, 0.0);
    for k in 0..SAMPLES {
        let at = k as f32 * step;
        while edge < n - 1 && walked + lengths[edge] < at {
            walked += lengths[edge];
            edge += 1;
        }
        let (a, b) = (outline[edge], outline[(edge + 1) % n]);
        let t = if lengths[edge] > 0.0 { ((at - walked) / lengths[edge]).clamp(0.0, 1.0) } else { 0.0 };
        samples.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
    }
    Some(samples)
}

/// The samples moved by `grow` along the outward normal (the side that makes the enclosed area
/// larger, whichever way the outline turns).
fn grown(samples: &[[f32; 2]], grow: f32) -> Vec<[f32; 2]> {
    if grow == 0.0 {
        return samples.to_vec();
    }
    let n = samples.len();
    // For an outline turning clockwise on screen (positive area, y down) the outward side of
    // the tangent (dx, dy) is (dy, −dx).
    let sign = if signed_area(samples) >= 0.0 { 1.0 } else { -1.0 };
    (0..n)
        .map(|i| {
            let (before, after) = (samples[(i + n - 1) % n], samples[(i + 1) % n]);
            let (dx, dy) = (after[0] - before[0], after[1] - before[1]);
            let length = (dx * dx + dy * dy).sqrt();
            if length <= f32::EPSILON {
                return samples[i];
            }
            let normal = [sign * dy / length, -sign * dx / length];
            [samples[i][0] + grow * normal[0], samples[i][1] + grow * normal[1]]
        })
        .collect()
}

/// The cubic from `run[0]` to the last point of `run` closest to all of `run`, and the sum of
/// squared distances at the fitted parameters.
fn fit_cubic(run: &[[f32; 2]]) -> ([[f32; 2]; 4], f32) {
    let (first, last) = (run[0], run[run.len() - 1]);
    let mut t = chord_parameters(run);
    let mut control = handles(run, &t, first, last);
    for _ in 0..REPARAMETERIZE {
        for (ti, q) in t.iter_mut().zip(run).skip(1).take(run.len() - 2) {
            *ti = newton_step(&control, *q, *ti);
        }
        control = handles(run, &t, first, last);
    }
    let cost = run.iter().zip(&t).map(|(q, &ti)| distance(cubic_point(&control, ti), *q).powi(2)).sum();
    (control, cost)
}

/// Parameters in [0, 1] proportional to the distance walked along `run`.
fn chord_parameters(run: &[[f32; 2]]) -> Vec<f32> {
    let mut t = vec![0.0; run.len()];
    for i in 1..run.len() {
        t[i] = t[i - 1] + distance(run[i - 1], run[i]);
    }
    let total = t[run.len() - 1];
    if total > 0.0 {
        t.iter_mut().for_each(|v| *v /= total);
    } else {
        let last = (run.len() - 1) as f32;
        t.iter_mut().enumerate().for_each(|(i, v)| *v = i as f32 / last);
    }
    t
}

/// The two handles minimizing `Σ |B(tᵢ) − qᵢ|²` with the ends fixed (2 × 2 normal equations per
/// coordinate); a straight cubic when the system is singular.
fn handles(run: &[[f32; 2]], t: &[f32], first: [f32; 2], last: [f32; 2]) -> [[f32; 2]; 4] {
    let (mut a11, mut a12, mut a22) = (0.0f32, 0.0f32, 0.0f32);
    let (mut r1, mut r2) = ([0.0f32; 2], [0.0f32; 2]);
    for (q, &ti) in run.iter().zip(t) {
        let [b0, b1, b2, b3] = bernstein(ti);
        a11 += b1 * b1;
        a12 += b1 * b2;
        a22 += b2 * b2;
        for c in 0..2 {
            let rest = q[c] - b0 * first[c] - b3 * last[c];
            r1[c] += b1 * rest;
            r2[c] += b2 * rest;
        }
    }
    let det = a11 * a22 - a12 * a12;
    if det.abs() <= 1e-9 * (a11 * a22).max(f32::MIN_POSITIVE) {
        return straight_cubic(first, last);
    }
    let solve = |c: usize| ((a22 * r1[c] - a12 * r2[c]) / det, (a11 * r2[c] - a12 * r1[c]) / det);
    let ((x1, x2), (y1, y2)) = (solve(0), solve(1));
    let control = [first, [x1, y1], [x2, y2], last];
    if control.iter().flatten().all(|v| v.is_finite()) { control } else { straight_cubic(first, last) }
}

/// One Newton step of `t` towards the curve point nearest to `q`, kept in [0, 1].
fn newton_step(control: &[[f32; 2]; 4], q: [f32; 2], t: f32) -> f32 {
    let [p0, p1, p2, p3] = *control;
    let s = 1.0 - t;
    let point = cubic_point(control, t);
    let first = cubic_derivative(control, t);
    let second =
        [0, 1].map(|c| 6.0 * (s * (p2[c] - 2.0 * p1[c] + p0[c]) + t * (p3[c] - 2.0 * p2[c] + p1[c])));
    let offset = [point[0] - q[0], point[1] - q[1]];
    let numerator = offset[0] * first[0] + offset[1] * first[1];
    let denominator =
        first[0] * first[0] + first[1] * first[1] + offset[0] * second[0] + offset[1] * second[1];
    if denominator.abs() <= f32::EPSILON || !denominator.is_finite() {
        return t;
    }
    (t - numerator / denominator).clamp(0.0, 1.0)
}

fn distance(a: [f32; 2], b: [f32; 2]) -> f32 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn circle(center: [f32; 2], radius: f32, n: usize) -> Vec<[f32; 2]> {
        (0..n)
            .map(|i| {
                let angle = i as f32 / n as f32 * std::f32::consts::TAU;
                [center[0] + radius * angle.cos(), center[1] + radius * angle.sin()]
            })
            .collect()
    }

    #[test]
    fn a_circle_is_fitted_closely() {
        let path = fit_outline(&circle([20.0, 30.0], 10.0, 200), 0.0, [0.5; 3], 1.0).unwrap();
        for point in path.flatten(16) {
            let radius = ((point[0] - 20.0).powi(2) + (point[1] - 30.0).powi(2)).sqrt();
            assert!((radius - 10.0).abs() < 0.05, "{point:?} is {radius} from the centre");
        }
        let area = path.signed_area().abs();
        assert!((area - std::f32::consts::PI * 100.0).abs() < 1.0, "{area}");
    }

    #[test]
    fn squares_keep_their_corners_roughly_and_growing_enlarges_them() {
        let square = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]];
        let path = fit_outline(&square, 0.0, [0.0; 3], 1.0).unwrap();
        assert!((path.signed_area().abs() - 100.0).abs() < 6.0, "{}", path.signed_area());
        let grown = fit_outline(&square, 1.0, [0.0; 3], 1.0).unwrap();
        assert!(grown.signed_area().abs() > path.signed_area().abs() + 30.0);
        let mut reversed = square;
        reversed.reverse();
        let grown_reversed = fit_outline(&reversed, 1.0, [0.0; 3], 1.0).unwrap();
        assert!((grown_reversed.signed_area().abs() - grown.signed_area().abs()).abs() < 1.0);
    }

    #[test]
    fn degenerate_outlines_are_refused() {
        assert!(fit_outline(&[[1.0, 1.0]; 5], 0.0, [0.0; 3], 1.0).is_none());
        assert!(fit_outline(&[[0.0, 0.0], [1.0, 1.0]], 0.0, [0.0; 3], 1.0).is_none());
        assert!(fit_outline(&[[0.0, 0.0], [1.0, f32::NAN], [1.0, 0.0]], 0.0, [0.0; 3], 1.0).is_none());
        // A line walked there and back has length but no area: still a (flat) path, never NaN.
        let flat = fit_outline(&[[0.0, 0.0], [5.0, 0.0], [10.0, 0.0]], 0.0, [0.0; 3], 1.0).unwrap();
        assert!(flat.points.iter().flatten().all(|v| v.is_finite()));
    }
}
