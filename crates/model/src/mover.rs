//! The mover (E_m): the network that does SuperSVG-F's work in one pass. It moves every point of
//! every drawn outline along the outline's normal, to where the image puts the edge, reading
//! only the point's [`profile`]: the target's and the canvas's colours across the edge.
//!
//! The outlines it moves are what SuperSVG-B drew (regions traced along their shared
//! boundaries, E_c's and E_r's paths). It is trained to predict, point by point, the move the
//! exact optimizer finds for the point's outline with the rest of the drawing held
//! (`train-mover`): the best one batched pass can do.

use burn::module::Module;
use burn::nn::{Linear, LinearConfig, Relu};
use burn::tensor::{Device, Tensor, TensorData};
use image::Rgb32FImage;
use raster::{Outline, Segment};

/// Where a point's profile is read along its normal, in pixels of the working image.
pub const PROFILE_OFFSETS: [f32; 17] =
    [-4.0, -3.5, -3.0, -2.5, -2.0, -1.5, -1.0, -0.5, 0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0];
/// Values in a point's profile: the target's and the canvas's RGB at each offset.
pub const PROFILE_LEN: usize = 6 * PROFILE_OFFSETS.len();
/// Units of each of the mover's two hidden layers.
pub const MOVER_HIDDEN: usize = 32;
/// The farthest the mover moves a point, in pixels: the reach of its profile.
pub const MAX_MOVE: f32 = 4.0;

/// Two hidden ReLU layers over a point's profile, and the move along its normal in pixels.
#[derive(Module, Debug)]
pub struct Mover {
    first: Linear,
    second: Linear,
    out: Linear,
    relu: Relu,
}

impl Mover {
    /// A mover with burn's initial weights.
    pub fn new(device: &Device) -> Self {
        Self {
            first: LinearConfig::new(PROFILE_LEN, MOVER_HIDDEN).init(device),
            second: LinearConfig::new(MOVER_HIDDEN, MOVER_HIDDEN).init(device),
            out: LinearConfig::new(MOVER_HIDDEN, 1).init(device),
            relu: Relu::new(),
        }
    }

    /// Its two hidden layers, which read a profile: what the learned optimizer starts from.
    pub fn profile_layers(&self) -> (Linear, Linear) {
        (self.first.clone(), self.second.clone())
    }

    /// `[N, PROFILE_LEN]` profiles to `[N]` moves in pixels, unbounded: what training regresses.
    pub fn forward(&self, profiles: Tensor<2>) -> Tensor<1> {
        let hidden = self.relu.forward(self.first.forward(profiles));
        let hidden = self.relu.forward(self.second.forward(hidden));
        self.out.forward(hidden).flatten(0, 1)
    }

    /// The moves of `profiles` (row-major, [`PROFILE_LEN`] values a point) in pixels, each
    /// within [`MAX_MOVE`]: what inference applies.
    ///
    /// # Panics
    /// If `profiles` is not a whole number of profiles.
    pub fn moves(&self, profiles: Vec<f32>, device: &Device) -> Vec<f32> {
        assert!(profiles.len().is_multiple_of(PROFILE_LEN), "whole profiles, {PROFILE_LEN} values each");
        let rows = profiles.len() / PROFILE_LEN;
        if rows == 0 {
            return Vec::new();
        }
        let input = Tensor::from_data(TensorData::new(profiles, [rows, PROFILE_LEN]), device);
        let moves = self.forward(input).clamp(-MAX_MOVE, MAX_MOVE);
        moves.into_data().try_into_vec().expect("moves are f32")
    }
}

/// A point of an outline as the mover sees it: where it is (pixels of the working image) and
/// the outline's unit normal there, zero where the point's neighbours coincide (it is not moved).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// The point, in pixels.
    pub at: [f32; 2],
    /// The unit normal, or zero.
    pub normal: [f32; 2],
}

impl Frame {
    /// The point moved `distance` pixels along the normal, in the unit square of a `width ×
    /// height` canvas.
    pub fn moved(&self, distance: f32, (width, height): (u32, u32)) -> [f32; 2] {
        let (w, h) = (width as f32, height as f32);
        [(self.at[0] + distance * self.normal[0]) / w, (self.at[1] + distance * self.normal[1]) / h]
    }
}

/// The frame of each point of `outline` ([`Outline::points`]' order) on a `width × height`
/// canvas: the normal is that of the chord between the point's neighbours on its contour.
pub fn frames(outline: &Outline, (width, height): (u32, u32)) -> Vec<Frame> {
    let (w, h) = (width as f32, height as f32);
    let points: Vec<[f32; 2]> = outline.points().iter().map(|p| [p[0] * w, p[1] * h]).collect();
    neighbours(outline)
        .into_iter()
        .zip(&points)
        .map(|((prev, next), &point)| {
            let (prev, next) = (points[prev], points[next]);
            let (tx, ty) = (next[0] - prev[0], next[1] - prev[1]);
            let length = tx.hypot(ty);
            let normal = if length > 1e-6 { [-ty / length, tx / length] } else { [0.0; 2] };
            Frame { at: point, normal }
        })
        .collect()
}

/// The points before and after each point of `outline` on its contour ([`Outline::points`]'
/// indices and order).
pub fn neighbours(outline: &Outline) -> Vec<(usize, usize)> {
    let mut around = Vec::new();
    let mut at = 0;
    for contour in outline.contours() {
        let count: usize = (contour.segments.iter())
            .map(|segment| match segment {
                Segment::Line(_) => 1,
                Segment::Cubic(..) => 3,
            })
            .sum();
        around.extend((0..count).map(|j| (at + (j + count - 1) % count, at + (j + 1) % count)));
        at += count;
    }
    around
}

/// What the mover reads at `frame`: the target's and the canvas's RGB at each of
/// [`PROFILE_OFFSETS`] along the normal, less the canvas's colour at the point (so that the
/// same edge reads the same in any colour). Both images are sampled bilinearly between pixel
/// centres, clamped at the edges.
///
/// # Panics
/// If the images differ in size.
pub fn profile(target: &Rgb32FImage, canvas: &Rgb32FImage, frame: &Frame) -> [f32; PROFILE_LEN] {
    assert_eq!(target.dimensions(), canvas.dimensions(), "target and canvas sizes");
    let ([px, py], [nx, ny]) = (frame.at, frame.normal);
    let (target, canvas, width) = (target.as_raw(), canvas.as_raw(), target.width());
    let size = (width, target.len() as u32 / 3 / width.max(1));
    let centre = Bilinear::at(px, py, size).read(canvas);
    let mut values = [0.0; PROFILE_LEN];
    for (k, s) in PROFILE_OFFSETS.iter().enumerate() {
        let at = Bilinear::at(px + s * nx, py + s * ny, size);
        let (t, c) = (at.read(target), at.read(canvas));
        for ch in 0..3 {
            values[6 * k + ch] = t[ch] - centre[ch];
            values[6 * k + 3 + ch] = c[ch] - centre[ch];
        }
    }
    values
}

/// Where a bilinear sample of an image at pixel position (x, y) reads: its four pixels (as
/// offsets into interleaved RGB) and how far between them, found once for images of one size.
struct Bilinear {
    corners: [usize; 4],
    fx: f32,
    fy: f32,
}

impl Bilinear {
    /// The sample at (x, y) of a `width × height` image, between pixel centres, clamped at
    /// the edges.
    fn at(x: f32, y: f32, (width, height): (u32, u32)) -> Self {
        let (u, v) = ((x - 0.5).clamp(0.0, width as f32 - 1.0), (y - 0.5).clamp(0.0, height as f32 - 1.0));
        let (x0, y0) = (u.floor() as usize, v.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(width as usize - 1), (y0 + 1).min(height as usize - 1));
        let (fx, fy) = (u - x0 as f32, v - y0 as f32);
        let at = |x: usize, y: usize| 3 * (y * width as usize + x);
        Self { corners: [at(x0, y0), at(x1, y0), at(x0, y1), at(x1, y1)], fx, fy }
    }

    /// The sample of `rgb` (interleaved, the size it was found for).
    fn read(&self, rgb: &[f32]) -> [f32; 3] {
        let ([a, b, c, d], (fx, fy)) = (self.corners, (self.fx, self.fy));
        std::array::from_fn(|k| {
            (rgb[a + k] * (1.0 - fx) + rgb[b + k] * fx) * (1.0 - fy)
                + (rgb[c + k] * (1.0 - fx) + rgb[d + k] * fx) * fy
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Rgb;

    /// A square's points get outward or inward normals of unit length, all the same way round,
    /// and a frame moves its point along its normal.
    #[test]
    fn a_square_has_unit_normals_one_way_round() {
        let square =
            Outline::polygon(&[[0.25, 0.25], [0.75, 0.25], [0.75, 0.75], [0.25, 0.75]], [0.5; 3], 1.0)
                .unwrap();
        let frames = frames(&square, (8, 8));
        assert_eq!(frames.len(), 4);
        let centre = [4.0, 4.0];
        let sides: Vec<f32> = (frames.iter())
            .map(|f| {
                assert!((f.normal[0].hypot(f.normal[1]) - 1.0).abs() < 1e-6, "{f:?}");
                (f.at[0] - centre[0]) * f.normal[0] + (f.at[1] - centre[1]) * f.normal[1]
            })
            .collect();
        assert!(sides.iter().all(|s| *s > 0.0) || sides.iter().all(|s| *s < 0.0), "{sides:?}");
        let moved = frames[0].moved(1.0, (8, 8));
        assert_eq!(moved, [(2.0 + frames[0].normal[0]) / 8.0, (2.0 + frames[0].normal[1]) / 8.0]);
    }

    /// The profile across a vertical edge reads the target's step where the target has it, and
    /// nothing where the canvas already draws the target.
    #[test]
    fn a_profile_reads_the_edge_against_the_canvas() {
        let edge = Rgb32FImage::from_fn(16, 16, |x, _| if x < 10 { Rgb([0.0; 3]) } else { Rgb([1.0; 3]) });
        let frame = Frame { at: [8.0, 8.0], normal: [1.0, 0.0] };
        let flat = Rgb32FImage::from_pixel(16, 16, Rgb([0.0; 3]));
        let values = profile(&edge, &flat, &frame);
        let target_at = |k: usize| values[6 * k];
        // Offsets −4..1.5 px land left of x = 10 (pixel centres 4.5..9.5 hold 0), 2.5.. right.
        assert_eq!(target_at(0), 0.0);
        assert_eq!(target_at(PROFILE_OFFSETS.len() - 1), 1.0);
        assert!(values.iter().skip(3).step_by(6).all(|&c| c == 0.0), "the canvas is flat");
        let same = profile(&edge, &edge, &frame);
        assert!((0..PROFILE_OFFSETS.len()).all(|k| same[6 * k] == same[6 * k + 3]));
    }

    /// Moves stay within the reach, whatever the weights say, one per profile.
    #[test]
    fn moves_are_one_per_point_within_reach() {
        let device = Device::flex();
        let mover = Mover::new(&device);
        let profiles: Vec<f32> = (0..3 * PROFILE_LEN).map(|i| (i as f32 * 0.37).sin() * 1000.0).collect();
        let moves = mover.moves(profiles, &device);
        assert_eq!(moves.len(), 3);
        assert!(moves.iter().all(|m| m.abs() <= MAX_MOVE), "{moves:?}");
        assert!(mover.moves(Vec::new(), &device).is_empty());
    }
}
