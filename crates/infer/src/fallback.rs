//! The simplest drawing of an image split into superpixels: one path under everything in the
//! image's mean colour, then every region's outline, fitted with one path, in its mean colour.
//!
//! Every result starts from it, so no pixel is left uncovered whatever the later stages keep,
//! and a region's learned paths are kept only where they beat it.

use image::Rgb32FImage;
use raster::{Path, fit_outline};
use superpixel::Segmentation;

/// How far (pixels) each region's outline is pushed outwards before it is fitted, so the paths
/// of neighbouring regions overlap instead of leaving seams of the background between them;
/// the later region covers the overlap. Half a pixel measured best on data/eval/photos (see
/// docs/operating-point.md).
pub const GROW: f32 = 0.5;

/// A path covering the whole canvas in the image's mean colour: what shows wherever no region
/// path reaches.
pub fn background(image: &Rgb32FImage) -> Path {
    let count = (image.width() * image.height()).max(1) as f64;
    let mut sum = [0.0f64; 3];
    for pixel in image.pixels() {
        (0..3).for_each(|c| sum[c] += pixel.0[c] as f64);
    }
    let color = sum.map(|s| (s / count) as f32);
    Path::quadrilateral([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]], color, 1.0)
}

/// Region `region`'s outline fitted with one path (the image's unit square), in its mean
/// colour; `None` if the outline cannot be fitted (never for a region of at least one pixel).
pub fn region_path(segmentation: &Segmentation, region: u32, grow: f32) -> Option<Path> {
    let outline = segmentation.outline(region);
    let color = segmentation.regions[region as usize].mean_color;
    let (width, height) = (segmentation.width as f32, segmentation.height as f32);
    let path = fit_outline(&outline, grow, color, 1.0)?;
    Some(path.map_points(|[x, y]| [x / width, y / height]))
}

/// The regions in the order they are painted: larger bounding boxes first, so a region that
/// encloses another (its box contains the other's) never covers it.
pub fn painter_order(segmentation: &Segmentation) -> Vec<u32> {
    let mut order: Vec<u32> = (0..segmentation.regions.len() as u32).collect();
    let area = |r: &u32| {
        let bbox = segmentation.regions[*r as usize].bbox;
        bbox.width() as u64 * bbox.height() as u64
    };
    order.sort_by_key(|r| (std::cmp::Reverse(area(r)), *r));
    order
}

/// The fallback drawing alone: the background, then every region's path in painter's order.
pub fn mosaic(image: &Rgb32FImage, segmentation: &Segmentation) -> Vec<Path> {
    std::iter::once(background(image))
        .chain(painter_order(segmentation).into_iter().filter_map(|r| region_path(segmentation, r, GROW)))
        .collect()
}

#[cfg(test)]
mod tests {
    use image::Rgb;
    use superpixel::{SlicOptions, slic};

    use super::*;
    use crate::metrics::psnr;

    #[test]
    fn the_mosaic_is_close_to_the_pixel_exact_one() {
        let image = Rgb32FImage::from_fn(96, 64, |x, y| {
            let wave = ((x as f32 / 9.0).sin() + (y as f32 / 7.0).cos()) * 0.25 + 0.5;
            Rgb([wave, (x as f32 / 96.0), if (x / 24 + y / 16) % 2 == 0 { 0.8 } else { 0.2 }])
        });
        let segmentation = slic(&image, &SlicOptions { n_segments: 40, ..Default::default() }).unwrap();
        let exact = Rgb32FImage::from_fn(96, 64, |x, y| {
            Rgb(segmentation.regions[segmentation.label(x, y) as usize].mean_color)
        });
        let drawn = raster::render_exact(&mosaic(&image, &segmentation), 96, 64, [1.0; 3]);
        let drawn = image::DynamicImage::ImageRgb8(drawn).to_rgb32f();
        let (ours, pixels) = (psnr(&drawn, &image), psnr(&exact, &image));
        assert!(ours > pixels - 1.5, "fitted outlines {ours:.2} dB, pixel regions {pixels:.2} dB");
    }

    #[test]
    fn enclosing_regions_are_painted_first() {
        let image = Rgb32FImage::from_fn(30, 30, |x, y| {
            if (10..20).contains(&x) && (10..20).contains(&y) { Rgb([1.0, 0.0, 0.0]) } else { Rgb([0.0, 0.0, 1.0]) }
        });
        let segmentation = slic(&image, &SlicOptions { n_segments: 2, compactness: 1.0, ..Default::default() }).unwrap();
        let order = painter_order(&segmentation);
        let boxes: Vec<u64> = order
            .iter()
            .map(|&r| {
                let b = segmentation.regions[r as usize].bbox;
                b.width() as u64 * b.height() as u64
            })
            .collect();
        assert!(boxes.windows(2).all(|w| w[0] >= w[1]), "{boxes:?}");
    }
}
