//! Random vector scenes: training data that needs no dataset.

use image::{Rgb, Rgb32FImage};
use rand::Rng;
use raster::{random_blob, skia_outline};
use tiny_skia::{Color, GradientStop, LinearGradient, Paint, Pixmap, Point, Rect, SpreadMode, Transform};

/// A `size × size` picture of 3–24 random closed Bézier shapes over a flat or gradient background,
/// each filled flat or with a linear gradient, rendered exactly with tiny-skia, plus a little
/// per-pixel noise (σ up to 0.03).
pub fn synthetic_scene(rng: &mut impl Rng, size: u32) -> Rgb32FImage {
    let mut pixmap = Pixmap::new(size, size).expect("scene size is positive");
    let canvas = Rect::from_xywh(0.0, 0.0, size as f32, size as f32).expect("positive size");
    let base = random_color(rng);
    let background = random_paint(rng, [0.5, 0.5], 0.7, base, size);
    pixmap.fill_rect(canvas, &background, Transform::identity(), None);
    for _ in 0..rng.random_range(3..=24) {
        let center = [rng.random_range(0.0..1.0), rng.random_range(0.0..1.0)];
        let radius = rng.random_range(0.04..0.3);
        let blob = random_blob(rng, center, radius);
        let Some(outline) = skia_outline(&blob) else { continue };
        let paint = random_paint(rng, center, radius, blob.color, size);
        let scale = Transform::from_scale(size as f32, size as f32);
        pixmap.fill_path(&outline, &paint, tiny_skia::FillRule::Winding, scale, None);
    }
    let noise = rng.random_range(0.0..0.03f32);
    let pixels: Vec<u8> = pixmap.data().chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect();
    Rgb32FImage::from_fn(size, size, |x, y| {
        let i = 3 * (y * size + x) as usize;
        let mut channel = |c: usize| {
            let jitter =
                (rng.random::<f32>() + rng.random::<f32>() + rng.random::<f32>() - 1.5) * 2.0 * noise;
            (pixels[i + c] as f32 / 255.0 + jitter).clamp(0.0, 1.0)
        };
        Rgb([channel(0), channel(1), channel(2)])
    })
}

fn random_color(rng: &mut impl Rng) -> [f32; 3] {
    [rng.random(), rng.random(), rng.random()]
}

/// Flat `color` (60%) or a linear gradient from `color` to another colour across the shape.
fn random_paint(
    rng: &mut impl Rng,
    center: [f32; 2],
    radius: f32,
    color: [f32; 3],
    size: u32,
) -> Paint<'static> {
    let solid = |[r, g, b]: [f32; 3]| Color::from_rgba(r, g, b, 1.0).expect("colour in range");
    let mut paint = Paint::default();
    paint.set_color(solid(color));
    if rng.random_bool(0.4) {
        let angle = rng.random_range(0.0..std::f32::consts::TAU);
        let (dx, dy) = (angle.cos() * radius * size as f32, angle.sin() * radius * size as f32);
        let (cx, cy) = (center[0] * size as f32, center[1] * size as f32);
        let stops =
            vec![GradientStop::new(0.0, solid(color)), GradientStop::new(1.0, solid(random_color(rng)))];
        let start = Point::from_xy(cx - dx, cy - dy);
        let end = Point::from_xy(cx + dx, cy + dy);
        if let Some(shader) = LinearGradient::new(start, end, stops, SpreadMode::Pad, Transform::identity()) {
            paint.shader = shader;
        }
    }
    paint
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;

    use super::*;

    #[test]
    fn scenes_are_deterministic_varied_and_in_range() {
        let scene = |seed| synthetic_scene(&mut rand_chacha::ChaCha8Rng::seed_from_u64(seed), 48);
        assert_eq!(scene(1), scene(1));
        assert_ne!(scene(1), scene(2));
        let image = scene(3);
        assert!(image.pixels().all(|p| p.0.iter().all(|c| (0.0..=1.0).contains(c))));
        let first = image.get_pixel(0, 0).0;
        assert!(image.pixels().any(|p| (p.0[0] - first[0]).abs() > 0.1), "the scene is not flat");
    }
}
