//! The exact rendering of paths over a fixed canvas, with the gradient of its L2 error, on the
//! CPU: what fine-tuning needs, for a cost that grows with the pixels each path covers and the
//! length of its outline, not with paths × pixels or the size of an autodiff graph.
//!
//! The forward pass is tiny-skia's anti-aliased coverage (the exact renderer's), composited in
//! painter's order. The gradient of the colour and opacity follows from the coverage; that of
//! the control points comes from the outline (edge sampling, as in DiffVG): moving a piece of
//! the outline of length `ds` outwards by `δ` adds `δ·ds` to the coverage of the pixel under it,
//! so `∂L/∂P = ∮ g(x) · B_P(t) · n(t) ds`, with `g` the loss's derivative by that pixel's
//! coverage, `B_P` the weight of control point `P` on the outline and `n` the outward normal.

use std::ops::Range;

use common::{PixelBox, Ramp};
use rayon::prelude::*;

use crate::exact::coverage_exact_window;
use crate::fill::{Fill, RAMP_PARAMS, ramp_params};
use crate::geometry::{bernstein, cubic_derivative, cubic_point};
use crate::path::{PARAMS, POINTS, Path};
use crate::shape::{Filled, Outline, Piece, PieceIndices};

/// Outline samples per pixel of a cubic's control polygon (an upper bound of its length): two,
/// so that every pixel the outline crosses is sampled.
const SAMPLES_PER_PIXEL: f32 = 2.0;

/// A `width × height` window of an image: the fixed canvas paths are painted over and the
/// target they are scored against, both planar RGB in [0, 1] (`[3][height][width]`).
#[derive(Clone, Debug)]
pub struct Window {
    width: u32,
    height: u32,
    canvas: Vec<f32>,
    target: Vec<f32>,
}

impl Window {
    /// The window, or `None` when it is empty or a buffer does not hold `3 × width × height`
    /// values.
    pub fn new(width: u32, height: u32, canvas: Vec<f32>, target: Vec<f32>) -> Option<Self> {
        let values = 3 * width as usize * height as usize;
        (values > 0 && canvas.len() == values && target.len() == values).then_some(Self {
            width,
            height,
            canvas,
            target,
        })
    }

    /// `paths` (coordinates in the window's unit square) painted exactly, in order, over the
    /// canvas: planar RGB like the canvas.
    pub fn render(&self, paths: &[Path]) -> Vec<f32> {
        self.forward(paths, &[], RGB)
    }

    /// [`Self::render`], and the union of the paths' coverages (`1 − Π(1 − coverageᵢ)`,
    /// `[height][width]`, invisible paths included, as the soft rasterizer's union): what a
    /// loss on where paths reach (outside a region's mask) reads.
    pub fn render_with_union(&self, paths: &[Path]) -> (Vec<f32>, Vec<f32>) {
        let mut render = self.forward(paths, &[], RGB.start..UNION.end);
        let union = render.split_off(3 * self.width as usize * self.height as usize);
        (render, union)
    }

    /// The mean squared error of [`Self::render`] against the target, over pixels and channels.
    pub fn l2(&self, paths: &[Path]) -> f64 {
        self.error_of(&self.render(paths))
    }

    /// The mean squared error of a render against the target.
    fn error_of(&self, render: &[f32]) -> f64 {
        let sum: f64 = render.iter().zip(&self.target).map(|(r, t)| f64::from((r - t) * (r - t))).sum();
        sum / render.len() as f64
    }

    /// The mean squared error of [`Self::render`] against the target (over pixels and
    /// channels) and its gradient by each path's parameters (in [`Path::to_params`]'s layout,
    /// coordinates in the window's unit square). Paths that cannot be drawn get a zero
    /// gradient. Each path costs the pixels of its own box, not of the window; bands of rows
    /// run in parallel.
    pub fn l2_gradient(&self, paths: &[Path]) -> (f64, Vec<[f32; PARAMS]>) {
        let (loss, gradients) = self.backward(paths, &[], RGB, &Seed::L2);
        (loss, gradients.iter().map(path_params).collect())
    }

    /// `outlines` (points in the window's unit square, ramps laid out there as the exact
    /// renderer lays out a [`crate::Fill::Linear`]) painted exactly, in order, over the canvas:
    /// planar RGB like the canvas.
    pub fn render_outlines(&self, outlines: &[Outline]) -> Vec<f32> {
        self.forward(outlines, &ramps_of(outlines), RGB)
    }

    /// The mean squared error of [`Self::render_outlines`] against the target.
    pub fn l2_outlines(&self, outlines: &[Outline]) -> f64 {
        self.error_of(&self.render_outlines(outlines))
    }

    /// [`Self::l2_outlines`] and its gradient by each outline's points ([`Outline::points`]'
    /// order), paint and opacity: [`Self::l2_gradient`] for shapes of any number of lines
    /// and cubics, such as the regions' traced outlines, moved where they are.
    pub fn l2_gradient_outlines(&self, outlines: &[Outline]) -> (f64, Vec<ShapeGradient>) {
        self.backward(outlines, &ramps_of(outlines), RGB, &Seed::L2)
    }

    /// `paths` with each colour replaced by the one that fits the target best (least squares)
    /// over what lies below the path: the canvas and the paths before it, in their fitted
    /// colours. The error of each pixel is weighed by `weights` (`[height][width]`; `None`: 1
    /// everywhere). A path that covers no weighted pixel keeps its colour.
    ///
    /// This is what inference does to every path E_r proposes (infer's `Scene::fit_colour`, one
    /// path at a time over the drawing so far), so a loss of the fitted paths scores shapes and
    /// opacities alone; with the colours at their optimum, its gradient by the other parameters
    /// is the fitted loss's (colours held fixed).
    ///
    /// # Panics
    /// If `weights` does not hold one value per pixel.
    pub fn fit_colours(&self, paths: &[Path], weights: Option<&[f32]>) -> Vec<Path> {
        let (width, pixels) = (self.width as usize, self.width as usize * self.height as usize);
        assert!(weights.is_none_or(|w| w.len() == pixels), "one weight per pixel");
        let mut below = self.canvas.clone();
        paths
            .iter()
            .zip(self.coverages(paths))
            .map(|(path, coverage)| {
                let Some(Coverage { bbox, values: covers }) = coverage else {
                    return *path;
                };
                let [x0, y0, x1, y1] = corners(&bbox);
                let alpha = f64::from(path.alpha.clamp(0.0, 1.0));
                // Each pixel of the box: its index in a plane, and the path's share of it.
                let cells = (y0..y1)
                    .flat_map(|y| (x0..x1).map(move |x| (y, x)))
                    .map(|(y, x)| (y * width + x, covers[(y - y0) * (x1 - x0) + x - x0]));
                // Painted: a·colour + (1 − a)·below, a = α·coverage; fit a·colour to target − (1 − a)·below.
                let (mut numerator, mut denominator) = ([0.0f64; 3], 0.0f64);
                for (index, cover) in cells.clone() {
                    let (a, weight) =
                        (alpha * f64::from(cover), weights.map_or(1.0, |w| f64::from(w[index])));
                    if a == 0.0 || weight == 0.0 {
                        continue;
                    }
                    for (c, n) in numerator.iter_mut().enumerate() {
                        let i = c * pixels + index;
                        *n += weight * a * (f64::from(self.target[i]) - (1.0 - a) * f64::from(below[i]));
                    }
                    denominator += weight * a * a;
                }
                let fitted = if denominator > 0.0 {
                    Path { color: numerator.map(|n| (n / denominator).clamp(0.0, 1.0) as f32), ..*path }
                } else {
                    *path
                };
                for (index, cover) in cells {
                    let a = alpha as f32 * cover;
                    for (c, color) in fitted.color.iter().enumerate() {
                        let value = &mut below[c * pixels + index];
                        *value += a * (color - *value);
                    }
                }
                fitted
            })
            .collect()
    }

    /// The gradient by each path's parameters (as [`Self::l2_gradient`]'s) of any loss of the
    /// render and of the union, given the loss's derivative by each value of
    /// [`Self::render_with_union`]'s two buffers (`None`: the loss does not read it). The
    /// window's target is not used.
    ///
    /// # Panics
    /// If a buffer does not hold one value per value of the render (`3 × width × height`) or
    /// of the union (`width × height`).
    pub fn gradient(
        &self,
        paths: &[Path],
        by_render: Option<&[f32]>,
        by_union: Option<&[f32]>,
    ) -> Vec<[f32; PARAMS]> {
        let pixels = self.width as usize * self.height as usize;
        assert!(by_render.is_none_or(|g| g.len() == 3 * pixels), "one derivative per render value");
        assert!(by_union.is_none_or(|g| g.len() == pixels), "one derivative per union value");
        let planes = match (by_render, by_union) {
            (Some(_), Some(_)) => RGB.start..UNION.end,
            (None, Some(_)) => UNION,
            (_, None) => RGB,
        };
        self.backward(paths, &[], planes, &Seed::Given { by_render, by_union })
            .1
            .iter()
            .map(path_params)
            .collect()
    }

    /// The planes `planes` of the render, one after the other.
    fn forward<S: Movable>(&self, paths: &[S], ramps: &[Option<Ramp>], planes: Range<usize>) -> Vec<f32> {
        let coverages = self.coverages(paths);
        let laid = self.lay_out(ramps);
        let bands: Vec<Band> = self
            .bands()
            .into_par_iter()
            .map(|rows| self.band(paths, &laid, &coverages, rows, planes.clone(), None))
            .collect();
        let pixels = self.width as usize * self.height as usize;
        let mut render = vec![0.0; planes.len() * pixels];
        let mut start = 0;
        for band in bands {
            let len = band.render.len() / planes.len();
            for k in 0..planes.len() {
                render[k * pixels + start..k * pixels + start + len]
                    .copy_from_slice(&band.render[k * len..(k + 1) * len]);
            }
            start += len;
        }
        render
    }

    /// The loss (for [`Seed::L2`]) and the gradient of the loss `seed` stands for, over the
    /// planes `planes`.
    fn backward<S: Movable>(
        &self,
        paths: &[S],
        ramps: &[Option<Ramp>],
        planes: Range<usize>,
        seed: &Seed,
    ) -> (f64, Vec<ShapeGradient>) {
        let coverages = self.coverages(paths);
        let laid = self.lay_out(ramps);
        self.bands()
            .into_par_iter()
            .map(|rows| self.band(paths, &laid, &coverages, rows, planes.clone(), Some(seed)))
            .map(|band| (band.loss, band.gradients))
            .reduce(
                || (0.0, paths.iter().map(ShapeGradient::zero).collect()),
                |(loss, mut gradients), (more, others)| {
                    for (sum, other) in gradients.iter_mut().zip(&others) {
                        sum.add(other);
                    }
                    (loss + more, gradients)
                },
            )
    }

    /// `ramps` laid out on the window's pixels, one entry per path that has one.
    fn lay_out(&self, ramps: &[Option<Ramp>]) -> Vec<Option<Laid>> {
        ramps.iter().map(|ramp| ramp.as_ref().map(|ramp| Laid::new(ramp, self.width, self.height))).collect()
    }

    /// Row ranges, one per worker thread.
    fn bands(&self) -> Vec<Range<usize>> {
        let height = self.height as usize;
        let step = height.div_ceil(rayon::current_num_threads().max(1)).max(1);
        (0..height).step_by(step).map(|start| start..(start + step).min(height)).collect()
    }

    /// Each drawable path's pixel box and anti-aliased coverage there.
    fn coverages<S: Movable>(&self, paths: &[S]) -> Vec<Option<Coverage>> {
        paths
            .par_iter()
            .map(|path| {
                let bbox = path.pixel_box(self.width, self.height)?;
                let size = (bbox.width(), bbox.height());
                let mask =
                    coverage_exact_window(path, (self.width, self.height), (bbox.x0(), bbox.y0()), size)?;
                let values = mask.data().iter().map(|&v| f32::from(v) / 255.0).collect();
                Some(Coverage { bbox, values })
            })
            .collect()
    }

    /// The rows `rows` of the planes `planes` of the render (RGB: the canvas, then each path in
    /// its colour; union: nothing, then each path in white) and, with a `seed`, their share of
    /// the loss and of the gradient.
    fn band<'a, S: Movable>(
        &'a self,
        paths: &[S],
        laid: &[Option<Laid>],
        coverages: &[Option<Coverage>],
        rows: Range<usize>,
        planes: Range<usize>,
        seed: Option<&Seed<'a>>,
    ) -> Band {
        let width = self.width as usize;
        let window_pixels = width * self.height as usize;
        let (pixels, offset) = (rows.len() * width, rows.start * width);
        // The band's rows of plane `c` of a planar window buffer.
        let plane = |buffer: &'a [f32], c: usize| -> &'a [f32] {
            let start = c * window_pixels + offset;
            &buffer[start..start + pixels]
        };
        let mut render: Vec<f32> = Vec::with_capacity(planes.len() * pixels);
        for c in planes.clone() {
            if c < RGB.end {
                render.extend_from_slice(plane(&self.canvas, c));
            } else {
                render.resize(render.len() + pixels, 0.0);
            }
        }
        // The value plane `c` of `path` paints, and with what opacity.
        let paint = |path: &S, c: usize| {
            if c < RGB.end {
                (path.color()[c].clamp(0.0, 1.0), path.alpha().clamp(0.0, 1.0))
            } else {
                (1.0, 1.0)
            }
        };
        let backward = seed.is_some();
        // The rows of each path's box inside the band, and the band's pixels under it there.
        let mut layers: Vec<Option<(Range<usize>, Vec<f32>)>> = Vec::with_capacity(paths.len());
        for (index, (path, coverage)) in paths.iter().zip(coverages).enumerate() {
            let ramp = laid.get(index).and_then(Option::as_ref);
            let Some(Coverage { bbox, values: covers }) = coverage else {
                layers.push(None);
                continue;
            };
            let [x0, y0, x1, y1] = corners(bbox);
            let (first, last) = (y0.max(rows.start), y1.min(rows.end));
            if first >= last {
                layers.push(None);
                continue;
            }
            let box_width = x1 - x0;
            let span = (last - first) * box_width;
            let mut below = if backward { vec![0.0; planes.len() * span] } else { Vec::new() };
            for y in first..last {
                let (at, local, covered) =
                    ((y - rows.start) * width + x0, (y - first) * box_width, (y - y0) * box_width);
                let covers = &covers[covered..covered + box_width];
                for (k, c) in planes.clone().enumerate() {
                    let (color, alpha) = paint(path, c);
                    let values = &mut render[k * pixels + at..k * pixels + at + box_width];
                    if backward {
                        below[k * span + local..k * span + local + box_width].copy_from_slice(values);
                    }
                    match ramp.filter(|_| c < RGB.end) {
                        None => {
                            for (value, &cover) in values.iter_mut().zip(covers) {
                                *value += alpha * cover * (color - *value);
                            }
                        }
                        Some(ramp) => {
                            for (x, (value, &cover)) in (x0..).zip(values.iter_mut().zip(covers)) {
                                let color = ramp.color(c, ramp.along(x, y));
                                *value += alpha * cover * (color - *value);
                            }
                        }
                    }
                }
            }
            layers.push(Some((first..last, below)));
        }
        let Some(seed) = seed else {
            return Band { render, loss: 0.0, gradients: Vec::new() };
        };
        let mut loss = 0.0f64;
        // ∂L/∂(render), carried down through the layers.
        let mut upstream = vec![0.0f32; render.len()];
        for (k, c) in planes.clone().enumerate() {
            let ups = &mut upstream[k * pixels..(k + 1) * pixels];
            match seed {
                Seed::L2 => {
                    let scale = 2.0 / (3 * window_pixels) as f32;
                    for ((up, r), t) in
                        ups.iter_mut().zip(&render[k * pixels..(k + 1) * pixels]).zip(plane(&self.target, c))
                    {
                        let difference = r - t;
                        loss += f64::from(difference * difference);
                        *up = scale * difference;
                    }
                }
                Seed::Given { by_render, by_union } => {
                    let given = if c < RGB.end {
                        by_render.map(|g| plane(g, c))
                    } else {
                        by_union.map(|g| plane(g, 0))
                    };
                    if let Some(given) = given {
                        ups.copy_from_slice(given);
                    }
                }
            }
        }
        loss /= (3 * window_pixels) as f64;
        let mut gradients: Vec<ShapeGradient> = paths.iter().map(ShapeGradient::zero).collect();
        for (index, (((path, layer), coverage), gradient)) in
            paths.iter().zip(&layers).zip(coverages).zip(gradients.iter_mut()).enumerate().rev()
        {
            let (Some((band_rows, below)), Some(drawn @ Coverage { bbox, values: covers })) =
                (layer, coverage)
            else {
                continue;
            };
            let [x0, y0, x1, _] = corners(bbox);
            let box_width = x1 - x0;
            let span = band_rows.len() * box_width;
            let (mut d_color, mut d_alpha) = ([0.0f32; 3], 0.0f32);
            let ramp = laid.get(index).and_then(Option::as_ref);
            let mut d_ramp = RampGradient::default();
            let mut by_coverage = vec![0.0f32; span];
            for y in band_rows.clone() {
                let (at, local) = ((y - rows.start) * width + x0, (y - band_rows.start) * box_width);
                let covered = (y - y0) * box_width;
                let covers = &covers[covered..covered + box_width];
                let by = &mut by_coverage[local..local + box_width];
                for (k, c) in planes.clone().enumerate() {
                    let (color, alpha) = paint(path, c);
                    let ups = &mut upstream[k * pixels + at..k * pixels + at + box_width];
                    let unders = &below[k * span + local..k * span + local + box_width];
                    let (mut sum_color, mut sum_alpha) = (0.0, 0.0);
                    match ramp.filter(|_| c < RGB.end) {
                        None => {
                            for (((up, &under), &cover), by) in
                                ups.iter_mut().zip(unders).zip(covers).zip(by.iter_mut())
                            {
                                let (u, difference) = (*up, color - under);
                                *by += u * alpha * difference;
                                sum_color += u * cover;
                                sum_alpha += u * cover * difference;
                                *up = u * (1.0 - alpha * cover);
                            }
                        }
                        Some(ramp) => {
                            for (x, (((up, &under), &cover), by)) in
                                (x0..).zip(ups.iter_mut().zip(unders).zip(covers).zip(by.iter_mut()))
                            {
                                let along = ramp.along(x, y);
                                let (u, difference) = (*up, ramp.color(c, along) - under);
                                *by += u * alpha * difference;
                                sum_alpha += u * cover * difference;
                                d_ramp.add(ramp, c, (x, y), along, alpha * u * cover);
                                *up = u * (1.0 - alpha * cover);
                            }
                        }
                    }
                    if c < RGB.end {
                        d_color[c] += alpha * sum_color;
                        d_alpha += sum_alpha;
                    }
                }
            }
            let cells = PixelBox::new(x0 as u32, band_rows.start as u32, x1 as u32, band_rows.end as u32)
                .expect("a band of the path's box");
            self.outline_gradient(path, drawn, cells, &by_coverage, &mut gradient.points);
            (gradient.color, gradient.alpha) = (d_color, d_alpha);
            if let Some(ramp) = ramp {
                gradient.ramp = d_ramp.params(ramp, self.width, self.height);
            }
        }
        Band { render, loss, gradients }
    }

    /// `∮ g · B_P · n ds` for every control point over the part of the outline inside the pixels
    /// `cells`, `g` per pixel of `cells` (row-major), in the window's unit square.
    ///
    /// Which side of a piece of outline is inside is read from the path's own coverage a pixel
    /// away on either side, not from the orientation of the whole outline: a tangled outline
    /// (the loops a network draws early in training) has pieces of both orientations, and
    /// pieces inside other lobes, where moving the outline changes nothing.
    fn outline_gradient<S: Movable>(
        &self,
        path: &S,
        coverage: &Coverage,
        cells: PixelBox,
        by_coverage: &[f32],
        gradient: &mut [[f32; 2]],
    ) {
        let (w, h) = (self.width as f32, self.height as f32);
        let [x0, y0, x1, y1] = corners(&cells).map(|v| v as f32);
        let cells_width = cells.width() as usize;
        for Piece { control, indices } in path.pieces() {
            let q = control.map(|[x, y]| [x * w, y * h]);
            let [left, top, right, bottom] = q
                .iter()
                .fold([f32::INFINITY, f32::INFINITY, -f32::INFINITY, -f32::INFINITY], |[l, t, r, b], p| {
                    [l.min(p[0]), t.min(p[1]), r.max(p[0]), b.max(p[1])]
                });
            if bottom < y0 || top >= y1 || right < x0 || left >= x1 {
                continue; // this cubic lies outside the cells
            }
            let samples = piece_samples(&q, (w, h));
            let dt = 1.0 / samples as f32;
            for m in 0..samples {
                let t = (m as f32 + 0.5) * dt;
                let [x, y] = cubic_point(&q, t);
                if !(x >= x0 && y >= y0 && x < x1 && y < y1) {
                    continue;
                }
                let g = by_coverage[(y - y0) as usize * cells_width + (x - x0) as usize];
                if g == 0.0 {
                    continue;
                }
                let tangent = cubic_derivative(&q, t);
                let length = tangent[0].hypot(tangent[1]);
                if length == 0.0 {
                    continue;
                }
                // n = (t_y, −t_x)·|x'(t)|: a normal times the length this sample stands for.
                // Moving the outline by δ along n gives the strip on its side the coverage of
                // the other side: Δcoverage = (behind − ahead)·δ·ds.
                let normal = [tangent[1] / length, -tangent[0] / length];
                let ahead = coverage.at(x + normal[0], y + normal[1]);
                let behind = coverage.at(x - normal[0], y - normal[1]);
                let jump = behind - ahead;
                if jump == 0.0 {
                    continue;
                }
                let push = [tangent[1] * jump * g * dt, -tangent[0] * jump * g * dt];
                let mut add = |index: usize, weight: f32| {
                    let point = &mut gradient[index];
                    point[0] += weight * push[0] * w;
                    point[1] += weight * push[1] * h;
                };
                match indices {
                    PieceIndices::Cubic(indices) => {
                        for (index, weight) in indices.into_iter().zip(bernstein(t)) {
                            add(index, weight);
                        }
                    }
                    PieceIndices::Line([start, end]) => {
                        add(start, 1.0 - t);
                        add(end, t);
                    }
                }
            }
        }
    }
}

/// A drawable path's pixel box in the window and its anti-aliased coverage there (in [0, 1],
/// row-major).
struct Coverage {
    bbox: PixelBox,
    values: Vec<f32>,
}

/// A box's corners `[x0, y0, x1, y1]` as indices into the window's buffers.
fn corners(bbox: &PixelBox) -> [usize; 4] {
    [bbox.x0(), bbox.y0(), bbox.x1(), bbox.y1()].map(|v| v as usize)
}

impl Coverage {
    /// The coverage of the pixel holding the point `(x, y)` (window pixels); 0 outside the box.
    fn at(&self, x: f32, y: f32) -> f32 {
        let [x0, y0, x1, y1] = corners(&self.bbox);
        let (px, py) = (x.floor(), y.floor());
        if !(px >= x0 as f32 && py >= y0 as f32 && px < x1 as f32 && py < y1 as f32) {
            return 0.0;
        }
        self.values[(py as usize - y0) * (x1 - x0) + (px as usize - x0)]
    }
}

/// The render's colour planes.
const RGB: Range<usize> = 0..3;
/// The plane of the union of the paths' coverages, after the colours.
const UNION: Range<usize> = 3..4;

/// Where a backward pass starts: the derivative of the loss by each value of the render.
enum Seed<'a> {
    /// The mean squared error against the window's target (RGB planes).
    L2,
    /// Derivatives computed elsewhere, planar like the render's buffers.
    Given {
        /// By each RGB value (`3 × height × width`), if the loss reads the colours.
        by_render: Option<&'a [f32]>,
        /// By each value of the union (`height × width`), if the loss reads it.
        by_union: Option<&'a [f32]>,
    },
}

/// What one band of rows contributes: its rows of the render (planar), and when asked, its
/// share of the loss and of each path's gradient.
struct Band {
    render: Vec<f32>,
    loss: f64,
    gradients: Vec<ShapeGradient>,
}

/// What the window draws and differentiates: a closed outline whose points are parameters.
trait Movable: Filled + Sync {
    /// Its pieces in order, with where their points lie among its points.
    fn pieces(&self) -> Vec<Piece>;
    /// How many points shape it.
    fn point_count(&self) -> usize;
}

impl Movable for Path {
    fn pieces(&self) -> Vec<Piece> {
        Path::pieces(self)
    }

    fn point_count(&self) -> usize {
        POINTS
    }
}

impl Movable for Outline {
    fn pieces(&self) -> Vec<Piece> {
        Outline::pieces(self)
    }

    fn point_count(&self) -> usize {
        Outline::point_count(self)
    }
}

/// The gradient of a loss by one shape's parameters, coordinates in the window's unit square.
#[derive(Clone, Debug, PartialEq)]
pub struct ShapeGradient {
    /// By each of its points ([`Outline::points`]' order; a path's 12 control points).
    pub points: Vec<[f32; 2]>,
    /// By its colour: zero for a ramp, which does not paint it.
    pub color: [f32; 3],
    /// By its opacity.
    pub alpha: f32,
    /// By its ramp's parameters ([`crate::ramp_params`]' layout); zero for a flat fill.
    pub ramp: [f32; RAMP_PARAMS],
}

impl ShapeGradient {
    /// No gradient for `shape`'s parameters.
    fn zero(shape: &impl Movable) -> Self {
        Self {
            points: vec![[0.0; 2]; shape.point_count()],
            color: [0.0; 3],
            alpha: 0.0,
            ramp: [0.0; RAMP_PARAMS],
        }
    }

    /// Adds `other` in, entry by entry.
    fn add(&mut self, other: &Self) {
        for (sum, value) in self.points.iter_mut().zip(&other.points) {
            sum[0] += value[0];
            sum[1] += value[1];
        }
        for (sum, value) in self.color.iter_mut().zip(&other.color) {
            *sum += value;
        }
        self.alpha += other.alpha;
        for (sum, value) in self.ramp.iter_mut().zip(&other.ramp) {
            *sum += value;
        }
    }
}

/// A path's gradient in [`Path::to_params`]' layout.
fn path_params(gradient: &ShapeGradient) -> [f32; PARAMS] {
    let mut points = [[0.0; 2]; POINTS];
    points.copy_from_slice(&gradient.points);
    Path { points, color: gradient.color, alpha: gradient.alpha }.to_params()
}

/// Each outline's ramp, where it is filled with one.
fn ramps_of(outlines: &[Outline]) -> Vec<Option<Ramp>> {
    outlines
        .iter()
        .map(|outline| match outline.fill {
            Fill::Linear(ramp) => Some(ramp),
            Fill::Solid(_) => None,
        })
        .collect()
}

/// A ramp laid out on a window's pixels (as the exact renderer draws it: the position of a
/// pixel's centre along the line from `start` to `end`, in pixels, clamped to the ends), stops
/// clamped to [0, 1].
struct Laid {
    start: [f32; 2],
    /// `end − start`.
    axis: [f32; 2],
    /// `1 / |axis|²`; 0 where the ends coincide (the last stop everywhere, as renderers paint).
    inverse: f32,
    stops: [[f32; 3]; 2],
}

impl Laid {
    fn new(ramp: &Ramp, width: u32, height: u32) -> Self {
        let (w, h) = (width as f32, height as f32);
        let start = [ramp.start[0] * w, ramp.start[1] * h];
        let axis = [ramp.end[0] * w - start[0], ramp.end[1] * h - start[1]];
        let length = axis[0] * axis[0] + axis[1] * axis[1];
        let inverse = if length > 0.0 && length.is_finite() { 1.0 / length } else { 0.0 };
        Self { start, axis, inverse, stops: ramp.stops.map(|stop| stop.map(|v| v.clamp(0.0, 1.0))) }
    }

    /// Where the centre of pixel `(x, y)` lies along the ramp, unclamped (1 where the ends
    /// coincide).
    fn along(&self, x: usize, y: usize) -> f32 {
        if self.inverse == 0.0 {
            return 1.0;
        }
        let [dx, dy] = [x as f32 + 0.5 - self.start[0], y as f32 + 0.5 - self.start[1]];
        (dx * self.axis[0] + dy * self.axis[1]) * self.inverse
    }

    /// Channel `c` of the colour at position `along`.
    fn color(&self, c: usize, along: f32) -> f32 {
        let t = along.clamp(0.0, 1.0);
        self.stops[0][c] + t * (self.stops[1][c] - self.stops[0][c])
    }
}

/// A ramp's gradient as it is summed over pixels: by its stops, and the sums its ends'
/// gradient follows from.
#[derive(Default)]
struct RampGradient {
    stops: [[f32; 3]; 2],
    /// Over pixels strictly inside the ramp, of `g` (the loss's derivative by the position along
    /// it): `Σg`, `Σg·x`, `Σg·y` (pixel centres) and `Σg·along`.
    along: [f32; 4],
}

impl RampGradient {
    /// Adds pixel `(x, y)`'s share of channel `c`: `by_color` is the loss's derivative by the
    /// colour the ramp paints there, which lies at `along` on it.
    fn add(&mut self, ramp: &Laid, c: usize, (x, y): (usize, usize), along: f32, by_color: f32) {
        let t = along.clamp(0.0, 1.0);
        self.stops[0][c] += by_color * (1.0 - t);
        self.stops[1][c] += by_color * t;
        if along > 0.0 && along < 1.0 {
            let g = by_color * (ramp.stops[1][c] - ramp.stops[0][c]);
            let sums = [g, g * (x as f32 + 0.5), g * (y as f32 + 0.5), g * along];
            for (sum, term) in self.along.iter_mut().zip(sums) {
                *sum += term;
            }
        }
    }

    /// In [`crate::ramp_params`]' layout, ends in the unit square of the window `ramp` was laid
    /// out on: with `along = (p − s)·a / a·a`, `a = e − s`, `∂along/∂e = ((p − s) − 2·along·a) /
    /// a·a` and `∂along/∂s = −∂along/∂e − a / a·a`.
    fn params(&self, ramp: &Laid, width: u32, height: u32) -> [f32; RAMP_PARAMS] {
        let [sum, sum_x, sum_y, sum_along] = self.along;
        let mut end = [0.0; 2];
        let mut start = [0.0; 2];
        for (k, sum_p) in [sum_x, sum_y].into_iter().enumerate() {
            end[k] = ramp.inverse * (sum_p - ramp.start[k] * sum - 2.0 * ramp.axis[k] * sum_along);
            start[k] = -end[k] - ramp.inverse * ramp.axis[k] * sum;
        }
        let scale = [width as f32, height as f32];
        let [start, end] = [start, end].map(|p| [p[0] * scale[0], p[1] * scale[1]]);
        ramp_params(&Ramp { start, end, stops: self.stops })
    }
}

/// How many samples the boundary term takes along the cubic `q` (pixel coordinates) in a window
/// `w` × `h`: [`SAMPLES_PER_PIXEL`] along its control polygon, which bounds its length, capped
/// at 3·(w + h), longer than any cubic inside the window, so that a wild handle far outside it
/// never makes the sampling unbounded.
fn piece_samples(q: &[[f32; 2]; 4], (w, h): (f32, f32)) -> usize {
    let span: f32 = (0..3).map(|k| (q[k + 1][0] - q[k][0]).hypot(q[k + 1][1] - q[k][1])).sum();
    (span.min(3.0 * (w + h)) * SAMPLES_PER_PIXEL).ceil().max(4.0) as usize
}

#[cfg(test)]
mod tests {
    use burn::tensor::{Device, Tensor, TensorData};
    use rand::{Rng, SeedableRng};

    use super::*;
    use crate::fill::{RAMP_COORDS, ramp_from_params};
    use crate::path::{COORDS, PathBatch};
    use crate::shape::Outline;
    use crate::shapes::{random_blob, random_scene};
    use crate::soft::{SoftRasterOptions, paint_soft};

    const WIDTH: u32 = 40;
    const HEIGHT: u32 = 30;

    /// A window whose canvas and target are two random scenes over grey.
    fn window(rng: &mut impl Rng) -> Window {
        let mut draw = |count| {
            let grey = vec![0.5; 3 * (WIDTH * HEIGHT) as usize];
            let window = Window::new(WIDTH, HEIGHT, grey.clone(), grey).unwrap();
            window.render(&random_scene(rng, count))
        };
        let (canvas, target) = (draw(3), draw(4));
        Window::new(WIDTH, HEIGHT, canvas, target).unwrap()
    }

    fn cosine(a: &[f32], b: &[f32]) -> f32 {
        let dot: f32 = a.iter().zip(b).map(|(x, y)| x * y).sum();
        let norm = |v: &[f32]| v.iter().map(|x| x * x).sum::<f32>().sqrt();
        dot / (norm(a) * norm(b))
    }

    #[test]
    fn window_checks_its_buffers() {
        assert!(Window::new(2, 2, vec![0.0; 12], vec![0.0; 12]).is_some());
        assert!(Window::new(2, 2, vec![0.0; 11], vec![0.0; 12]).is_none());
        assert!(Window::new(0, 2, vec![], vec![]).is_none());
    }

    /// Fitting recovers the colours a target was painted with (paths apart, so that each fit
    /// sees only its own path), leaves a path with no weighted pixel as it was, reads only the
    /// weighted pixels, and gives one path alone a colour no worse than a random one.
    #[test]
    fn fitted_colours_are_the_least_squares_ones() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(8);
        let grey = vec![0.5; 3 * (WIDTH * HEIGHT) as usize];
        let mut painted =
            vec![random_blob(&mut rng, [0.25, 0.5], 0.15), random_blob(&mut rng, [0.75, 0.5], 0.15)];
        painted[0].color = [0.9, 0.1, 0.3];
        painted[1].color = [0.2, 0.7, 0.0];
        painted[1].alpha = 0.6;
        let target = Window::new(WIDTH, HEIGHT, grey.clone(), grey.clone()).unwrap().render(&painted);
        let apart = Window::new(WIDTH, HEIGHT, grey, target).unwrap();
        let given: Vec<Path> = painted.iter().map(|path| Path { color: [0.5, 0.5, 0.0], ..*path }).collect();
        let fitted = apart.fit_colours(&given, None);
        for (fit, truth) in fitted.iter().zip(&painted) {
            for (f, t) in fit.color.iter().zip(truth.color) {
                assert!((f - t).abs() < 1e-3, "{:?} vs {:?}", fit.color, truth.color);
            }
            assert_eq!((fit.points, fit.alpha), (truth.points, truth.alpha));
        }
        assert!(apart.l2(&fitted) < 1e-6 && apart.l2(&given) > 1e-3);

        // Weighed only on the left half: the right path covers nothing that counts.
        let left: Vec<f32> =
            (0..HEIGHT).flat_map(|_| (0..WIDTH).map(|x| if x < WIDTH / 2 { 1.0 } else { 0.0 })).collect();
        let fitted = apart.fit_colours(&given, Some(&left));
        assert!((fitted[0].color[0] - 0.9).abs() < 1e-3);
        assert_eq!(fitted[1].color, given[1].color);

        // One path over a random drawing: its fitted colour is the best there is, so never
        // worse than a random one.
        for _ in 0..4 {
            let random = window(&mut rng);
            let scene = random_scene(&mut rng, 1);
            assert!(random.l2(&random.fit_colours(&scene, None)) <= random.l2(&scene) + 1e-9);
        }
    }

    /// Central differences of the loss, one parameter at a time, against the gradient: colours
    /// and opacity to rounding (the coverage does not move), control points in direction (the
    /// anti-aliased coverage is quantized, so shifts of half a pixel are compared; measured:
    /// cosine 0.94–0.99, norm ratio 0.78–1.0).
    #[test]
    fn gradient_matches_finite_differences() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for _ in 0..4 {
            let window = window(&mut rng);
            let mut path = random_blob(&mut rng, [0.5, 0.5], 0.3);
            path.color = [rng.random(), rng.random(), rng.random()];
            path.alpha = 0.8;
            let (_, gradient) = window.l2_gradient(&[path]);
            let base = path.to_params();
            let loss_at = |index: usize, delta: f32| {
                let mut params = base;
                params[index] += delta;
                window.l2_gradient(&[Path::from_params(&params)]).0 as f32
            };
            for index in COORDS..PARAMS {
                let numeric = (loss_at(index, 1e-3) - loss_at(index, -1e-3)) / 2e-3;
                let analytic = gradient[0][index];
                assert!(
                    (numeric - analytic).abs() < 1e-3 + 0.02 * analytic.abs(),
                    "{index}: {numeric} vs {analytic}"
                );
            }
            let (similarity, ratio) = points_against_differences(&window, path, &gradient[0]);
            assert!(similarity > 0.9, "cosine {similarity}");
            assert!((0.6..1.5).contains(&ratio), "norm ratio {ratio}");
        }
    }

    /// Cosine and norm ratio of the control points' gradient against central differences of
    /// the loss over half a pixel.
    fn points_against_differences(window: &Window, path: Path, gradient: &[f32; PARAMS]) -> (f32, f32) {
        let base = path.to_params();
        let loss_at = |index: usize, delta: f32| {
            let mut params = base;
            params[index] += delta;
            window.l2(&[Path::from_params(&params)]) as f32
        };
        let numeric: Vec<f32> = (0..COORDS)
            .map(|index| {
                let step = if index % 2 == 0 { 0.5 / WIDTH as f32 } else { 0.5 / HEIGHT as f32 };
                (loss_at(index, step) - loss_at(index, -step)) / (2.0 * step)
            })
            .collect();
        let norm = |v: &[f32]| v.iter().map(|g| g * g).sum::<f32>().sqrt();
        (cosine(&numeric, &gradient[..COORDS]), norm(&gradient[..COORDS]) / norm(&numeric))
    }

    /// A bow tie (an outline that crosses itself: two lobes of opposite orientation, its signed
    /// area near zero) moves the way the loss says: which side of each piece of outline is
    /// inside comes from the coverage, not from the orientation of the whole outline (which
    /// pushed one lobe the wrong way: training on it spread paths far outside their regions).
    #[test]
    fn tangled_outlines_get_the_right_gradient() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(31);
        for _ in 0..3 {
            let window = window(&mut rng);
            let corners = [[0.2, 0.25], [0.8, 0.75], [0.75, 0.2], [0.25, 0.8]];
            let path = Path::quadrilateral(corners, [rng.random(), rng.random(), rng.random()], 1.0);
            assert!(path.signed_area().abs() < 0.02, "{}", path.signed_area());
            let (_, gradient) = window.l2_gradient(&[path]);
            let (similarity, ratio) = points_against_differences(&window, path, &gradient[0]);
            assert!(similarity > 0.9, "cosine {similarity}");
            assert!((0.6..1.5).contains(&ratio), "norm ratio {ratio}");
        }
    }

    /// The same loss through the burn soft rasterizer and autodiff gives gradients of the same
    /// direction (the two rasterizers differ by their anti-aliasing only), for two paths where
    /// the second covers part of the first.
    #[test]
    fn gradient_agrees_with_the_soft_rasterizer() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let device = Device::flex().autodiff();
        let window = window(&mut rng);
        let paths = vec![random_blob(&mut rng, [0.4, 0.5], 0.3), random_blob(&mut rng, [0.6, 0.5], 0.25)];
        let (loss, gradient) = window.l2_gradient(&paths);
        let planar = |values: &[f32]| {
            Tensor::<4>::from_data(
                TensorData::new(values.to_vec(), [1, 3, HEIGHT as usize, WIDTH as usize]),
                &device,
            )
        };
        let params = PathBatch::from_scenes(&[paths], &device).into_params().require_grad();
        let render = paint_soft(
            planar(&window.canvas),
            &PathBatch::new(params.clone()),
            &SoftRasterOptions::default(),
        );
        let soft_loss = (render - planar(&window.target)).square().mean();
        assert!((soft_loss.clone().into_scalar::<f32>() as f64 - loss).abs() < 0.05 * loss);
        let soft: Vec<f32> = params.grad(&soft_loss.backward()).unwrap().try_to_vec_as().unwrap();
        let exact: Vec<f32> = gradient.iter().flatten().copied().collect();
        let similarity = cosine(&soft, &exact);
        assert!(similarity > 0.98, "cosine {similarity}");
    }

    /// What fine-tuning optimizes is what the exact renderer draws: the window's render of a
    /// scene (each path rasterized in its own box, bands of rows) against `render_exact` of
    /// the whole canvas. Only anti-aliased edge pixels may differ by a few levels (measured:
    /// 54 dB).
    #[test]
    fn render_matches_the_exact_renderer() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
        let (width, height) = (96, 64);
        let white = vec![1.0; 3 * width * height];
        let window = Window::new(width as u32, height as u32, white.clone(), white).unwrap();
        let scene = random_scene(&mut rng, 12);
        let psnr = psnr_against_exact(&window.render(&scene), &scene);
        assert!(psnr >= 35.0, "{psnr:.1} dB");

        // Every other path filled with a ramp, drawn by the exact renderer as the outline of
        // that path with that fill (measured: 54 dB, as with flat fills: the edges differ, not the ramps).
        let outlines: Vec<Outline> = (scene.iter().enumerate())
            .map(|(i, path)| match i % 2 {
                0 => Outline::from_path(path, random_ramp(&mut rng)).unwrap(),
                _ => Outline::from_path(path, path.color).unwrap(),
            })
            .collect();
        let ramped = window.render_outlines(&outlines);
        assert_ne!(ramped, window.render(&scene));
        let psnr = psnr_against_exact(&ramped, &outlines);
        assert!(psnr >= 35.0, "{psnr:.1} dB");
    }

    /// PSNR of a window's render (planar) against `render_exact` of `shapes` over white.
    fn psnr_against_exact<F: crate::shape::Filled>(ours: &[f32], shapes: &[F]) -> f64 {
        let (width, height) = (96, 64);
        let exact = crate::exact::render_exact(shapes, width as u32, height as u32, [1.0; 3]);
        let squared: f64 = exact
            .pixels()
            .enumerate()
            .flat_map(|(i, pixel)| (0..3).map(move |c| (i, c, pixel.0[c])))
            .map(|(i, c, value)| f64::from(ours[c * width * height + i] - f32::from(value) / 255.0).powi(2))
            .sum();
        common::psnr_of_mse(squared / (3 * width * height) as f64)
    }

    /// A ramp from the upper left to the lower right of the window's middle, random stops.
    fn random_ramp(rng: &mut impl Rng) -> Ramp {
        let mut point =
            |range: std::ops::Range<f32>| [rng.random_range(range.clone()), rng.random_range(range)];
        let (start, end) = (point(0.2..0.4), point(0.6..0.8));
        // Stops away from 0 and 1, where a difference would step over the clamp.
        let mut stop = || [(); 3].map(|_| rng.random_range(0.05..0.95));
        Ramp { start, end, stops: [stop(), stop()] }
    }

    /// Central differences of the loss by each of a ramp's parameters against its gradient:
    /// to rounding, since moving the stops or the ends changes colours, not coverage; a
    /// ramped path's colour gets no gradient, and its outline still moves.
    #[test]
    fn ramp_gradient_matches_finite_differences() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(41);
        for _ in 0..4 {
            let window = window(&mut rng);
            let mut path = random_blob(&mut rng, [0.5, 0.5], 0.3);
            path.alpha = 0.8;
            let ramp = random_ramp(&mut rng);
            let outline = Outline::from_path(&path, ramp).unwrap();
            let (_, gradient) = window.l2_gradient_outlines(std::slice::from_ref(&outline));
            assert_eq!(gradient[0].color, [0.0; 3]);
            assert!(gradient[0].points.iter().flatten().any(|g| *g != 0.0));
            let base = ramp_params(&ramp);
            let loss_at = |index: usize, delta: f32| {
                let mut params = base;
                params[index] += delta;
                let mut moved = outline.clone();
                moved.fill = ramp_from_params(&params).into();
                window.l2_outlines(&[moved]) as f32
            };
            let ramp_gradient = [gradient[0].ramp];
            for (index, &analytic) in ramp_gradient[0].iter().enumerate() {
                let numeric = (loss_at(index, 1e-3) - loss_at(index, -1e-3)) / 2e-3;
                assert!(
                    (numeric - analytic).abs() < 1e-4 + 0.02 * analytic.abs(),
                    "{index}: {numeric} vs {analytic}"
                );
            }
            assert!(ramp_gradient[0][..RAMP_COORDS].iter().any(|g| g.abs() > 1e-3), "{:?}", ramp_gradient[0]);
        }
    }

    /// A path and its outline ([`Outline::from_path`]) are the same shape: the same render, loss
    /// and gradient, point for point.
    #[test]
    fn outlines_of_paths_move_as_the_paths() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(43);
        let window = window(&mut rng);
        let scene = random_scene(&mut rng, 3);
        let outlines: Vec<Outline> = scene.iter().map(|p| Outline::from_path(p, p.color).unwrap()).collect();
        let ((loss, gradient), (outline_loss, outline_gradient)) =
            (window.l2_gradient(&scene), window.l2_gradient_outlines(&outlines));
        assert_eq!(loss, outline_loss);
        for (path, outline) in gradient.iter().zip(&outline_gradient) {
            assert_eq!(*path, path_params(outline));
        }
    }

    /// A polygon's corners move the way the loss says (central differences over half a pixel,
    /// as for paths), its colour and opacity to rounding; a polygon with a hole (a second
    /// contour the other way round) too.
    #[test]
    fn polygon_gradient_matches_finite_differences() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(47);
        for round in 0..4 {
            let window = window(&mut rng);
            let corners: Vec<[f32; 2]> = (0..7)
                .map(|i| {
                    let angle = i as f32 / 7.0 * std::f32::consts::TAU;
                    let radius = rng.random_range(0.25..0.4);
                    [0.5 + radius * angle.cos(), 0.5 + radius * angle.sin()]
                })
                .collect();
            let color = [rng.random(), rng.random(), rng.random()];
            let mut outline = Outline::polygon(&corners, color, 0.8).unwrap();
            if round % 2 == 1 {
                let hole = Outline::polygon(&[[0.45, 0.45], [0.45, 0.6], [0.6, 0.55]], color, 0.8).unwrap();
                let contours = [outline.contours(), hole.contours()].concat();
                outline = Outline::new(contours, color, 0.8).unwrap();
            }
            let (_, gradient) = window.l2_gradient_outlines(std::slice::from_ref(&outline));
            let base = outline.points();
            assert_eq!(gradient[0].points.len(), base.len());
            let loss_at = |index: usize, delta: f32| {
                let mut points = base.clone();
                points[index / 2][index % 2] += delta;
                window.l2_outlines(&[outline.with_points(&points)]) as f32
            };
            let numeric: Vec<f32> = (0..2 * base.len())
                .map(|index| {
                    let step = if index % 2 == 0 { 0.5 / WIDTH as f32 } else { 0.5 / HEIGHT as f32 };
                    (loss_at(index, step) - loss_at(index, -step)) / (2.0 * step)
                })
                .collect();
            let analytic: Vec<f32> = gradient[0].points.iter().flatten().copied().collect();
            let norm = |v: &[f32]| v.iter().map(|g| g * g).sum::<f32>().sqrt();
            let (similarity, ratio) = (cosine(&numeric, &analytic), norm(&analytic) / norm(&numeric));
            assert!(similarity > 0.9, "cosine {similarity}");
            assert!((0.6..1.5).contains(&ratio), "norm ratio {ratio}");
            let recolored = |c: usize, delta: f32| {
                let mut color = color;
                color[c] += delta;
                let mut recolored = outline.clone();
                recolored.fill = color.into();
                window.l2_outlines(&[recolored]) as f32
            };
            for c in 0..3 {
                let numeric = (recolored(c, 1e-3) - recolored(c, -1e-3)) / 2e-3;
                let analytic = gradient[0].color[c];
                assert!((numeric - analytic).abs() < 1e-3 + 0.02 * analytic.abs(), "{numeric} vs {analytic}");
            }
        }
    }

    /// An invisible path draws nothing and moves nothing, but its opacity has a gradient (a
    /// straight-through visibility must be able to turn it back on); a path with a non-finite
    /// point gets no gradient at all.
    #[test]
    fn hidden_and_undrawable_paths() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let window = window(&mut rng);
        let mut hidden = random_blob(&mut rng, [0.5, 0.5], 0.3);
        hidden.alpha = 0.0;
        let mut broken = hidden;
        broken.alpha = 1.0;
        broken.points[4] = [f32::NAN, 0.5];
        assert_eq!(window.render(&[hidden, broken]), window.canvas);
        let (loss, gradient) = window.l2_gradient(&[hidden, broken]);
        assert!(loss.is_finite());
        assert!(gradient[0][..PARAMS - 1].iter().all(|g| *g == 0.0), "{:?}", gradient[0]);
        assert!(gradient[0][PARAMS - 1] != 0.0);
        assert!(gradient[1].iter().all(|g| *g == 0.0));
        // Its opacity's gradient is the one at a small opacity.
        let mut faint = hidden;
        faint.alpha = 1e-4;
        let (_, near) = window.l2_gradient(&[faint]);
        let (at, by) = (gradient[0][PARAMS - 1], near[0][PARAMS - 1]);
        assert!((at - by).abs() < 1e-3 * by.abs(), "{at} vs {by}");
    }

    /// A handle ten million window widths away never makes the sampling of the outline
    /// unbounded (uncapped: some 10⁹ samples, 18.6 s in a debug build), and every number stays
    /// finite.
    #[test]
    fn wild_handles_cost_no_more_than_the_window() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(23);
        let window = window(&mut rng);
        let mut wild = random_blob(&mut rng, [0.5, 0.5], 0.3);
        wild.points[1] = [1e7, -1e7];
        let (w, h) = (window.width as f32, window.height as f32);
        let wild_piece = [[0.5 * w, 0.5 * h], [1e7 * w, -1e7 * h], [0.5 * w, 0.6 * h], [0.6 * w, 0.6 * h]];
        let cap = (3.0 * (w + h) * SAMPLES_PER_PIXEL).ceil() as usize;
        assert_eq!(piece_samples(&wild_piece, (w, h)), cap);
        let tame = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0]];
        assert_eq!(piece_samples(&tame, (w, h)), (3.0 * SAMPLES_PER_PIXEL).ceil().max(4.0) as usize);
        let (loss, gradient) = window.l2_gradient(&[wild]);
        assert!(loss.is_finite() && gradient.iter().flatten().all(|g| g.is_finite()));
    }
}
