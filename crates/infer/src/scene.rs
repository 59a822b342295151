//! The drawing being built: every path with the region and stage it came from, and one exact
//! canvas kept equal to the rendering of those paths.
//!
//! Stages only append paths (painter's order) or try to: a trial paints the path, compares the
//! error over a scope of pixels with what it was, and restores the pixels under the path if the
//! path did not help. The canvas is touched only inside the pixel box of the path being painted,
//! so it always equals a full exact rendering of the paths without ever re-rendering it.

use std::sync::Arc;

use common::PixelBox;
use image::{Rgb, Rgb32FImage, RgbImage};
use model::ModelConfig;
use raster::{Filled, Path, Shape, coverage_exact_window, paint_exact};
use serde::Serialize;
use superpixel::{RegionCrop, Segmentation};
use tiny_skia::{IntRect, Pixmap};

/// Which stage drew a path.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Origin {
    /// The one path under everything, covering the whole canvas.
    Background,
    /// A region's outline filled with its mean colour.
    Fallback,
    /// The coarse model E_c.
    Coarse,
    /// The refinement model E_r.
    Refine,
}

impl Origin {
    /// Every stage, in pipeline order.
    pub const ALL: [Origin; 4] = [Origin::Background, Origin::Fallback, Origin::Coarse, Origin::Refine];

    /// Lower-case name for reports (the field names of [`StageCounts`]).
    pub fn name(self) -> &'static str {
        match self {
            Origin::Background => "background",
            Origin::Fallback => "fallback",
            Origin::Coarse => "coarse",
            Origin::Refine => "refine",
        }
    }
}

/// How many paths each stage drew.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct StageCounts {
    /// The path under everything (one, once drawn).
    pub background: usize,
    /// Regions' outlines in their mean colour.
    pub fallback: usize,
    /// E_c's paths.
    pub coarse: usize,
    /// E_r's paths.
    pub refine: usize,
}

impl StageCounts {
    /// The count of paths from `origin`.
    pub fn of(&self, origin: Origin) -> usize {
        match origin {
            Origin::Background => self.background,
            Origin::Fallback => self.fallback,
            Origin::Coarse => self.coarse,
            Origin::Refine => self.refine,
        }
    }

    /// Every path.
    pub fn total(&self) -> usize {
        self.background + self.fallback + self.coarse + self.refine
    }
}

/// A shape of the result, the superpixel it was drawn for and the stage that drew it.
#[derive(Clone, Debug, PartialEq)]
pub struct Placed {
    /// The shape, in the image's unit square.
    pub shape: Shape,
    /// Its region in the segmentation (`None` for the background).
    pub region: Option<u32>,
    /// The stage that drew it.
    pub origin: Origin,
}

/// Which pixels of a path's box judge a trial.
#[derive(Clone, Copy, Debug)]
pub enum Scope<'a> {
    /// Every pixel.
    All,
    /// Pixels whose region is marked true.
    Regions(&'a [bool]),
}

/// The image, its superpixels, the paths drawn so far and their exact rendering. The image and
/// the superpixels are shared (`Arc`): a copy of the scene (a drawing kept to fall back to)
/// copies only its paths and canvas.
#[derive(Clone)]
pub struct Scene {
    target: Arc<Rgb32FImage>,
    segmentation: Arc<Segmentation>,
    paths: Vec<Placed>,
    canvas: Pixmap,
}

impl Scene {
    /// An empty drawing of `target` (nothing covered yet) split into `segmentation`.
    ///
    /// # Panics
    /// If the segmentation was not computed on an image of `target`'s size.
    pub fn new(target: impl Into<Arc<Rgb32FImage>>, segmentation: impl Into<Arc<Segmentation>>) -> Self {
        let target = target.into();
        let canvas = Pixmap::new(target.width(), target.height()).expect("a non-empty image");
        Self::drawn(target, segmentation, Vec::new(), canvas)
    }

    /// The drawing of `target` made of `paths`, whose exact rendering `canvas` already is (made
    /// elsewhere, e.g. when the drawing was scored): nothing is painted again.
    ///
    /// # Panics
    /// If the segmentation or the canvas is not of `target`'s size.
    pub fn drawn(
        target: impl Into<Arc<Rgb32FImage>>,
        segmentation: impl Into<Arc<Segmentation>>,
        paths: Vec<Placed>,
        canvas: Pixmap,
    ) -> Self {
        let (target, segmentation) = (target.into(), segmentation.into());
        let size = target.dimensions();
        assert_eq!(size, (segmentation.width, segmentation.height), "target and segmentation sizes");
        assert_eq!(size, (canvas.width(), canvas.height()), "target and canvas sizes");
        Self { target, segmentation, paths, canvas }
    }

    /// The image being drawn (working resolution).
    pub fn target(&self) -> &Arc<Rgb32FImage> {
        &self.target
    }

    /// Its superpixels.
    pub fn segmentation(&self) -> &Arc<Segmentation> {
        &self.segmentation
    }

    /// The paths in painter's order.
    pub fn paths(&self) -> &[Placed] {
        &self.paths
    }

    /// The shapes alone, in painter's order.
    pub fn scene(&self) -> Vec<Shape> {
        self.paths.iter().map(|placed| placed.shape.clone()).collect()
    }

    /// Number of paths.
    pub fn len(&self) -> usize {
        self.paths.len()
    }

    /// Whether nothing is drawn yet.
    pub fn is_empty(&self) -> bool {
        self.paths.is_empty()
    }

    /// Region `region` cut out as the models read it (the input contract of `config`).
    pub fn region_crop(&self, config: &ModelConfig, region: u32) -> RegionCrop {
        config.region_crop(&self.segmentation, &self.target, region)
    }

    /// How many paths each stage drew.
    pub fn counts(&self) -> StageCounts {
        let mut counts = StageCounts::default();
        for placed in &self.paths {
            *match placed.origin {
                Origin::Background => &mut counts.background,
                Origin::Fallback => &mut counts.fallback,
                Origin::Coarse => &mut counts.coarse,
                Origin::Refine => &mut counts.refine,
            } += 1;
        }
        counts
    }

    /// Paints `placed` over everything drawn so far and keeps it; false (nothing kept) if the
    /// path cannot be drawn or lies wholly outside the canvas.
    pub fn push(&mut self, placed: Placed) -> bool {
        if self.pixel_box(&placed.shape).is_none() {
            return false;
        }
        let size = self.size();
        let painted = paint_exact(&mut self.canvas, &placed.shape, size, (0, 0));
        if painted {
            self.paths.push(placed);
        }
        painted
    }

    /// Paints `placed` over everything drawn so far and keeps it only if the squared error
    /// over the `scope` pixels of its box drops by more than rounding to 8 bits could make it
    /// drop (`ROUNDING_GAIN` a pixel judged); otherwise the canvas is restored. Returns how
    /// much it dropped when the path was kept, `None` otherwise.
    pub fn try_push(&mut self, placed: Placed, scope: Scope<'_>) -> Option<f64> {
        let bbox = self.pixel_box(&placed.shape)?;
        let saved = self.save(bbox);
        let (before, pixels) = self.error_and_pixels(bbox, scope);
        let min_gain = pixels as f64 * ROUNDING_GAIN;
        let size = self.size();
        if !paint_exact(&mut self.canvas, &placed.shape, size, (0, 0)) {
            return None;
        }
        let gain = before - self.error(bbox, scope);
        if gain > min_gain {
            self.paths.push(placed);
            Some(gain)
        } else {
            self.restore(bbox, &saved);
            None
        }
    }

    /// Moves the last `count` paths to `index` in painter's order, keeping their order, and
    /// paints their boxes again, so the paths after them cover them there.
    ///
    /// # Panics
    /// If there are fewer than `count` paths, or `index` is past where they start.
    pub fn move_last(&mut self, count: usize, index: usize) {
        let start = self.paths.len() - count;
        assert!(index <= start, "paths move back in painter's order");
        if count == 0 || index == start {
            return;
        }
        let (width, height) = self.size();
        let moved: Vec<Placed> = self.paths.drain(start..).collect();
        let boxes = moved.iter().filter_map(|placed| placed.shape.pixel_box(width, height));
        let union = boxes.reduce(|a, b| a.union(&b));
        self.paths.splice(index..index, moved);
        if let Some(union) = union {
            self.repaint_box(union);
        }
    }

    /// `path` in the fill colour that brings the drawing closest to the image over the `scope`
    /// pixels it covers when painted over what is drawn: least squares over its anti-aliased
    /// coverage, each channel clamped to [0, 1]. A model places a path better than it picks
    /// its colour, and the colour has this closed form. `None` when the path cannot be drawn
    /// or covers none of those pixels.
    pub fn fit_colour(&self, path: &Path, scope: Scope<'_>) -> Option<Path> {
        let bbox = self.pixel_box(path)?;
        let size = self.size();
        let coverage =
            coverage_exact_window(path, size, (bbox.x0(), bbox.y0()), (bbox.width(), bbox.height()))?;
        let alpha = path.alpha.clamp(0.0, 1.0) as f64;
        let (width, data) = (self.target.width(), self.canvas.data());
        let (mut numerator, mut denominator) = ([0.0f64; 3], 0.0f64);
        for (row, y) in bbox.rows().enumerate() {
            for (column, x) in bbox.columns().enumerate() {
                let index = (y * width + x) as usize;
                if !self.in_scope(index, scope) {
                    continue;
                }
                let cover = alpha * coverage.data()[row * bbox.width() as usize + column] as f64 / 255.0;
                if cover == 0.0 {
                    continue;
                }
                // Painted: cover·colour + (1 − cover)·below; fit cover·colour to target − (1 − cover)·below.
                let (target, i) = (self.target.get_pixel(x, y), 4 * index);
                for c in 0..3 {
                    let below = over_white(data[i + c], data[i + 3]) as f64;
                    numerator[c] += cover * (target.0[c] as f64 - (1.0 - cover) * below);
                }
                denominator += cover * cover;
            }
        }
        (denominator > 0.0)
            .then(|| Path { color: numerator.map(|n| (n / denominator).clamp(0.0, 1.0) as f32), ..*path })
    }

    /// Sum of squared differences (RGB in [0, 1]) between the drawing, seen over white, and the
    /// image over the `scope` pixels of `bbox`.
    pub fn error(&self, bbox: PixelBox, scope: Scope<'_>) -> f64 {
        self.error_and_pixels(bbox, scope).0
    }

    /// [`Scene::error`] and how many pixels it was summed over.
    fn error_and_pixels(&self, bbox: PixelBox, scope: Scope<'_>) -> (f64, u64) {
        let width = self.target.width();
        let (mut sum, mut pixels) = (0.0f64, 0u64);
        for y in bbox.rows() {
            let row = (y * width) as usize;
            for x in bbox.columns() {
                let index = row + x as usize;
                if !self.in_scope(index, scope) {
                    continue;
                }
                sum += pixel_error(self.canvas.data(), index, self.target.get_pixel(x, y));
                pixels += 1;
            }
        }
        (sum, pixels)
    }

    /// Sum of squared differences per region over the whole image.
    pub fn region_errors(&self) -> Vec<f64> {
        region_errors(&self.canvas, &self.target, &self.segmentation)
    }

    /// The drawing seen over white, RGB in [0, 1].
    pub fn canvas_image(&self) -> Rgb32FImage {
        let (width, height) = self.size();
        let data = self.canvas.data();
        Rgb32FImage::from_fn(width, height, |x, y| {
            let i = 4 * (y * width + x) as usize;
            Rgb(std::array::from_fn(|c| over_white(data[i + c], data[i + 3])))
        })
    }

    /// The drawing seen over white, 8 bits per channel: the picture previews show.
    pub fn canvas_rgb8(&self) -> RgbImage {
        let (width, height) = self.size();
        let data = self.canvas.data();
        RgbImage::from_fn(width, height, |x, y| {
            let i = 4 * (y * width + x) as usize;
            Rgb(std::array::from_fn(|c| data[i + c].saturating_add(255 - data[i + 3])))
        })
    }

    /// The canvas: premultiplied RGBA, transparent where no path covers a pixel.
    pub fn canvas(&self) -> &Pixmap {
        &self.canvas
    }

    /// The canvas alone, the scene given up (a drawing that was only made to be scored).
    pub fn into_canvas(self) -> Pixmap {
        self.canvas
    }

    /// Replaces every shape (same count, same regions and stages) by `shapes`, e.g. after
    /// fine-tuning, and renders the canvas again.
    ///
    /// # Panics
    /// If the number of shapes differs.
    pub fn set_shapes(&mut self, shapes: &[Shape]) {
        assert_eq!(shapes.len(), self.paths.len(), "the scene keeps its path count");
        for (placed, shape) in self.paths.iter_mut().zip(shapes) {
            placed.shape = shape.clone();
        }
        self.repaint();
    }

    /// Renders the canvas again from the paths, in one pass over the whole canvas: what a box
    /// painted again in a window of its own ([`Scene::retain`], [`Scene::move_last`]) gives
    /// but for a few anti-aliased pixels (see `raster::paint_exact`), exactly.
    pub fn repaint(&mut self) {
        self.canvas.fill(tiny_skia::Color::TRANSPARENT);
        let size = self.size();
        for placed in &self.paths {
            paint_exact(&mut self.canvas, &placed.shape, size, (0, 0));
        }
    }

    /// Keeps only the paths `keep` accepts (given each path's index and the path), in order,
    /// and paints again only the boxes of the paths that went.
    pub fn retain(&mut self, mut keep: impl FnMut(usize, &Placed) -> bool) {
        let (width, height) = self.size();
        let mut dropped: Vec<PixelBox> = Vec::new();
        let mut index = 0;
        self.paths.retain(|placed| {
            index += 1;
            let kept = keep(index - 1, placed);
            if !kept && let Some(bbox) = placed.shape.pixel_box(width, height) {
                dropped.push(bbox);
            }
            kept
        });
        // Past the canvas's area in boxes, one whole repaint is cheaper.
        if dropped.iter().map(PixelBox::area).sum::<u64>() > u64::from(width) * u64::from(height) {
            self.repaint();
        } else {
            dropped.iter().for_each(|&bbox| self.repaint_box(bbox));
        }
    }

    /// Paints the pixels of `bbox` again from the paths that reach them.
    fn repaint_box(&mut self, bbox: PixelBox) {
        let size = self.size();
        let mut window = Pixmap::new(bbox.width(), bbox.height()).expect("a non-empty box");
        for placed in &self.paths {
            let reaches =
                placed.shape.pixel_box(size.0, size.1).is_some_and(|b| b.intersection(&bbox).is_some());
            if reaches {
                paint_exact(&mut window, &placed.shape, size, (bbox.x0(), bbox.y0()));
            }
        }
        self.restore(bbox, &window);
    }

    /// Sum of squared differences over the whole image.
    pub fn total_error(&self) -> f64 {
        let (width, height) = self.size();
        self.error(PixelBox::image(width, height), Scope::All)
    }

    /// Whether pixel `index` (row-major) is one of the `scope` pixels.
    fn in_scope(&self, index: usize, scope: Scope<'_>) -> bool {
        match scope {
            Scope::All => true,
            Scope::Regions(marked) => marked[self.segmentation.labels[index] as usize],
        }
    }

    fn size(&self) -> (u32, u32) {
        (self.target.width(), self.target.height())
    }

    /// The pixels a shape can change ([`Filled::pixel_box`] on this canvas).
    pub fn pixel_box(&self, path: &impl Filled) -> Option<PixelBox> {
        let (width, height) = self.size();
        path.pixel_box(width, height)
    }

    fn save(&self, bbox: PixelBox) -> Pixmap {
        let rect = IntRect::from_xywh(bbox.x0() as i32, bbox.y0() as i32, bbox.width(), bbox.height())
            .expect("a non-empty box");
        self.canvas.clone_rect(rect).expect("the box lies inside the canvas")
    }

    fn restore(&mut self, bbox: PixelBox, saved: &Pixmap) {
        let width = self.target.width() as usize;
        let row_bytes = 4 * bbox.width() as usize;
        let data = self.canvas.data_mut();
        for (row, source) in saved.data().chunks_exact(row_bytes).enumerate() {
            let start = 4 * ((bbox.y0() as usize + row) * width + bbox.x0() as usize);
            data[start..start + row_bytes].copy_from_slice(source);
        }
    }
}

/// Sum of squared differences (RGB over white against `target`) per region of `segmentation`
/// of the premultiplied `canvas`.
pub fn region_errors(canvas: &Pixmap, target: &Rgb32FImage, segmentation: &Segmentation) -> Vec<f64> {
    let mut errors = vec![0.0; segmentation.regions.len()];
    for (index, (pixel, &label)) in target.pixels().zip(&segmentation.labels).enumerate() {
        errors[label as usize] += pixel_error(canvas.data(), index, pixel);
    }
    errors
}

/// The most a path can lower the squared error of one pixel (three channels) without drawing
/// anything a viewer could see: the canvas holds 8 bits a channel, so a flat region whose exact
/// colour falls between two levels is off by up to half a level everywhere, and anti-aliased
/// edges dithering between the two levels "improve" it. On a flat picture E_r otherwise added
/// hundreds of such paths.
pub const ROUNDING_GAIN: f64 = 3.0 * (0.5 / 255.0) * (0.5 / 255.0);

/// A premultiplied channel over white, in [0, 1].
fn over_white(channel: u8, alpha: u8) -> f32 {
    (channel as f32 + (255 - alpha) as f32) / 255.0
}

/// Squared RGB difference at pixel `index` of premultiplied RGBA `data` (over white).
pub(crate) fn pixel_error(data: &[u8], index: usize, target: &Rgb<f32>) -> f64 {
    let i = 4 * index;
    let alpha = data[i + 3];
    (0..3).map(|c| (over_white(data[i + c], alpha) - target.0[c]).powi(2) as f64).sum()
}

/// A path that lowered the error where it was tried ([`paint_with`]).
pub(crate) struct Tried {
    /// The error it took away.
    pub(crate) gain: f64,
    /// The region it was drawn for.
    pub(crate) region: u32,
    /// The path, in its fitted colour.
    pub(crate) path: Path,
}

impl Tried {
    /// Its place in `scene`, which holds it.
    pub(crate) fn position(&self, scene: &Scene) -> usize {
        let shape = Shape::Path(self.path);
        scene
            .paths()
            .iter()
            .position(|placed| placed.region == Some(self.region) && placed.shape == shape)
            .expect("a path kept is in the scene")
    }
}

/// Tries each of E_c's `proposals[region]` on `scene`, a drawing whose regions come in
/// painter's order `order` (their fallback paths, and E_c paths kept before): a path goes in
/// right after its region's paths, in its least-squares colour over what is drawn, if it
/// lowers the error over the pixels of the regions up to its own (later regions cover the
/// rest). It is judged painted over the drawing as it is, later regions and all: over those
/// pixels they differ from the drawing at its place in painter's order only along their
/// anti-aliased edges, and nothing is painted again but, once per region, the boxes of the
/// paths it kept. Returns the paths kept.
pub(crate) fn paint_with(scene: &mut Scene, order: &[u32], mut proposals: Vec<Vec<Path>>) -> Vec<Tried> {
    let mut painted = vec![false; order.len()];
    let mut kept = Vec::new();
    let mut next = 1; // past the background
    for &region in order {
        painted[region as usize] = true;
        while next < scene.len() && scene.paths()[next].region == Some(region) {
            next += 1;
        }
        let before = scene.len();
        for path in std::mem::take(&mut proposals[region as usize]) {
            let scope = Scope::Regions(&painted);
            let path = scene.fit_colour(&path, scope).unwrap_or(path);
            let placed = Placed { shape: path.into(), region: Some(region), origin: Origin::Coarse };
            if let Some(gain) = scene.try_push(placed, scope) {
                kept.push(Tried { gain, region, path });
            }
        }
        let added = scene.len() - before;
        scene.move_last(added, next);
        next += added;
    }
    kept
}

#[cfg(test)]
mod tests {
    use raster::render_exact;
    use superpixel::{SlicOptions, slic};

    use super::*;

    fn target() -> Rgb32FImage {
        Rgb32FImage::from_fn(40, 30, |x, y| {
            if x < 20 { Rgb([0.9, 0.2, 0.1]) } else { Rgb([0.1, 0.3, 0.8 * y as f32 / 30.0]) }
        })
    }

    fn quad(lo: [f32; 2], hi: [f32; 2], color: [f32; 3]) -> Path {
        Path::quadrilateral([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]], color, 1.0)
    }

    fn square(lo: [f32; 2], hi: [f32; 2], color: [f32; 3]) -> Placed {
        Placed { shape: quad(lo, hi, color).into(), region: Some(0), origin: Origin::Refine }
    }

    /// The whole image's error after painting `path` in `color` over `scene`.
    fn error_with(scene: &Scene, path: Path, color: [f32; 3]) -> f64 {
        let mut trial = scene.clone();
        trial.push(Placed { shape: Path { color, ..path }.into(), region: Some(0), origin: Origin::Refine });
        trial.total_error()
    }

    #[test]
    fn stages_are_counted_by_name() {
        let image = target();
        let segmentation = slic(&image, &SlicOptions { n_segments: 4, ..Default::default() }).unwrap();
        let mut scene = Scene::new(image, segmentation);
        let whole = quad([0.0, 0.0], [1.0, 1.0], [0.5; 3]).into();
        assert!(scene.push(Placed { shape: whole, region: None, origin: Origin::Background }));
        assert!(scene.push(square([0.0, 0.0], [0.5, 0.5], [0.1; 3])));
        let counts = scene.counts();
        assert_eq!((counts.background, counts.refine, counts.total()), (1, 1, 2));
        assert_eq!(Origin::ALL.map(|o| counts.of(o)), [1, 0, 0, 1]);
        let json = serde_json::to_value(counts).unwrap();
        assert!(Origin::ALL.iter().all(|o| json[o.name()] == counts.of(*o)), "{json}");
    }

    #[test]
    fn fitted_colours_are_the_least_squares_fill() {
        let image = target();
        let segmentation = slic(&image, &SlicOptions { n_segments: 4, ..Default::default() }).unwrap();
        let mut scene = Scene::new(image, segmentation);
        assert!(scene.push(square([0.0, 0.0], [1.0, 1.0], [0.5; 3])));
        // Over the flat red half, pixel-aligned: exactly its colour.
        let red = scene.fit_colour(&quad([0.0, 0.0], [0.5, 1.0], [0.0, 0.0, 1.0]), Scope::All).unwrap();
        for (c, want) in red.color.iter().zip([0.9, 0.2, 0.1]) {
            assert!((c - want).abs() < 1e-4, "{:?}", red.color);
        }
        // Half transparent, straddling both halves, edges mid-pixel: no colour nearby does better.
        let straddling = Path { alpha: 0.5, ..quad([0.3, 0.1], [0.77, 0.83], [0.0; 3]) };
        let fitted = scene.fit_colour(&straddling, Scope::All).unwrap();
        let best = error_with(&scene, straddling, fitted.color);
        for c in 0..3 {
            for step in [-0.02, 0.02] {
                let mut color = fitted.color;
                color[c] = (color[c] + step).clamp(0.0, 1.0);
                let error = error_with(&scene, straddling, color);
                assert!(error >= best - 1e-9, "channel {c} {step:+}: {error} < {best}");
            }
        }
        // Off the canvas: nothing to fit.
        assert!(scene.fit_colour(&quad([2.0, 2.0], [3.0, 3.0], [0.0; 3]), Scope::All).is_none());
    }

    #[test]
    fn trials_keep_helpful_paths_and_leave_no_trace_of_others() {
        let image = target();
        let segmentation = slic(&image, &SlicOptions { n_segments: 4, ..Default::default() }).unwrap();
        let mut scene = Scene::new(image.clone(), segmentation);
        assert!(scene.push(square([0.0, 0.0], [1.0, 1.0], [0.5; 3])));
        let before = scene.canvas().clone();
        // Blue on the red half makes it worse: rejected, canvas untouched.
        assert!(scene.try_push(square([0.1, 0.1], [0.4, 0.6], [0.0, 0.0, 1.0]), Scope::All).is_none());
        assert_eq!(scene.canvas().data(), before.data());
        // Red on the red half helps.
        assert!(
            scene
                .try_push(square([0.0, 0.0], [0.5, 1.0], [0.9, 0.2, 0.1]), Scope::All)
                .is_some_and(|gain| gain > 0.0)
        );
        assert_eq!(scene.len(), 2);
        // Off the canvas: nothing to gain, nothing kept.
        assert!(scene.try_push(square([2.0, 2.0], [3.0, 3.0], [0.9, 0.2, 0.1]), Scope::All).is_none());
        // The canvas is the exact rendering of the kept paths.
        let rendered = render_exact(&scene.scene(), 40, 30, [1.0; 3]);
        let drawn = scene.canvas_image();
        for (a, b) in rendered.pixels().zip(drawn.pixels()) {
            for c in 0..3 {
                assert!((a.0[c] as f32 / 255.0 - b.0[c]).abs() < 1e-6);
            }
        }
        let total: f64 = scene.region_errors().iter().sum();
        assert!((total - scene.error(PixelBox::image(40, 30), Scope::All)).abs() < 1e-6 * total.max(1.0));
    }

    #[test]
    fn dropping_paths_repaints_their_boxes_to_the_full_rendering() {
        let image = target();
        let segmentation = slic(&image, &SlicOptions { n_segments: 4, ..Default::default() }).unwrap();
        let mut scene = Scene::new(image, segmentation);
        assert!(scene.push(square([0.0, 0.0], [1.0, 1.0], [0.5; 3])));
        for (i, lo) in [[0.1, 0.1], [0.3, 0.2], [0.5, 0.5], [0.05, 0.6]].into_iter().enumerate() {
            let color = [0.2 * i as f32, 0.9, 0.3];
            assert!(scene.push(square(lo, [lo[0] + 0.37, lo[1] + 0.33], color)));
        }
        scene.retain(|index, _| index % 2 == 0);
        assert_eq!(scene.len(), 3);
        let rendered = render_exact(&scene.scene(), 40, 30, [1.0; 3]);
        assert_eq!(scene.canvas_rgb8(), rendered, "the canvas is the rendering of the paths kept");
    }
}
