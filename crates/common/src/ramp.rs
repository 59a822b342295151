//! A linear colour ramp (what SVG's `linearGradient` with two stops draws) and the statistics of
//! a set of pixels that fit the best one in closed form.
//!
//! The fit is least squares over a region's pixels: among colour fields that change along one
//! direction only, `c(p) = c̄ + u · vᵀ(p − p̄)`, the one of least squared error. For a direction
//! `v` the best slope is `u = C v / vᵀSv` (`C`: the colour–position covariance, `S`: the position
//! covariance, both summed over pixels), and it lowers the flat fill's error by `|C v|² / vᵀSv`; the
//! best direction maximizes that Rayleigh quotient, the largest root of `det(CᵀC − λS) = 0`.
//! Every statistic is a sum over pixels, so a union of regions is fitted from the sum of theirs.

use std::ops::AddAssign;

use image::Rgb32FImage;

/// A colour that changes linearly from `stops[0]` at `start` to `stops[1]` at `end` along the
/// line between them, constant across it, and padded beyond the ends (SVG's
/// `spreadMethod="pad"`). Points are in whatever frame the shape it fills uses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ramp {
    /// Where the colour is `stops[0]`.
    pub start: [f32; 2],
    /// Where the colour is `stops[1]`.
    pub end: [f32; 2],
    /// RGB in [0, 1] at `start` and at `end`.
    pub stops: [[f32; 3]; 2],
}

impl Ramp {
    /// The colour at `point`: the stops interpolated at its projection onto the ramp, clamped to
    /// the ends (the first stop where the ends coincide).
    pub fn color_at(&self, point: [f32; 2]) -> [f32; 3] {
        let axis = [self.end[0] - self.start[0], self.end[1] - self.start[1]];
        let length = axis[0] * axis[0] + axis[1] * axis[1];
        let along = if length > 0.0 {
            ((point[0] - self.start[0]) * axis[0] + (point[1] - self.start[1]) * axis[1]) / length
        } else {
            0.0
        };
        let t = along.clamp(0.0, 1.0);
        let [a, b] = self.stops;
        std::array::from_fn(|c| a[c] + t * (b[c] - a[c]))
    }

    /// The colour halfway: what one flat colour standing for the ramp is.
    pub fn middle(&self) -> [f32; 3] {
        let [a, b] = self.stops;
        std::array::from_fn(|c| 0.5 * (a[c] + b[c]))
    }

    /// The same ramp with its end points mapped by `f` (another frame).
    pub fn map_points(&self, f: impl Fn([f32; 2]) -> [f32; 2]) -> Self {
        Self { start: f(self.start), end: f(self.end), stops: self.stops }
    }

    /// Whether every number is finite.
    pub fn is_finite(&self) -> bool {
        self.start.iter().chain(&self.end).chain(self.stops.iter().flatten()).all(|v| v.is_finite())
    }
}

/// Sums over a set of pixels (position and RGB) from which its best flat colour, its best
/// [`Ramp`] and their squared errors follow in closed form. Sums add: the statistics of a union
/// are the sum of its parts'.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Moments {
    count: f64,
    position: [f64; 2],
    color: [f64; 3],
    /// Σx², Σxy, Σy².
    position_squares: [f64; 3],
    /// Σ c·x and Σ c·y per channel.
    cross: [[f64; 2]; 3],
    /// Σ |c|².
    color_squares: f64,
}

impl Moments {
    /// Adds one pixel at `position` of colour `color`.
    pub fn add(&mut self, position: [f32; 2], color: [f32; 3]) {
        let [x, y] = position.map(f64::from);
        self.count += 1.0;
        self.position[0] += x;
        self.position[1] += y;
        self.position_squares[0] += x * x;
        self.position_squares[1] += x * y;
        self.position_squares[2] += y * y;
        for (c, &value) in color.iter().enumerate() {
            let value = f64::from(value);
            self.color[c] += value;
            self.cross[c][0] += value * x;
            self.cross[c][1] += value * y;
            self.color_squares += value * value;
        }
    }

    /// The sums of each label's pixels of `image`, `labels` giving every pixel's (row-major, each
    /// below `count`), at pixel centres (`x + 0.5`, `y + 0.5`): the frame ramps are fitted in.
    ///
    /// # Panics
    /// If a label is `count` or more.
    pub fn per_label(image: &Rgb32FImage, labels: &[u32], count: usize) -> Vec<Moments> {
        let width = image.width() as usize;
        let mut sums = vec![Moments::default(); count];
        for (i, (&label, pixel)) in labels.iter().zip(image.pixels()).enumerate() {
            sums[label as usize].add([(i % width) as f32 + 0.5, (i / width) as f32 + 0.5], pixel.0);
        }
        sums
    }

    /// How many pixels.
    pub fn count(&self) -> f64 {
        self.count
    }

    /// The mean colour (black for no pixels).
    pub fn mean_color(&self) -> [f32; 3] {
        let n = self.count.max(1.0);
        self.color.map(|s| (s / n) as f32)
    }

    /// The squared error (summed over pixels and channels) of filling the pixels with their mean
    /// colour.
    pub fn flat_error(&self) -> f64 {
        if self.count == 0.0 {
            return 0.0;
        }
        let means: f64 = self.color.iter().map(|s| s * s).sum::<f64>() / self.count;
        (self.color_squares - means).max(0.0)
    }

    /// The best colour field that changes along one direction ([`LinearFit`]); `None` without
    /// pixels spread in two dimensions (a line of pixels or fewer than three) or without a
    /// direction in which the colour changes.
    pub fn linear_fit(&self) -> Option<LinearFit> {
        let n = self.count;
        if n < 3.0 {
            return None;
        }
        let centroid = self.position.map(|s| s / n);
        // Position covariance S and colour–position covariance C, summed over pixels.
        let s = [
            self.position_squares[0] - self.position[0] * centroid[0],
            self.position_squares[1] - self.position[0] * centroid[1],
            self.position_squares[2] - self.position[1] * centroid[1],
        ];
        let det_s = s[0] * s[2] - s[1] * s[1];
        // Pixels on one line (or all but a sliver of them) have no second direction to ramp in.
        if !(det_s > 1e-9 * (s[0] + s[2]).powi(2)) {
            return None;
        }
        let cov: [[f64; 2]; 3] = std::array::from_fn(|c| {
            let mean = self.color[c] / n;
            [self.cross[c][0] - mean * self.position[0], self.cross[c][1] - mean * self.position[1]]
        });
        // M = CᵀC (2 × 2).
        let m = [
            cov.iter().map(|r| r[0] * r[0]).sum::<f64>(),
            cov.iter().map(|r| r[0] * r[1]).sum::<f64>(),
            cov.iter().map(|r| r[1] * r[1]).sum::<f64>(),
        ];
        // det(M − λS) = det S·λ² − (m₀s₂ + m₂s₀ − 2m₁s₁)·λ + det M = 0; the larger root.
        let b = m[0] * s[2] + m[2] * s[0] - 2.0 * m[1] * s[1];
        let det_m = m[0] * m[2] - m[1] * m[1];
        let discriminant = (b * b - 4.0 * det_s * det_m).max(0.0);
        let reduction = (b + discriminant.sqrt()) / (2.0 * det_s);
        if !(reduction > 0.0) {
            return None;
        }
        // (M − λS)v = 0: v is orthogonal to either row; take the longer candidate.
        let rows = [
            [m[0] - reduction * s[0], m[1] - reduction * s[1]],
            [m[1] - reduction * s[1], m[2] - reduction * s[2]],
        ];
        let candidates = rows.map(|[a, b]| [-b, a]);
        let norm = |v: [f64; 2]| (v[0] * v[0] + v[1] * v[1]).sqrt();
        let v = if norm(candidates[0]) >= norm(candidates[1]) { candidates[0] } else { candidates[1] };
        let length = norm(v);
        if !(length > 0.0) {
            return None;
        }
        let direction = v.map(|x| x / length);
        let spread = direction[0] * direction[0] * s[0]
            + 2.0 * direction[0] * direction[1] * s[1]
            + direction[1] * direction[1] * s[2];
        let slope = std::array::from_fn(|c| (cov[c][0] * direction[0] + cov[c][1] * direction[1]) / spread);
        Some(LinearFit {
            centroid,
            direction,
            mean: self.color.map(|s| s / n),
            slope,
            reduction: reduction.min(self.flat_error()),
        })
    }
}

impl AddAssign for Moments {
    fn add_assign(&mut self, other: Self) {
        self.count += other.count;
        self.color_squares += other.color_squares;
        for i in 0..2 {
            self.position[i] += other.position[i];
        }
        for i in 0..3 {
            self.color[i] += other.color[i];
            self.position_squares[i] += other.position_squares[i];
            for j in 0..2 {
                self.cross[i][j] += other.cross[i][j];
            }
        }
    }
}

/// The least-squares colour field of a set of pixels that changes along one direction:
/// `mean + slope · along(p)`, with `along(p)` the signed distance of `p` from the centroid along
/// `direction`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinearFit {
    /// The pixels' mean position.
    pub centroid: [f64; 2],
    /// The unit direction the colour changes along.
    pub direction: [f64; 2],
    /// The mean colour (the field's colour at the centroid).
    pub mean: [f64; 3],
    /// Change of each channel per unit of distance along `direction`.
    pub slope: [f64; 3],
    /// How much less squared error (summed over pixels and channels) the field leaves than the
    /// mean colour does.
    pub reduction: f64,
}

impl LinearFit {
    /// Where `point` lies along the fit's direction, from the centroid.
    pub fn along(&self, point: [f32; 2]) -> f64 {
        (f64::from(point[0]) - self.centroid[0]) * self.direction[0]
            + (f64::from(point[1]) - self.centroid[1]) * self.direction[1]
    }

    /// The fitted colour at `along` ([`LinearFit::along`]), not clamped.
    pub fn color(&self, along: f64) -> [f64; 3] {
        std::array::from_fn(|c| self.mean[c] + self.slope[c] * along)
    }

    /// The ramp drawing the field from `low` to `high` along its direction (the extent of the
    /// pixels it fits, so none is padded), both ends pulled in to where a channel would leave
    /// [0, 1]: beyond that point the ramp is padded with the colour it reached, not tinted by
    /// clamping one channel alone. `None` when `low ≥ high` or the range leaves nothing in [0, 1].
    pub fn ramp(&self, low: f64, high: f64) -> Option<Ramp> {
        if !(low < high) {
            return None;
        }
        // Where each channel stays in [0, 1]: an interval of `along` (everything if flat).
        let (mut from, mut to) = (low, high);
        for c in 0..3 {
            let (mean, slope) = (self.mean[c], self.slope[c]);
            if slope == 0.0 {
                continue;
            }
            let (a, b) = ((0.0 - mean) / slope, (1.0 - mean) / slope);
            from = from.max(a.min(b));
            to = to.min(a.max(b));
        }
        if !(from < to) {
            return None;
        }
        let point = |t: f64| {
            [
                (self.centroid[0] + t * self.direction[0]) as f32,
                (self.centroid[1] + t * self.direction[1]) as f32,
            ]
        };
        let stop = |t: f64| self.color(t).map(|v| v.clamp(0.0, 1.0) as f32);
        Some(Ramp { start: point(from), end: point(to), stops: [stop(from), stop(to)] })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The squared error of `color` against `pixels`.
    fn error(pixels: &[([f32; 2], [f32; 3])], color: impl Fn([f32; 2]) -> [f32; 3]) -> f64 {
        pixels.iter().map(|&(p, c)| (0..3).map(|i| f64::from(color(p)[i] - c[i]).powi(2)).sum::<f64>()).sum()
    }

    fn moments(pixels: &[([f32; 2], [f32; 3])]) -> Moments {
        let mut moments = Moments::default();
        for &(p, c) in pixels {
            moments.add(p, c);
        }
        moments
    }

    /// A 20 × 12 block of pixels whose colour is a ramp along (cos θ, sin θ) plus a wobble
    /// across it.
    fn ramp_pixels(angle: f32, wobble: f32) -> Vec<([f32; 2], [f32; 3])> {
        let (sin, cos) = angle.sin_cos();
        let mut pixels = Vec::new();
        for y in 0..12 {
            for x in 0..20 {
                let p = [x as f32 + 0.5, y as f32 + 0.5];
                let t = (p[0] - 10.0) * cos + (p[1] - 6.0) * sin;
                let across = -(p[0] - 10.0) * sin + (p[1] - 6.0) * cos;
                let w = wobble * (across * 0.7).sin();
                pixels.push((p, [0.5 + 0.02 * t + w, 0.4 - 0.01 * t, 0.3 + 0.015 * t - w]));
            }
        }
        pixels
    }

    #[test]
    fn an_exact_ramp_is_found_whatever_its_direction() {
        for angle in [0.0f32, 0.4, 1.3, 2.5, -0.9] {
            let pixels = ramp_pixels(angle, 0.0);
            let fit = moments(&pixels).linear_fit().unwrap();
            let ramp = fit.ramp(-100.0, 100.0).unwrap();
            let left = error(&pixels, |p| ramp.color_at(p));
            assert!(left < 1e-8, "angle {angle}: {left} left over");
            let flat = moments(&pixels).flat_error();
            assert!((fit.reduction - flat).abs() < 1e-6 * flat, "{} of {flat}", fit.reduction);
        }
    }

    #[test]
    fn the_closed_form_beats_every_direction_tried_by_brute_force() {
        // With a wobble across the ramp no direction fits exactly; the closed form's error is
        // the least of a dense search over directions, each with its least-squares slope, and
        // its `reduction` says exactly what it leaves.
        let pixels = ramp_pixels(0.7, 0.05);
        let m = moments(&pixels);
        let fit = m.linear_fit().unwrap();
        let field = |p: [f32; 2]| fit.color(fit.along(p)).map(|v| v as f32);
        let closed = error(&pixels, field);
        assert!((closed - (m.flat_error() - fit.reduction)).abs() < 1e-4 * m.flat_error());
        let mean = m.mean_color();
        let best_searched = (0..3600)
            .map(|i| {
                let angle = i as f32 * std::f32::consts::PI / 3600.0;
                let v = [angle.cos(), angle.sin()];
                let t: Vec<f32> =
                    pixels.iter().map(|(p, _)| (p[0] - 10.0) * v[0] + (p[1] - 6.0) * v[1]).collect();
                let mean_t = t.iter().sum::<f32>() / t.len() as f32;
                let var: f32 = t.iter().map(|x| (x - mean_t).powi(2)).sum();
                let slope: [f32; 3] = std::array::from_fn(|c| {
                    t.iter().zip(&pixels).map(|(x, (_, col))| (x - mean_t) * (col[c] - mean[c])).sum::<f32>()
                        / var
                });
                pixels
                    .iter()
                    .zip(&t)
                    .map(|((_, col), x)| {
                        (0..3)
                            .map(|c| f64::from(mean[c] + slope[c] * (x - mean_t) - col[c]).powi(2))
                            .sum::<f64>()
                    })
                    .sum::<f64>()
            })
            .fold(f64::INFINITY, f64::min);
        assert!(closed <= best_searched * (1.0 + 1e-4), "{closed} against {best_searched}");
        assert!(closed < 0.5 * m.flat_error(), "the ramp explains most of it");
    }

    #[test]
    fn sums_add_and_degenerate_sets_have_no_ramp() {
        let pixels = ramp_pixels(0.3, 0.02);
        let (a, b) = pixels.split_at(100);
        let mut sum = moments(a);
        sum += moments(b);
        let whole = moments(&pixels);
        assert!((sum.flat_error() - whole.flat_error()).abs() < 1e-9);
        assert_eq!(sum.count(), whole.count());
        assert!((sum.linear_fit().unwrap().reduction - whole.linear_fit().unwrap().reduction).abs() < 1e-9);
        // A row of pixels, a flat block, nothing.
        let row: Vec<_> = (0..10).map(|x| ([x as f32, 3.0], [x as f32 / 10.0; 3])).collect();
        assert_eq!(moments(&row).linear_fit(), None);
        let flat: Vec<_> = (0..25).map(|i| ([(i % 5) as f32, (i / 5) as f32], [0.3; 3])).collect();
        assert_eq!(moments(&flat).linear_fit(), None);
        assert_eq!(Moments::default().linear_fit(), None);
    }

    #[test]
    fn a_ramp_stops_where_a_channel_would_leave_the_unit_range() {
        // Red climbs 0.1 a unit from 0.5: it reaches 1 at +5.
        let fit = LinearFit {
            centroid: [0.0, 0.0],
            direction: [1.0, 0.0],
            mean: [0.5, 0.5, 0.5],
            slope: [0.1, 0.0, -0.01],
            reduction: 1.0,
        };
        let ramp = fit.ramp(-3.0, 8.0).unwrap();
        assert_eq!((ramp.start, ramp.end), ([-3.0, 0.0], [5.0, 0.0]));
        assert!((ramp.stops[1][0] - 1.0).abs() < 1e-6 && (ramp.stops[0][0] - 0.2).abs() < 1e-6);
        assert_eq!(ramp.color_at([9.0, 4.0]), ramp.stops[1], "padded beyond the end");
        assert_eq!(fit.ramp(2.0, 2.0), None);
    }
}
