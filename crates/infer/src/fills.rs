//! What the fallback fills its regions with: each region's mean colour, or the best linear ramp
//! through its pixels ([`common::Moments::linear_fit`], closed form), where the ramp pays.
//!
//! A ramp adds a `linearGradient` to the SVG (about [`RAMP_BYTES`]); the bytes are worth it
//! where it takes away more error than the same bytes buy as regions. What a region buys is
//! read off Ward's merge tree at the drawn cut (the error its last merges add, a region each)
//! and what it costs from the drawing (its regions' mean bytes): one price per byte for the
//! whole drawing, the same for every ramp. The regions themselves are merged knowing that they
//! may be ramps ([`superpixel::RegionFill::Ramp`], at that price per byte), so a smooth shading
//! is one region, not bands.

use common::{LinearFit, Moments};
use image::Rgb32FImage;
use raster::{Decimals, Filled, Outline, Ramp};
use superpixel::Segmentation;

/// Which regions get a ramp.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Ramps {
    /// None: every region in its mean colour.
    #[default]
    None,
    /// Every region whose pixels a ramp fits better than their mean colour.
    Every,
    /// The regions whose ramp takes away more error than its bytes would as regions:
    /// `region_worth` is the error one more region takes away at this cut (squared RGB error
    /// summed over pixels, as [`superpixel::Hierarchy::fill_error`] counts it).
    Paying {
        /// Error a region takes away at the drawn cut.
        region_worth: f64,
    },
}

/// Bytes a ramp adds to the SVG: its `linearGradient` at 2 decimals on a 512-pixel canvas
/// (`<linearGradient id="ab" gradientUnits="userSpaceOnUse" x1="123.45" … </linearGradient>`,
/// 188 bytes) and the longer `fill="url(#ab)"`.
pub const RAMP_BYTES: f64 = 189.0;

/// Bytes a region's `<path>` element takes on data/eval/photos at 500 paths (382 on average;
/// 212 at 2000): what the merge tree prices a ramp in before any region is traced (the drawing
/// then measures its own, [`Ramps::Paying`]).
pub const REGION_BYTES: f64 = 382.0;

/// Bytes a region's `<path>` element takes besides its path data (`<path d="" fill="#rrggbb"
/// fill-rule="nonzero"/>` and a line break).
const PATH_ELEMENT_BYTES: f64 = 44.0;

/// For each of `outlines` (region `order[i]` of `segmentation`, made on `image`), the ramp
/// `rule` gives it (in the unit square), or `None` to keep its mean colour.
pub(crate) fn region_ramps(
    image: &Rgb32FImage,
    segmentation: &Segmentation,
    order: &[u32],
    outlines: &[Option<Outline>],
    rule: Ramps,
) -> Vec<Option<Ramp>> {
    let (width, height) = image.dimensions();
    let threshold = match rule {
        Ramps::None => return vec![None; outlines.len()],
        Ramps::Every => 0.0,
        Ramps::Paying { region_worth } => region_worth * RAMP_BYTES / mean_bytes(outlines, (width, height)),
    };
    let center = |i: usize| [(i % width as usize) as f32 + 0.5, (i / width as usize) as f32 + 0.5];
    let moments = Moments::per_label(image, &segmentation.labels, segmentation.regions.len());
    let fits: Vec<Option<LinearFit>> =
        moments.iter().map(|m| m.linear_fit().filter(|fit| fit.reduction > threshold)).collect();
    // How far each fitted region's pixels reach along its ramp: the ramp's ends.
    let mut extents = vec![(f64::INFINITY, f64::NEG_INFINITY); fits.len()];
    for (i, &label) in segmentation.labels.iter().enumerate() {
        if let Some(fit) = &fits[label as usize] {
            let along = fit.along(center(i));
            let extent = &mut extents[label as usize];
            *extent = (extent.0.min(along), extent.1.max(along));
        }
    }
    let unit = |[x, y]: [f32; 2]| [x / width as f32, y / height as f32];
    order
        .iter()
        .zip(outlines)
        .map(|(&region, outline)| {
            outline.as_ref()?;
            let (low, high) = extents[region as usize];
            Some(fits[region as usize]?.ramp(low, high)?.map_points(unit))
        })
        .collect()
}

/// The mean bytes of the `<path>` elements of `outlines` on a `size` canvas at 2 decimals.
fn mean_bytes(outlines: &[Option<Outline>], (width, height): (u32, u32)) -> f64 {
    let mut data = String::new();
    let mut count = 0usize;
    for outline in outlines.iter().flatten() {
        outline.svg_data([width as f32, height as f32], Decimals::new(2), &mut data);
        count += 1;
    }
    data.len() as f64 / count.max(1) as f64 + PATH_ELEMENT_BYTES
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use image::Rgb;
    use raster::{Fill, Filled, Outline, Shape};
    use superpixel::{SlicOptions, slic};

    use super::*;
    use crate::fallback::{FallbackDrawing, Style};
    use crate::finetune::{FinetuneOptions, Limit, finetune};
    use crate::scene::Scene;

    /// A sky (a vertical ramp) over flat ground with a flat disc on it.
    fn sky_and_ground() -> Rgb32FImage {
        Rgb32FImage::from_fn(96, 64, |x, y| {
            let (dx, dy) = (x as f32 - 70.0, y as f32 - 48.0);
            if dx * dx + dy * dy < 64.0 {
                Rgb([0.9, 0.8, 0.1])
            } else if y < 36 {
                let t = y as f32 / 36.0;
                Rgb([0.2 + 0.5 * t, 0.4 + 0.4 * t, 0.9 - 0.1 * t])
            } else {
                Rgb([0.3, 0.5, 0.2])
            }
        })
    }

    fn drawing(image: &Arc<Rgb32FImage>, ramps: Ramps) -> FallbackDrawing {
        let segmentation = slic(image, &SlicOptions { n_segments: 12, ..Default::default() }).unwrap();
        FallbackDrawing::new(image, &Arc::new(segmentation), Style { tolerance: None, ramps })
    }

    fn ramps(drawing: &FallbackDrawing) -> usize {
        let ramp = |shape: &Shape| matches!(shape.fill(), Fill::Linear(_));
        drawing.regions.iter().flatten().filter(|shape| ramp(shape)).count()
    }

    #[test]
    fn ramps_draw_the_sky_better_than_mean_colours() {
        let image = Arc::new(sky_and_ground());
        let flat = drawing(&image, Ramps::None);
        let linear = drawing(&image, Ramps::Every);
        assert_eq!(ramps(&flat), 0);
        // The sky's regions get ramps; what is left is mostly the regions that straddle the
        // horizon or the disc's edge.
        assert!(ramps(&linear) >= 3, "{} ramps", ramps(&linear));
        assert!(linear.error < 0.6 * flat.error, "{} against flat {}", linear.error, flat.error);
    }

    /// SuperSVG-F moves a ramp with its outline: starting from the sky's ramps turned around,
    /// it draws better and the sky's regions leave it ramped, their ramps moved.
    #[test]
    fn fine_tuning_moves_ramps() {
        let image = Arc::new(sky_and_ground());
        let segmentation =
            Arc::new(slic(&image, &SlicOptions { n_segments: 12, ..Default::default() }).unwrap());
        let linear =
            FallbackDrawing::new(&image, &segmentation, Style { tolerance: None, ramps: Ramps::Every });
        let turned = |shape: &Shape| match (shape, shape.fill()) {
            (Shape::Outline(outline), Fill::Linear(ramp)) => {
                let ramp = raster::Ramp { stops: [ramp.stops[1], ramp.stops[0]], ..ramp };
                let mut outline: Outline = (**outline).clone();
                outline.fill = Fill::Linear(ramp);
                Shape::from(outline)
            }
            _ => shape.clone(),
        };
        let mut scene = Scene::drawn(image.clone(), segmentation, linear.placed(), linear.canvas.clone());
        let start: Vec<Shape> = scene.scene().iter().map(turned).collect();
        scene.set_shapes(&start);
        let before = scene.total_error();
        finetune(&mut scene, &FinetuneOptions { limit: Limit::Steps(60), ..FinetuneOptions::default() });
        assert!(scene.total_error() < 0.5 * before, "{} against {before}", scene.total_error());
        let fills: Vec<Fill> = scene.scene().iter().map(Shape::fill).collect();
        let ramped = fills.iter().filter(|fill| matches!(fill, Fill::Linear(_))).count();
        assert_eq!(ramped, ramps(&linear));
        let moved = start
            .iter()
            .zip(&fills)
            .filter(|(shape, fill)| matches!(fill, Fill::Linear(_)) && shape.fill() != **fill);
        assert_eq!(moved.count(), ramped);
    }

    #[test]
    fn a_ramp_that_does_not_pay_for_its_bytes_is_not_drawn() {
        let image = Arc::new(sky_and_ground());
        let every = drawing(&image, Ramps::Every);
        // A region worth more than any ramp's gain buys no ramp; one worth nothing buys them all.
        let costly = drawing(&image, Ramps::Paying { region_worth: 1e9 });
        let free = drawing(&image, Ramps::Paying { region_worth: 0.0 });
        assert_eq!((ramps(&costly), costly.error), (0, drawing(&image, Ramps::None).error));
        assert_eq!((ramps(&free), free.error), (ramps(&every), every.error));
    }
}
