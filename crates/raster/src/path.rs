//! The path layout shared by every crate: one closed shape of four cubic Béziers with a fill.
//!
//! A path has 12 control points P0..P11; segment j runs through (P3j, P3j+1, P3j+2, P3((j+1) mod 4)),
//! so consecutive segments share end points and the last one closes back on P0. Coordinates are in
//! the unit square of the canvas (x = column, y = row), colours are RGB in [0, 1], and α in [0, 1] is
//! the path's opacity (the coarse model's visibility β ∈ {0, 1}).
//!
//! [`PathBatch`] holds a batch of such paths as one `[batch, paths, 28]` tensor (the layout the
//! models emit and the soft rasterizer consumes); [`Path`] is the same thing as plain numbers on the
//! CPU (what the exact renderer and the SVG writer take). Nothing outside this module indexes into
//! the 28 values.

use burn::tensor::{Device, Tensor, TensorData};

use crate::geometry::{cubic_point, straight_cubic};

/// Number of control points of a path.
pub const POINTS: usize = 12;
/// Number of cubic segments of a path.
pub const SEGMENTS: usize = 4;
/// Coordinates per path (12 points × 2).
pub const COORDS: usize = 2 * POINTS;
/// Parameters of a path without opacity: coordinates then RGB (what the refinement model emits).
pub const PARAMS_OPAQUE: usize = COORDS + 3;
/// Parameters of a path: coordinates, RGB, then α.
pub const PARAMS: usize = PARAMS_OPAQUE + 1;

/// The opacity above which a path is drawn at all: the coarse model's visibility β is a step
/// at 0.5 (its straight-through surrogate, `dpw::visibility`), so what it emits above it is a
/// path it means to draw.
pub const VISIBLE_ALPHA: f32 = 0.5;

const COLOR: std::ops::Range<usize> = COORDS..COORDS + 3;
const ALPHA: usize = PARAMS_OPAQUE;

/// One closed path on the CPU, coordinates in the canvas's unit square.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Path {
    /// Control points P0..P11 as (x, y), x = column and y = row, both in [0, 1] of the canvas.
    pub points: [[f32; 2]; POINTS],
    /// Fill colour, RGB in [0, 1].
    pub color: [f32; 3],
    /// Opacity in [0, 1]; 0 means the path is invisible.
    pub alpha: f32,
}

impl Path {
    /// A quadrilateral through `corners` (in order), each side a straight cubic: the shape tests
    /// and masks reach for when they need edges that are exactly where they say.
    pub fn quadrilateral(corners: [[f32; 2]; SEGMENTS], color: [f32; 3], alpha: f32) -> Self {
        let mut points = [[0.0; 2]; POINTS];
        for (j, a) in corners.into_iter().enumerate() {
            let straight = straight_cubic(a, corners[(j + 1) % SEGMENTS]);
            points[3 * j..3 * j + 3].copy_from_slice(&straight[..3]);
        }
        Self { points, color, alpha }
    }

    /// Whether the path is one its model means to draw ([`VISIBLE_ALPHA`]).
    pub fn is_visible(&self) -> bool {
        self.alpha > VISIBLE_ALPHA
    }

    /// The control points of segment `j` (0..4): start, two handles, end.
    pub fn segment(&self, j: usize) -> [[f32; 2]; 4] {
        let p = |i: usize| self.points[i % POINTS];
        [p(3 * j), p(3 * j + 1), p(3 * j + 2), p(3 * j + 3)]
    }

    /// The same path with every control point mapped through `f`.
    pub fn map_points(mut self, f: impl Fn([f32; 2]) -> [f32; 2]) -> Self {
        for point in &mut self.points {
            *point = f(*point);
        }
        self
    }

    /// The path as its 28 parameters, in [`PathBatch`]'s layout: coordinates (x, y per point),
    /// RGB, α. Optimizers that work on plain numbers (and gradients) use this layout.
    pub fn to_params(self) -> [f32; PARAMS] {
        let mut params = [0.0; PARAMS];
        for (i, [x, y]) in self.points.into_iter().enumerate() {
            params[2 * i] = x;
            params[2 * i + 1] = y;
        }
        params[COLOR].copy_from_slice(&self.color);
        params[ALPHA] = self.alpha;
        params
    }

    /// The path of 28 parameters in [`Self::to_params`]'s layout.
    pub fn from_params(params: &[f32; PARAMS]) -> Self {
        let mut points = [[0.0; 2]; POINTS];
        for (i, point) in points.iter_mut().enumerate() {
            *point = [params[2 * i], params[2 * i + 1]];
        }
        let mut color = [0.0; 3];
        color.copy_from_slice(&params[COLOR]);
        Path { points, color, alpha: params[ALPHA] }
    }
}

/// A batch of paths as a `[batch, paths, 28]` tensor: 24 coordinates, RGB, α per path.
///
/// Paths are painted in order (painter's order: a later path covers an earlier one).
#[derive(Clone, Debug)]
pub struct PathBatch {
    params: Tensor<3>,
}

impl PathBatch {
    /// Wraps a `[batch, paths, 28]` tensor laid out as described in the module documentation.
    ///
    /// # Panics
    /// If the last dimension is not 28.
    pub fn new(params: Tensor<3>) -> Self {
        let [_, _, width] = params.dims();
        assert_eq!(width, PARAMS, "a path batch has {PARAMS} parameters per path, got {width}");
        Self { params }
    }

    /// Builds a batch from its parts: points `[B, P, 12, 2]`, colours `[B, P, 3]`, α `[B, P, 1]`.
    pub fn from_parts(points: Tensor<4>, colors: Tensor<3>, alpha: Tensor<3>) -> Self {
        let [batch, paths, _, _] = points.dims();
        let coords = points.reshape([batch, paths, COORDS]);
        Self::new(Tensor::cat(vec![coords, colors, alpha], 2))
    }

    /// Builds an opaque batch (α = 1) from `[B, P, 27]` coordinates and colours.
    pub fn opaque(params: Tensor<3>) -> Self {
        let [batch, paths, width] = params.dims();
        assert_eq!(width, PARAMS_OPAQUE, "an opaque path batch has {PARAMS_OPAQUE} parameters");
        let alpha = Tensor::ones([batch, paths, 1], &params.device());
        Self::new(Tensor::cat(vec![params, alpha], 2))
    }

    /// Uploads CPU paths, one scene per batch entry; every scene must hold the same number of
    /// paths (pad with α = 0 paths otherwise).
    ///
    /// # Panics
    /// If the scenes have different lengths.
    pub fn from_scenes(scenes: &[Vec<Path>], device: &Device) -> Self {
        let paths = scenes.first().map_or(0, Vec::len);
        assert!(
            scenes.iter().all(|scene| scene.len() == paths),
            "every scene of a batch needs the same number of paths"
        );
        let values: Vec<f32> = scenes.iter().flatten().flat_map(|path| path.to_params()).collect();
        let data = TensorData::new(values, [scenes.len(), paths, PARAMS]);
        Self::new(Tensor::from_data(data, device))
    }

    /// Downloads the batch as CPU paths, one scene per batch entry.
    pub fn to_scenes(&self) -> Vec<Vec<Path>> {
        let [batch, paths, _] = self.params.dims();
        let values = self.params.try_to_vec_as::<f32>().expect("path parameters are readable");
        values
            .chunks_exact(PARAMS)
            .map(|params| Path::from_params(params.try_into().expect("chunks of PARAMS values")))
            .collect::<Vec<_>>()
            .chunks(paths.max(1))
            .take(batch)
            .map(<[Path]>::to_vec)
            .collect()
    }

    /// The underlying `[batch, paths, 28]` tensor.
    pub fn params(&self) -> &Tensor<3> {
        &self.params
    }

    /// Consumes the batch, returning the `[batch, paths, 28]` tensor.
    pub fn into_params(self) -> Tensor<3> {
        self.params
    }

    /// `[batch, paths]`.
    pub fn dims(&self) -> [usize; 2] {
        let [batch, paths, _] = self.params.dims();
        [batch, paths]
    }

    /// The device the parameters live on.
    pub fn device(&self) -> Device {
        self.params.device()
    }

    /// Control points `[B, P, 12, 2]` in the unit square.
    pub fn points(&self) -> Tensor<4> {
        let [batch, paths] = self.dims();
        self.params.clone().narrow(2, 0, COORDS).reshape([batch, paths, POINTS, 2])
    }

    /// Fill colours `[B, P, 3]`.
    pub fn colors(&self) -> Tensor<3> {
        self.params.clone().narrow(2, COLOR.start, 3)
    }

    /// Opacities `[B, P, 1]`.
    pub fn alpha(&self) -> Tensor<3> {
        self.params.clone().narrow(2, ALPHA, 1)
    }

    /// Coordinates and colours `[B, P, 27]`: the parameters that describe what a visible path
    /// looks like (what path-to-path distances compare).
    pub fn shape_and_color(&self) -> Tensor<3> {
        self.params.clone().narrow(2, 0, PARAMS_OPAQUE)
    }

    /// The same paths with every colour replaced by `colors` (`[B, P, 3]`, broadcastable).
    pub fn with_colors(&self, colors: Tensor<3>) -> Self {
        let [batch, paths] = self.dims();
        let colors = colors.expand([batch, paths, 3]);
        Self::from_parts(self.points(), colors, self.alpha())
    }

    /// The same paths with every opacity replaced by `alpha` (`[B, P, 1]`, broadcastable).
    pub fn with_alpha(&self, alpha: Tensor<3>) -> Self {
        let [batch, paths] = self.dims();
        let alpha = alpha.expand([batch, paths, 1]);
        Self::new(Tensor::cat(vec![self.shape_and_color(), alpha], 2))
    }

    /// Paths `start..start + len` of every batch entry.
    pub fn narrow(&self, start: usize, len: usize) -> Self {
        Self::new(self.params.clone().narrow(1, start, len))
    }

    /// Paints `later` over `self`: concatenates along the path dimension.
    pub fn then(&self, later: &PathBatch) -> Self {
        Self::new(Tensor::cat(vec![self.params.clone(), later.params.clone()], 1))
    }

    /// The same parameters cut from the autodiff graph.
    pub fn detach(&self) -> Self {
        Self::new(self.params.clone().detach())
    }
}

impl Path {
    /// The polygon of `steps` points per cubic (start of the cubic included, end left to the
    /// next one), `4 · steps` points in order: the path as straight edges.
    pub fn flatten(&self, steps: usize) -> Vec<[f32; 2]> {
        let steps = steps.max(1);
        let mut points = Vec::with_capacity(SEGMENTS * steps);
        for j in 0..SEGMENTS {
            let control = self.segment(j);
            points.extend((0..steps).map(|i| cubic_point(&control, i as f32 / steps as f32)));
        }
        points
    }

    /// The area the path encloses in the canvas's unit square ([`common::signed_area`] of its
    /// outline flattened to 16 edges per cubic).
    pub fn signed_area(&self) -> f32 {
        common::signed_area(&self.flatten(16))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample_path(seed: f32) -> Path {
        let mut points = [[0.0; 2]; POINTS];
        for (i, point) in points.iter_mut().enumerate() {
            *point = [seed + i as f32 * 0.01, seed - i as f32 * 0.02];
        }
        Path { points, color: [0.1, 0.2, seed], alpha: 0.5 }
    }

    #[test]
    fn scenes_round_trip_and_accessors_agree() {
        let device = Device::flex();
        let scenes = vec![vec![sample_path(0.3), sample_path(0.4)], vec![sample_path(0.5), sample_path(0.6)]];
        let batch = PathBatch::from_scenes(&scenes, &device);
        assert_eq!(batch.dims(), [2, 2]);
        assert_eq!(batch.to_scenes(), scenes);

        let points = batch.points().try_to_vec_as::<f32>().unwrap();
        assert_eq!(points[2..4], [0.31, 0.28]); // batch 0, path 0, P1
        let colors = batch.colors().try_to_vec_as::<f32>().unwrap();
        assert_eq!(colors[9..12], [0.1, 0.2, 0.6]); // batch 1, path 1
        let alpha = batch.alpha().try_to_vec_as::<f32>().unwrap();
        assert_eq!(alpha, [0.5; 4]);
    }

    #[test]
    fn parts_round_trip() {
        let device = Device::flex();
        let batch = PathBatch::from_scenes(&[vec![sample_path(0.2)]], &device);
        let rebuilt = PathBatch::from_parts(batch.points(), batch.colors(), batch.alpha());
        assert_eq!(rebuilt.to_scenes(), batch.to_scenes());
        let opaque = PathBatch::opaque(batch.shape_and_color());
        assert_eq!(opaque.to_scenes()[0][0].alpha, 1.0);
        let white = batch.with_colors(Tensor::ones([1, 1, 3], &device));
        assert_eq!(white.to_scenes()[0][0].color, [1.0; 3]);
        assert_eq!(white.to_scenes()[0][0].points, batch.to_scenes()[0][0].points);
    }

    #[test]
    fn segments_close_the_loop() {
        let path = sample_path(0.0);
        assert_eq!(path.segment(0)[0], path.points[0]);
        assert_eq!(path.segment(0)[3], path.points[3]);
        assert_eq!(path.segment(3)[3], path.points[0]);
    }
}
