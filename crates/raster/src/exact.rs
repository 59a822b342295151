//! The exact renderer: tiny-skia's anti-aliased scanline fill of the true shapes.
//!
//! Used for previews, metrics and as ground truth for the soft rasterizer. Same layout and
//! painter's order as [`crate::render_soft`], nonzero fill rule, linear (non-gamma) blending;
//! ramps ([`crate::Fill::Linear`]) interpolated in sRGB values, as SVG's renderers do.

use image::RgbImage;
use tiny_skia::{Color, FillRule, Mask, Paint, Pixmap, Transform};

use crate::shape::Filled;

/// Renders `paths` (unit-square coordinates) to a `width × height` RGB image over `background`.
///
/// Paths with α ≤ 0 or any non-finite number are skipped: they cannot be drawn and an
/// invisible path changes nothing. Colours and α are clamped to [0, 1].
///
/// # Panics
/// If `width` or `height` is zero.
pub fn render_exact<F: Filled>(paths: &[F], width: u32, height: u32, background: [f32; 3]) -> RgbImage {
    let mut pixmap = Pixmap::new(width, height).expect("render_exact needs a non-empty canvas");
    pixmap.fill(opaque(background));
    for path in paths {
        paint_exact(&mut pixmap, path, (width, height), (0, 0));
    }
    let rgb = pixmap.data().chunks_exact(4).flat_map(|px| [px[0], px[1], px[2]]).collect();
    RgbImage::from_raw(width, height, rgb).expect("buffer matches the canvas")
}

/// Paints `path` (unit-square coordinates of a `canvas` = (width, height) image) over `pixmap`,
/// which holds that image or the part of it whose top-left pixel is `origin`: painting a box
/// of a canvas gives the pixels painting the whole canvas gives there, but for a few pixels of
/// anti-aliased edges (tiny-skia's coverage strips depend on the pixmap). Returns false, painting
/// nothing, for a path that cannot be drawn (α ≤ 0, a non-finite number).
pub fn paint_exact(
    pixmap: &mut Pixmap,
    path: &(impl Filled + ?Sized),
    canvas: (u32, u32),
    origin: (u32, u32),
) -> bool {
    let Some(outline) = skia_outline(path) else { return false };
    let Some(shader) = path.fill().shader(path.alpha(), canvas) else { return false };
    let paint = Paint { shader, ..Paint::default() };
    pixmap.fill_path(&outline, &paint, FillRule::Winding, canvas_transform(canvas, origin), None);
    true
}

/// Unit-square coordinates of a `canvas` to the pixels of a window whose top-left pixel is
/// `origin`: scale first, then move by whole pixels, so that the rasterizer sees the same
/// sub-pixel positions as on the whole canvas.
fn canvas_transform(canvas: (u32, u32), origin: (u32, u32)) -> Transform {
    Transform::from_scale(canvas.0 as f32, canvas.1 as f32)
        .post_translate(-(origin.0 as f32), -(origin.1 as f32))
}

/// The exact anti-aliased coverage (0–255 per pixel, row-major) of `path` alone on a `width ×
/// height` canvas, opacity ignored; `None` for a path that cannot be drawn or an empty canvas.
pub fn coverage_exact(path: &(impl Filled + ?Sized), width: u32, height: u32) -> Option<Mask> {
    coverage_exact_window(path, (width, height), (0, 0), (width, height))
}

/// [`coverage_exact`] inside the `size` window of a `canvas` = (width, height) image whose
/// top-left pixel is `origin` (placed as [`paint_exact`] places paths), for the cost of the
/// window.
pub fn coverage_exact_window(
    path: &(impl Filled + ?Sized),
    canvas: (u32, u32),
    origin: (u32, u32),
    size: (u32, u32),
) -> Option<Mask> {
    let outline = path.geometry()?;
    let mut mask = Mask::new(size.0, size.1)?;
    mask.fill_path(&outline, FillRule::Winding, true, canvas_transform(canvas, origin));
    Some(mask)
}

/// The closed outline of a drawable shape in unit-square coordinates (scale it to the canvas
/// with a transform), or `None` for an invisible or non-finite one.
pub fn skia_outline(path: &(impl Filled + ?Sized)) -> Option<tiny_skia::Path> {
    if !path.alpha().is_finite() || path.alpha() <= 0.0 {
        return None;
    }
    path.geometry()
}

fn opaque([r, g, b]: [f32; 3]) -> Color {
    Color::from_rgba(r.clamp(0.0, 1.0), g.clamp(0.0, 1.0), b.clamp(0.0, 1.0), 1.0)
        .expect("clamped colour is valid")
}
