//! How much of a drawing lies outside the regions its paths were drawn for.

use infer::Placed;
use raster::coverage_exact;
use superpixel::Segmentation;

/// The share of the painted area of region paths (the background left out) that falls outside
/// their region dilated by `dilation` pixels (Chebyshev): 0 when every path stays in its region,
/// 1 when none does. Each path's coverage is measured on its own, as if nothing covered it.
pub fn spill(paths: &[Placed], segmentation: &Segmentation, dilation: u32) -> f64 {
    let (width, height) = (segmentation.width, segmentation.height);
    let (mut outside, mut total) = (0.0f64, 0.0f64);
    for placed in paths {
        let (Some(region), Some(mask)) = (placed.region, coverage_exact(&placed.shape, width, height)) else {
            continue;
        };
        for (index, &value) in mask.data().iter().enumerate() {
            if value == 0 {
                continue;
            }
            let coverage = value as f64 / 255.0;
            total += coverage;
            let (x, y) = (index as u32 % width, index as u32 / width);
            if !near(segmentation, region, x, y, dilation) {
                outside += coverage;
            }
        }
    }
    if total > 0.0 { outside / total } else { 0.0 }
}

/// Whether a pixel of `region` lies within `dilation` pixels of (x, y).
fn near(segmentation: &Segmentation, region: u32, x: u32, y: u32, dilation: u32) -> bool {
    let (x0, x1) = (x.saturating_sub(dilation), (x + dilation).min(segmentation.width - 1));
    let (y0, y1) = (y.saturating_sub(dilation), (y + dilation).min(segmentation.height - 1));
    (y0..=y1).any(|v| (x0..=x1).any(|u| segmentation.label(u, v) == region))
}

#[cfg(test)]
mod tests {
    use image::{Rgb, Rgb32FImage};
    use infer::Origin;
    use raster::Path;
    use superpixel::{SlicOptions, slic};

    use super::*;

    #[test]
    fn paths_inside_their_region_do_not_spill() {
        let image =
            Rgb32FImage::from_fn(
                40,
                20,
                |x, _| if x < 20 { Rgb([1.0, 0.0, 0.0]) } else { Rgb([0.0, 0.0, 1.0]) },
            );
        let segmentation = slic(&image, &SlicOptions { n_segments: 2, ..Default::default() }).unwrap();
        let left = segmentation.label(0, 0);
        let square = |x0: f32, x1: f32| {
            let path =
                Path::quadrilateral([[x0, 0.0], [x1, 0.0], [x1, 1.0], [x0, 1.0]], [1.0, 0.0, 0.0], 1.0);
            Placed { shape: path.into(), region: Some(left), origin: Origin::Coarse }
        };
        assert_eq!(spill(&[square(0.0, 0.5)], &segmentation, 0), 0.0);
        // The whole width: the right half (20 of 40 columns) spills, minus what dilation forgives.
        let half = spill(&[square(0.0, 1.0)], &segmentation, 0);
        assert!((half - 0.5).abs() < 1e-6, "{half}");
        assert!((spill(&[square(0.0, 1.0)], &segmentation, 2) - 18.0 / 40.0).abs() < 1e-6);
    }
}
