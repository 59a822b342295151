//! Fitting curves to outlines: a path (four cubics, closed) to a whole outline, the simplest
//! drawing of a shape ([`fit_outline`]); lines and cubics to a traced boundary within a
//! tolerance ([`fit_curve`]).

use common::signed_area;

use crate::geometry::{bernstein, cubic_derivative, cubic_point, straight_cubic};
use crate::path::{POINTS, Path, SEGMENTS};
use crate::shape::Segment;

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
    let (control, t) = fit_cubic_parameters(run);
    let cost = run.iter().zip(&t).map(|(q, &ti)| distance(cubic_point(&control, ti), *q).powi(2)).sum();
    (control, cost)
}

/// The cubic of [`fit_cubic`] and the parameter of each point of `run` on it.
fn fit_cubic_parameters(run: &[[f32; 2]]) -> ([[f32; 2]; 4], Vec<f32>) {
    let (first, last) = (run[0], run[run.len() - 1]);
    let mut t = chord_parameters(run);
    let mut control = handles(run, &t, first, last);
    for _ in 0..REPARAMETERIZE {
        for (ti, q) in t.iter_mut().zip(run).skip(1).take(run.len() - 2) {
            *ti = newton_step(&control, *q, *ti);
        }
        control = handles(run, &t, first, last);
    }
    (control, t)
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

/// A turn sharper than this (degrees, between the directions [`CORNER_REACH`] before and after
/// a point) is a corner the fitted curve keeps: a staircase cut into slopes turns by at most
/// ~30° at that reach, a pixel-aligned square's corner by 90°.
const CORNER_ANGLE: f32 = 70.0;
/// How far along the polyline (its unit: pixels) the directions around a point are read.
const CORNER_REACH: f32 = 2.0;
/// The longest gap (pixels) between the points a fitted cubic is checked against: the curve
/// cannot stray far between two checks.
const CHECK_SPACING: f32 = 1.0;

/// Lines and cubics following the polyline `points` (back to its first point when `closed`),
/// no farther than `tolerance` from it and it no farther from them (checked at every point and
/// between points at most [`CHECK_SPACING`] apart): Schneider's scheme, a cubic fitted by least
/// squares and split at its worst point until it is close enough, a line wherever one is.
/// Corners (turns sharper than [`CORNER_ANGLE`]) stay where they are. Returns where the curve
/// starts (the first point, or a corner of a closed polyline) and its pieces, which end at the
/// last point (at the start when closed); a tolerance of 0 keeps every point, as lines.
/// Coordinates in any unit (the constants assume pixels); empty with fewer than two points.
pub fn fit_curve(points: &[[f32; 2]], closed: bool, tolerance: f32) -> ([f32; 2], Vec<Segment>) {
    let mut points = points.to_vec();
    points.dedup();
    if closed {
        while points.len() > 1 && points.first() == points.last() {
            points.pop();
        }
    }
    let Some(&first) = points.first() else { return ([0.0; 2], Vec::new()) };
    if points.len() < 2 {
        return (first, Vec::new());
    }
    let corners = corners(&points, closed);
    if closed {
        // Start at a corner, if there is one, so that it stays one; the loop ends where it starts.
        if let Some(&corner) = corners.first() {
            points.rotate_left(corner);
        }
        points.push(points[0]);
    }
    let mut cuts: Vec<usize> = if closed {
        let rotation = corners.first().copied().unwrap_or(0);
        let n = points.len() - 1;
        corners.iter().map(|&c| (c + n - rotation) % n).collect()
    } else {
        corners
    };
    cuts.retain(|&c| c > 0 && c < points.len() - 1);
    let mut ends = vec![0];
    ends.extend(cuts);
    ends.push(points.len() - 1);
    let mut segments = Vec::new();
    for pair in ends.windows(2) {
        let run = &points[pair[0]..=pair[1]];
        if tolerance <= 0.0 {
            segments.extend(run[1..].iter().map(|&p| Segment::Line(p)));
        } else {
            fit_run(&densified(run), tolerance, &mut segments);
        }
    }
    (points[0], segments)
}

/// The indices of the points where `points` turns by more than [`CORNER_ANGLE`], each the
/// sharpest within [`CORNER_REACH`] of it; the ends of an open polyline are not among them.
fn corners(points: &[[f32; 2]], closed: bool) -> Vec<usize> {
    let n = points.len();
    let at = |i: i64| -> Option<[f32; 2]> {
        if closed {
            Some(points[i.rem_euclid(n as i64) as usize])
        } else {
            points.get(usize::try_from(i).ok()?).copied()
        }
    };
    // The first point at least `CORNER_REACH` away walking `step` (±1) from `i`, or the last one.
    let reach = |i: usize, step: i64| -> Option<[f32; 2]> {
        let (mut j, mut walked, mut found) = (i as i64, 0.0, None);
        for _ in 0..n {
            let (Some(a), Some(b)) = (at(j), at(j + step)) else { break };
            walked += distance(a, b);
            j += step;
            found = Some(b);
            if walked >= CORNER_REACH {
                break;
            }
        }
        found
    };
    let turn: Vec<f32> = (0..n)
        .map(|i| {
            let (Some(before), Some(after)) = (reach(i, -1), reach(i, 1)) else { return 0.0 };
            let p = points[i];
            let (u, v) = ([p[0] - before[0], p[1] - before[1]], [after[0] - p[0], after[1] - p[1]]);
            let cos = (u[0] * v[0] + u[1] * v[1])
                / (distance(p, before) * distance(after, p)).max(f32::MIN_POSITIVE);
            cos.clamp(-1.0, 1.0).acos().to_degrees()
        })
        .collect();
    (0..n)
        .filter(|&i| turn[i] > CORNER_ANGLE)
        .filter(|&i| {
            // The sharpest turn within reach on either side (the first of equals).
            let mut keep = true;
            for step in [-1i64, 1] {
                let (mut j, mut walked) = (i as i64, 0.0);
                for _ in 0..n {
                    let (Some(a), Some(b)) = (at(j), at(j + step)) else { break };
                    walked += distance(a, b);
                    j += step;
                    if walked >= CORNER_REACH {
                        break;
                    }
                    let k = j.rem_euclid(n as i64) as usize;
                    if k != i && (turn[k] > turn[i] || (turn[k] == turn[i] && k < i)) {
                        keep = false;
                    }
                }
            }
            keep
        })
        .collect()
}

/// `run` with points added on its edges so that none is longer than [`CHECK_SPACING`].
fn densified(run: &[[f32; 2]]) -> Vec<[f32; 2]> {
    let mut dense = vec![run[0]];
    for pair in run.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        let pieces = (distance(a, b) / CHECK_SPACING).ceil().max(1.0) as usize;
        dense.extend((1..=pieces).map(|k| {
            let t = k as f32 / pieces as f32;
            [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]
        }));
    }
    dense
}

/// Appends to `segments` the pieces from `run[0]` to its last point: a line if every point is
/// within `tolerance` of it, else a cubic that is, else the two halves split at the worst point.
fn fit_run(run: &[[f32; 2]], tolerance: f32, segments: &mut Vec<Segment>) {
    let (first, last) = (run[0], run[run.len() - 1]);
    if run.len() <= 2 || run.iter().all(|&p| segment_distance(p, first, last) <= tolerance) {
        segments.push(Segment::Line(last));
        return;
    }
    let (control, t) = fit_cubic_parameters(run);
    let mut worst = (0.0f32, run.len() / 2);
    for i in 1..run.len() - 1 {
        let error = distance(cubic_point(&control, t[i]), run[i]);
        if error > worst.0 {
            worst = (error, i);
        }
    }
    // Between two points, the curve must stay near the edge joining them.
    let strays = t.windows(2).zip(run.windows(2)).any(|(ts, edge)| {
        let middle = cubic_point(&control, (ts[0] + ts[1]) / 2.0);
        segment_distance(middle, edge[0], edge[1]) > tolerance
    });
    if worst.0 <= tolerance && !strays {
        segments.push(Segment::Cubic(control[1], control[2], last));
        return;
    }
    if run.len() <= 3 {
        segments.extend(run[1..].iter().map(|&p| Segment::Line(p)));
        return;
    }
    let split = worst.1.clamp(1, run.len() - 2);
    fit_run(&run[..=split], tolerance, segments);
    fit_run(&run[split..], tolerance, segments);
}

/// The distance from `p` to the segment from `a` to `b`.
fn segment_distance(p: [f32; 2], a: [f32; 2], b: [f32; 2]) -> f32 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let length = dx * dx + dy * dy;
    if length <= f32::EPSILON {
        return distance(p, a);
    }
    let t = (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / length).clamp(0.0, 1.0);
    distance(p, [a[0] + t * dx, a[1] + t * dy])
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

    /// The distance from `p` to the polyline `points`.
    fn polyline_distance(p: [f32; 2], points: &[[f32; 2]]) -> f32 {
        points.windows(2).map(|e| segment_distance(p, e[0], e[1])).fold(f32::INFINITY, f32::min)
    }

    /// The points of `segments` from `start`, cubics sampled `steps` times.
    fn sampled(start: [f32; 2], segments: &[Segment], steps: usize) -> Vec<[f32; 2]> {
        let mut points = vec![start];
        let mut at = start;
        for segment in segments {
            let control = match *segment {
                Segment::Line(end) => straight_cubic(at, end),
                Segment::Cubic(c1, c2, end) => [at, c1, c2, end],
            };
            points.extend((1..=steps).map(|i| cubic_point(&control, i as f32 / steps as f32)));
            at = segment.end();
        }
        points
    }

    #[test]
    fn fitted_curves_stay_within_the_tolerance_both_ways() {
        // A wobbly traced edge: a staircase along a sine, in pixels.
        let traced: Vec<[f32; 2]> = (0..=60)
            .flat_map(|x| {
                let y = (10.0 + 6.0 * (x as f32 / 9.0).sin()).round();
                [[x as f32, y], [x as f32 + 1.0, y]]
            })
            .collect();
        for tolerance in [0.25, 0.5, 1.0, 2.0] {
            let (start, segments) = fit_curve(&traced, false, tolerance);
            assert_eq!(start, traced[0]);
            assert_eq!(segments.last().unwrap().end(), *traced.last().unwrap());
            let curve = sampled(start, &segments, 32);
            let far = traced.iter().map(|&p| polyline_distance(p, &curve)).fold(0.0, f32::max);
            let strays = curve.iter().map(|&p| polyline_distance(p, &traced)).fold(0.0, f32::max);
            assert!(far <= tolerance + 0.02, "tolerance {tolerance}: a traced point {far} away");
            assert!(strays <= tolerance + 0.02, "tolerance {tolerance}: the curve strays {strays}");
            // A pixel and more is looser than the steps: the curve follows the sine, not them.
            if tolerance >= 1.0 {
                assert!(segments.len() <= 12, "{} pieces for {} points", segments.len(), traced.len());
            }
        }
        // Looser fits take fewer pieces; no tolerance keeps every point.
        let count = |tolerance| fit_curve(&traced, false, tolerance).1.len();
        assert!(count(2.0) < count(0.25), "{} vs {}", count(2.0), count(0.25));
        let mut distinct = traced.clone();
        distinct.dedup();
        assert_eq!(count(0.0), distinct.len() - 1);
    }

    #[test]
    fn straight_edges_are_lines_and_corners_stay() {
        // A closed square, traced along its pixel edges: four lines meeting at its corners.
        let mut square = Vec::new();
        square.extend((0..10).map(|i| [i as f32, 0.0]));
        square.extend((0..10).map(|i| [10.0, i as f32]));
        square.extend((0..10).map(|i| [10.0 - i as f32, 10.0]));
        square.extend((0..10).map(|i| [0.0, 10.0 - i as f32]));
        square.rotate_left(5);
        let (start, segments) = fit_curve(&square, true, 0.5);
        assert_eq!(segments.len(), 4, "{segments:?}");
        assert!(segments.iter().all(|s| matches!(s, Segment::Line(_))));
        let mut ends: Vec<[f32; 2]> = segments.iter().map(Segment::end).collect();
        assert_eq!(ends.last(), Some(&start), "the loop closes where it starts");
        ends.sort_by(|a, b| a.partial_cmp(b).unwrap());
        assert_eq!(ends, vec![[0.0, 0.0], [0.0, 10.0], [10.0, 0.0], [10.0, 10.0]]);
        // A circle has no corner: cubics all round, within the tolerance.
        let circle = circle([20.0, 20.0], 12.0, 300);
        let (start, segments) = fit_curve(&circle, true, 0.2);
        assert!(
            segments.iter().all(|s| matches!(s, Segment::Cubic(..))) && segments.len() <= 12,
            "{segments:?}"
        );
        for p in sampled(start, &segments, 16) {
            let radius = distance(p, [20.0, 20.0]);
            assert!((radius - 12.0).abs() <= 0.25, "{p:?} at {radius}");
        }
        assert!(fit_curve(&[[1.0, 1.0]], false, 0.5).1.is_empty());
    }
}
