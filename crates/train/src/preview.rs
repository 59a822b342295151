//! Preview images: what the model sees and draws, side by side.

use std::path::Path;

use image::{Rgb, RgbImage};
use raster::{PathBatch, render_exact, skia_outline};
use superpixel::RegionCrop;
use tiny_skia::{Paint, Pixmap, Stroke, Transform};

/// Writes a PNG grid, one row per sample (up to `rows`): target crop (grey outside the mask) |
/// soft render | exact render of the paths over the row's background | the same with the path
/// outlines.
pub fn write_preview(
    path: &Path,
    crops: &[RegionCrop],
    render: &[f32],
    paths: &PathBatch,
    backgrounds: &[[f32; 3]],
    rows: usize,
) -> std::io::Result<()> {
    let scenes = paths.to_scenes();
    let size = crops.first().map_or(1, |crop| crop.size);
    let rows = rows.min(scenes.len()).min(crops.len());
    let tile = size as u32 * 2;
    let mut grid = RgbImage::from_pixel(4 * tile + 5, rows as u32 * (tile + 1) + 1, Rgb([40, 40, 40]));
    for (row, (scene, crop)) in scenes.iter().zip(crops).take(rows).enumerate() {
        let target = RgbImage::from_fn(size as u32, size as u32, |x, y| {
            let cell = y as usize * size + x as usize;
            let inside = crop.mask[cell] > 0.5;
            Rgb(std::array::from_fn(
                |c| if inside { to_u8(crop.pixels[c * size * size + cell]) } else { 128 },
            ))
        });
        let soft = RgbImage::from_fn(size as u32, size as u32, |x, y| {
            let at = |c: usize| render[((row * 3 + c) * size + y as usize) * size + x as usize];
            Rgb(std::array::from_fn(|c| to_u8(at(c))))
        });
        let exact = render_exact(scene, tile, tile, backgrounds[row]);
        let outlined = with_outlines(&exact, scene);
        let top = row as u32 * (tile + 1) + 1;
        let upscale = |image: &RgbImage| {
            image::imageops::resize(image, tile, tile, image::imageops::FilterType::Nearest)
        };
        for (column, image) in [upscale(&target), upscale(&soft), exact, outlined].iter().enumerate() {
            image::imageops::replace(&mut grid, image, (column as u32 * (tile + 1) + 1).into(), top.into());
        }
    }
    common::write::write_png(path, &grid)
}

fn to_u8(value: f32) -> u8 {
    (value.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// `image` with a thin dark outline around every visible path.
fn with_outlines(image: &RgbImage, scene: &[raster::Path]) -> RgbImage {
    let (width, height) = image.dimensions();
    let mut pixmap = Pixmap::new(width, height).expect("non-empty preview tile");
    for (pixel, rgb) in pixmap.pixels_mut().iter_mut().zip(image.pixels()) {
        *pixel = tiny_skia::ColorU8::from_rgba(rgb[0], rgb[1], rgb[2], 255).premultiply();
    }
    let mut paint = Paint::default();
    paint.set_color_rgba8(20, 20, 20, 200);
    let stroke = Stroke { width: 0.75, ..Stroke::default() };
    let scale = Transform::from_scale(width as f32, height as f32);
    for path in scene {
        if let Some(outline) = skia_outline(path).and_then(|o| o.transform(scale)) {
            pixmap.stroke_path(&outline, &paint, &stroke, Transform::identity(), None);
        }
    }
    RgbImage::from_fn(width, height, |x, y| {
        let p = pixmap.pixel(x, y).expect("inside the tile").demultiply();
        Rgb([p.red(), p.green(), p.blue()])
    })
}
