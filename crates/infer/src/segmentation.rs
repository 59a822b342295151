//! The first stage: how an image is split into regions.
//!
//! An image is over-segmented once and merged bottom-up into a tree ([`hierarchy`],
//! [`superpixel::Hierarchy`]): every region count is a cut of it, and the error of each cut's
//! flat fill is known without drawing it. The budget ([`crate::budget`]) decides where it is
//! cut and prices the regions merged away for the networks' paths on it.

use std::sync::Arc;

use image::Rgb32FImage;
use superpixel::{Hierarchy, SegmentOptions, Segmentation, SlicError};

use crate::fallback::{FallbackDrawing, Style};

/// The fewest pixels per region: SLIC cannot place centres closer than 4 × 4 pixels
/// meaningfully, and one path per pixel would only copy the raster.
pub const PIXELS_PER_REGION: usize = 16;

/// The most regions an image of `width × height` pixels is split into ([`PIXELS_PER_REGION`]).
pub fn max_regions(width: u32, height: u32) -> usize {
    (width as usize * height as usize / PIXELS_PER_REGION).max(1)
}

/// An image's regions for a budget: the merge tree of its over-segmentation, the cut of it that
/// is drawn, and that cut's fallback drawing (traced, rendered and scored once).
pub struct Segmented {
    /// Every region count of the image, as Ward's merges reach it: the coarse stage prices
    /// the regions it merges away to make room for E_c's paths with it, and cuts it again.
    pub hierarchy: Hierarchy,
    /// The regions drawn.
    pub segmentation: Arc<Segmentation>,
    /// Each region's outline in its fill over the background, with its rendering.
    pub fallback: FallbackDrawing,
}

impl Segmented {
    /// `image` split into `regions` regions of `hierarchy` (made on `image`), with its fallback
    /// drawing in `style`.
    pub fn new(image: &Arc<Rgb32FImage>, hierarchy: Hierarchy, regions: usize, style: Style) -> Self {
        let segmentation = Arc::new(hierarchy.cut(image, regions));
        let fallback = FallbackDrawing::new(image, &segmentation, style);
        Self { hierarchy, segmentation, fallback }
    }
}

/// The merge tree of `image` for up to `regions` regions: the over-segmentation
/// [`SegmentOptions::ward`] makes at `compactness` (flat art's areas of one colour, else SLIC),
/// merged down to one region.
pub fn hierarchy(image: &Rgb32FImage, regions: usize, compactness: f32) -> Result<Hierarchy, SlicError> {
    let base = SegmentOptions::ward(compactness).over_segment(image, regions)?;
    Ok(Hierarchy::new(image, base))
}

#[cfg(test)]
mod tests {
    use image::Rgb;
    use raster::render_exact;

    use super::*;

    /// Flat art with edges that round regions straddle: diagonal bands and a disc.
    fn bands_and_disc() -> Rgb32FImage {
        Rgb32FImage::from_fn(96, 96, |x, y| {
            let (dx, dy) = (x as f32 - 60.0, y as f32 - 40.0);
            if dx * dx + dy * dy < 20.0 * 20.0 {
                Rgb([0.9, 0.2, 0.1])
            } else if (x + 2 * y) / 11 % 2 == 0 {
                Rgb([0.1, 0.3, 0.8])
            } else {
                Rgb([1.0, 0.9, 0.6])
            }
        })
    }

    #[test]
    fn the_drawn_regions_are_the_trees_cut_and_its_fallback_is_scored_exactly() {
        let image = Arc::new(bands_and_disc());
        let regions = 24;
        let segmented =
            Segmented::new(&image, hierarchy(&image, regions, 30.0).unwrap(), regions, Style::default());
        assert_eq!(segmented.segmentation.regions.len(), regions);
        assert_eq!(segmented.fallback.regions.len(), regions);
        let flat = segmented.segmentation.flat_error(&image);
        let read = segmented.hierarchy.fill_error(regions);
        // (The tree sums its merges' costs in f64 from f32 means: a few parts in a million.)
        assert!((flat - read).abs() <= 1e-5 * flat, "the tree's {read} against the cut's {flat}");
        // What merging freely buys where round regions cannot follow the picture: better than
        // the method's own superpixels (plain SLIC at 30).
        let method = Arc::new(superpixel::segment(&image, regions, &SegmentOptions::default()).unwrap());
        let method_error = FallbackDrawing::new(&image, &method, Style::default()).error;
        assert!(
            segmented.fallback.error < 0.5 * method_error,
            "{} against plain SLIC's {method_error}",
            segmented.fallback.error
        );
        // The score is the exact rendering's error.
        let drawn =
            image::DynamicImage::ImageRgb8(render_exact(&segmented.fallback.paths(), 96, 96, [1.0; 3]));
        let mse = common::mse(&drawn.to_rgb32f(), &image);
        assert!((mse - segmented.fallback.mse()).abs() < 1e-9, "{mse} vs {}", segmented.fallback.mse());
    }
}
