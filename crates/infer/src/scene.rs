//! The drawing being built: every path with the region and stage it came from, and one exact
//! canvas kept equal to the rendering of those paths.
//!
//! Stages only append paths (painter's order) or try to: a trial paints the path, compares the
//! error over a scope of pixels with what it was, and restores the pixels under the path if the
//! path did not help. The canvas is touched only inside the pixel box of the path being painted,
//! so it always equals a full exact rendering of the paths without ever re-rendering it.

use image::{Rgb, Rgb32FImage};
use model::ModelConfig;
use raster::{Filled, Path, Shape, coverage_exact_window, paint_exact};
use superpixel::{BoundingBox, RegionCrop, Segmentation};
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

    /// Lower-case name for reports.
    pub fn name(self) -> &'static str {
        match self {
            Origin::Background => "background",
            Origin::Fallback => "fallback",
            Origin::Coarse => "coarse",
            Origin::Refine => "refine",
        }
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

/// The image, its superpixels, the paths drawn so far and their exact rendering.
#[derive(Clone)]
pub struct Scene {
    target: Rgb32FImage,
    segmentation: Segmentation,
    paths: Vec<Placed>,
    canvas: Pixmap,
}

impl Scene {
    /// An empty drawing of `target` (nothing covered yet) split into `segmentation`.
    ///
    /// # Panics
    /// If the segmentation was not computed on an image of `target`'s size.
    pub fn new(target: Rgb32FImage, segmentation: Segmentation) -> Self {
        assert_eq!(
            target.dimensions(),
            (segmentation.width, segmentation.height),
            "target and segmentation sizes"
        );
        let canvas = Pixmap::new(target.width(), target.height()).expect("a non-empty image");
        Self { target, segmentation, paths: Vec::new(), canvas }
    }

    /// The image being drawn (working resolution).
    pub fn target(&self) -> &Rgb32FImage {
        &self.target
    }

    /// Its superpixels.
    pub fn segmentation(&self) -> &Segmentation {
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
    pub fn counts(&self) -> Vec<(Origin, usize)> {
        Origin::ALL.iter().map(|&o| (o, self.paths.iter().filter(|p| p.origin == o).count())).collect()
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
    /// over the `scope` pixels of its box drops by more than `min_gain`; otherwise the canvas
    /// is restored. Returns how much it dropped when the path was kept, `None` otherwise.
    pub fn try_push(&mut self, placed: Placed, scope: Scope<'_>, min_gain: f64) -> Option<f64> {
        let bbox = self.pixel_box(&placed.shape)?;
        let saved = self.save(bbox);
        let before = self.error(bbox, scope);
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

    /// `path` in the fill colour that brings the drawing closest to the image over the `scope`
    /// pixels it covers when painted over what is drawn: least squares over its anti-aliased
    /// coverage, each channel clamped to [0, 1]. A model places a path better than it picks
    /// its colour, and the colour has this closed form. `None` when the path cannot be drawn
    /// or covers none of those pixels.
    pub fn fit_colour(&self, path: &Path, scope: Scope<'_>) -> Option<Path> {
        let bbox = self.pixel_box(path)?;
        let size = self.size();
        let coverage = coverage_exact_window(path, size, (bbox.x0, bbox.y0), (bbox.width(), bbox.height()))?;
        let alpha = path.alpha.clamp(0.0, 1.0) as f64;
        let (width, data) = (self.target.width(), self.canvas.data());
        let (mut numerator, mut denominator) = ([0.0f64; 3], 0.0f64);
        for (row, y) in (bbox.y0..bbox.y1).enumerate() {
            for (column, x) in (bbox.x0..bbox.x1).enumerate() {
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
    pub fn error(&self, bbox: BoundingBox, scope: Scope<'_>) -> f64 {
        let width = self.target.width();
        let mut sum = 0.0f64;
        for y in bbox.y0..bbox.y1 {
            let row = (y * width) as usize;
            for x in bbox.x0..bbox.x1 {
                let index = row + x as usize;
                if !self.in_scope(index, scope) {
                    continue;
                }
                sum += pixel_error(self.canvas.data(), index, self.target.get_pixel(x, y));
            }
        }
        sum
    }

    /// Sum of squared differences per region over the whole image.
    pub fn region_errors(&self) -> Vec<f64> {
        let mut errors = vec![0.0; self.segmentation.regions.len()];
        for (index, (pixel, &label)) in self.target.pixels().zip(&self.segmentation.labels).enumerate() {
            errors[label as usize] += pixel_error(self.canvas.data(), index, pixel);
        }
        errors
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

    /// The canvas: premultiplied RGBA, transparent where no path covers a pixel.
    pub fn canvas(&self) -> &Pixmap {
        &self.canvas
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

    /// Renders the canvas again from the paths.
    fn repaint(&mut self) {
        self.canvas.fill(tiny_skia::Color::TRANSPARENT);
        let size = self.size();
        for placed in &self.paths {
            paint_exact(&mut self.canvas, &placed.shape, size, (0, 0));
        }
    }

    /// Keeps only the paths `keep` accepts (given each path's index and the path), in order,
    /// and renders the canvas again.
    pub fn retain(&mut self, mut keep: impl FnMut(usize, &Placed) -> bool) {
        let mut index = 0;
        self.paths.retain(|placed| {
            index += 1;
            keep(index - 1, placed)
        });
        self.repaint();
    }

    /// Sum of squared differences over the whole image.
    pub fn total_error(&self) -> f64 {
        let whole = BoundingBox { x0: 0, y0: 0, x1: self.target.width(), y1: self.target.height() };
        self.error(whole, Scope::All)
    }

    /// Takes the scene apart: its paths and segmentation.
    pub fn into_parts(self) -> (Vec<Placed>, Segmentation) {
        (self.paths, self.segmentation)
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

    /// The pixels a shape can change: its bounds, widened by a pixel for anti-aliasing, within
    /// the canvas; `None` when that is empty or not finite.
    pub fn pixel_box(&self, path: &impl Filled) -> Option<BoundingBox> {
        let (width, height) = self.size();
        let [x0, y0, x1, y1] = path.pixel_box(width, height)?;
        Some(BoundingBox { x0, y0, x1, y1 })
    }

    fn save(&self, bbox: BoundingBox) -> Pixmap {
        let rect = IntRect::from_xywh(bbox.x0 as i32, bbox.y0 as i32, bbox.width(), bbox.height())
            .expect("a non-empty box");
        self.canvas.clone_rect(rect).expect("the box lies inside the canvas")
    }

    fn restore(&mut self, bbox: BoundingBox, saved: &Pixmap) {
        let width = self.target.width() as usize;
        let row_bytes = 4 * bbox.width() as usize;
        let data = self.canvas.data_mut();
        for (row, source) in saved.data().chunks_exact(row_bytes).enumerate() {
            let start = 4 * ((bbox.y0 as usize + row) * width + bbox.x0 as usize);
            data[start..start + row_bytes].copy_from_slice(source);
        }
    }
}

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
        assert!(scene.try_push(square([0.1, 0.1], [0.4, 0.6], [0.0, 0.0, 1.0]), Scope::All, 0.0).is_none());
        assert_eq!(scene.canvas().data(), before.data());
        // Red on the red half helps.
        assert!(
            scene
                .try_push(square([0.0, 0.0], [0.5, 1.0], [0.9, 0.2, 0.1]), Scope::All, 0.0)
                .is_some_and(|gain| gain > 0.0)
        );
        assert_eq!(scene.len(), 2);
        // Off the canvas: nothing to gain, nothing kept.
        assert!(scene.try_push(square([2.0, 2.0], [3.0, 3.0], [0.9, 0.2, 0.1]), Scope::All, 0.0).is_none());
        // The canvas is the exact rendering of the kept paths.
        let rendered = render_exact(&scene.scene(), 40, 30, [1.0; 3]);
        let drawn = scene.canvas_image();
        for (a, b) in rendered.pixels().zip(drawn.pixels()) {
            for c in 0..3 {
                assert!((a.0[c] as f32 / 255.0 - b.0[c]).abs() < 1e-6);
            }
        }
        let total: f64 = scene.region_errors().iter().sum();
        let whole = BoundingBox { x0: 0, y0: 0, x1: 40, y1: 30 };
        assert!((total - scene.error(whole, Scope::All)).abs() < 1e-6 * total.max(1.0));
    }
}
