//! The simplest drawing of an image split into superpixels: one path under everything, then
//! every region's outline, fitted with one path, in its mean colour.
//!
//! Every result starts from it, so no pixel is left uncovered whatever the later stages keep,
//! and a region's learned paths are kept only where they beat it.

use image::Rgb32FImage;
use raster::{Path, fit_outline, paint_exact};
use rayon::prelude::*;
use superpixel::Segmentation;
use tiny_skia::Pixmap;

/// How far (pixels) each region's outline is pushed outwards before it is fitted, so the paths
/// of neighbouring regions overlap instead of leaving seams of the background between them;
/// the later region covers the overlap. Half a pixel measured best on data/eval/photos (see
/// docs/operating-point.md).
pub const GROW: f32 = 0.5;

/// A path covering the whole canvas, in the colour that is best where `above` (the paths to be
/// painted over it) leaves it showing: the mean of the image weighted by how little `above`
/// covers each pixel (the image's mean if `above` covers everything). On flat art the seams
/// between regions then show the page's colour, not a tint of everything in the picture.
pub fn background(image: &Rgb32FImage, above: &[Path]) -> Path {
    let (width, height) = image.dimensions();
    let mut cover = Pixmap::new(width, height).expect("a non-empty image");
    for path in above {
        paint_exact(&mut cover, path, (width, height), (0, 0));
    }
    let (mut shown, mut sum, mut total) = (0.0f64, [0.0f64; 3], [0.0f64; 3]);
    for (pixel, rgba) in image.pixels().zip(cover.data().chunks_exact(4)) {
        let weight = (255 - rgba[3]) as f64 / 255.0;
        shown += weight;
        for c in 0..3 {
            sum[c] += weight * pixel.0[c] as f64;
            total[c] += pixel.0[c] as f64;
        }
    }
    let pixels = (width as f64 * height as f64).max(1.0);
    let color =
        if shown > 0.0 { sum.map(|s| (s / shown) as f32) } else { total.map(|s| (s / pixels) as f32) };
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

/// The fallback drawing of an image's segmentation: fitted once, then scored (choosing a
/// segmentation) and drawn (the coarse stage starts from it).
#[derive(Clone, Debug)]
pub struct FallbackDrawing {
    /// The regions in painter's order ([`painter_order`]).
    pub order: Vec<u32>,
    /// Each region's path, in `order`; `None` where a region cannot be fitted.
    pub regions: Vec<Option<Path>>,
    /// The path under everything ([`background`] of the region paths).
    pub background: Path,
}

impl FallbackDrawing {
    /// Fits every region of `segmentation` (in parallel) and the background of `image` under them.
    pub fn new(image: &Rgb32FImage, segmentation: &Segmentation) -> Self {
        let order = painter_order(segmentation);
        let regions: Vec<Option<Path>> =
            order.par_iter().map(|&r| region_path(segmentation, r, GROW)).collect();
        let background = background(image, &regions.iter().flatten().copied().collect::<Vec<_>>());
        Self { order, regions, background }
    }

    /// The drawing alone: the background, then every region's path in painter's order.
    pub fn paths(&self) -> Vec<Path> {
        std::iter::once(self.background).chain(self.regions.iter().flatten().copied()).collect()
    }
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
        let drawn =
            raster::render_exact(&FallbackDrawing::new(&image, &segmentation).paths(), 96, 64, [1.0; 3]);
        let drawn = image::DynamicImage::ImageRgb8(drawn).to_rgb32f();
        let (ours, pixels) = (psnr(&drawn, &image), psnr(&exact, &image));
        assert!(ours > pixels - 1.5, "fitted outlines {ours:.2} dB, pixel regions {pixels:.2} dB");
    }

    #[test]
    fn enclosing_regions_are_painted_first() {
        let image = Rgb32FImage::from_fn(30, 30, |x, y| {
            if (10..20).contains(&x) && (10..20).contains(&y) {
                Rgb([1.0, 0.0, 0.0])
            } else {
                Rgb([0.0, 0.0, 1.0])
            }
        });
        let segmentation =
            slic(&image, &SlicOptions { n_segments: 2, compactness: 1.0, ..Default::default() }).unwrap();
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
