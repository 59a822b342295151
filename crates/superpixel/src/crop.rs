//! Cutting a region out for the model, and mapping what the model draws back onto the image.

use image::Rgb32FImage;

use common::PixelBox;

use crate::slic::Segmentation;

/// How regions are cut out and resized.
#[derive(Clone, Debug, PartialEq)]
pub struct CropOptions {
    /// Side of the square crop, the model's input size.
    pub size: usize,
    /// Pixels added around the region's bounding box (clamped to the image), so paths along the
    /// region's edge have room to anti-alias.
    pub padding: u32,
    /// Value of every channel outside the region's mask (the reference uses −1 for inputs in
    /// [0, 1]: distinct from any colour).
    pub fill: f32,
}

impl Default for CropOptions {
    fn default() -> Self {
        Self { size: 64, padding: 2, fill: -1.0 }
    }
}

/// The rectangle of the image (in pixels) that a crop's unit square was stretched from.
///
/// The stretch is non-uniform when the rectangle is not square, as in the method: a path drawn in
/// the crop's unit square lands on the rectangle through [`CropTransform::to_image`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CropTransform {
    /// Left edge in image pixels.
    pub x: f32,
    /// Top edge in image pixels.
    pub y: f32,
    /// Width in image pixels.
    pub width: f32,
    /// Height in image pixels.
    pub height: f32,
}

impl CropTransform {
    /// The transform of a pixel rectangle.
    pub fn of_box(bbox: PixelBox) -> Self {
        Self {
            x: bbox.x0() as f32,
            y: bbox.y0() as f32,
            width: bbox.width() as f32,
            height: bbox.height() as f32,
        }
    }

    /// A point of the crop's unit square in image pixels.
    pub fn to_image(&self, [u, v]: [f32; 2]) -> [f32; 2] {
        [self.x + u * self.width, self.y + v * self.height]
    }

    /// A point of the crop's unit square in the unit square of a `width × height` image (the
    /// coordinates paths of the whole image use).
    pub fn to_image_unit(&self, point: [f32; 2], width: u32, height: u32) -> [f32; 2] {
        let [x, y] = self.to_image(point);
        [x / width as f32, y / height as f32]
    }
}

/// One region cut out and resized to the model's input.
#[derive(Clone, Debug, PartialEq)]
pub struct RegionCrop {
    /// Side of the crop.
    pub size: usize,
    /// `[3, size, size]` planar: in each cell the mean colour of the region's pixels under it,
    /// `fill` where the cell is outside the mask. This is both the model input and the target.
    pub pixels: Vec<f32>,
    /// `[size, size]`: 1 where at least half of the cell lies in the region, else 0.
    pub mask: Vec<f32>,
    /// Where the crop came from.
    pub transform: CropTransform,
}

impl RegionCrop {
    /// The mean colour of the cells inside the mask (0 for an empty mask): the flat fill a
    /// drawing of the region must beat.
    pub fn mean_colour(&self) -> [f32; 3] {
        let cells = self.size * self.size;
        let area: f32 = self.mask.iter().sum::<f32>().max(1.0);
        std::array::from_fn(|c| {
            self.mask.iter().zip(&self.pixels[c * cells..(c + 1) * cells]).map(|(m, p)| m * p).sum::<f32>()
                / area
        })
    }
}

impl Segmentation {
    /// Cuts region `region` out of `image` (the image this segmentation was computed on).
    ///
    /// The bounding box, grown by `options.padding`, is resampled onto `size × size` cells by
    /// area: each cell averages the source pixels it overlaps, weighted by overlap, counting only
    /// pixels of the region for the colour.
    ///
    /// # Panics
    /// If `region` is not a label of this segmentation or the image size differs.
    pub fn crop(&self, image: &Rgb32FImage, region: u32, options: &CropOptions) -> RegionCrop {
        assert_eq!(image.dimensions(), (self.width, self.height), "image and segmentation differ in size");
        let padded = self.regions[region as usize].bbox.padded(options.padding, self.width, self.height);
        let transform = CropTransform::of_box(padded);
        let size = options.size;
        let mut pixels = vec![options.fill; 3 * size * size];
        let mut mask = vec![0.0; size * size];
        let columns = overlaps(transform.x, transform.width, size, self.width);
        let rows = overlaps(transform.y, transform.height, size, self.height);
        for (v, row) in rows.iter().enumerate() {
            for (u, column) in columns.iter().enumerate() {
                let (mut area, mut inside, mut color) = (0.0f32, 0.0f32, [0.0f32; 3]);
                for &(y, wy) in row {
                    for &(x, wx) in column {
                        let weight = wx * wy;
                        area += weight;
                        if self.label(x as u32, y as u32) == region {
                            inside += weight;
                            let p = image.get_pixel(x as u32, y as u32).0;
                            (0..3).for_each(|c| color[c] += weight * p[c]);
                        }
                    }
                }
                if inside >= 0.5 * area && inside > 0.0 {
                    mask[v * size + u] = 1.0;
                    (0..3).for_each(|c| pixels[(c * size + v) * size + u] = color[c] / inside);
                }
            }
        }
        RegionCrop { size, pixels, mask, transform }
    }
}

/// Area resampling of the rectangle `transform` of `image` onto `size × size` cells, `[3, S, S]`
/// planar: each cell is the overlap-weighted mean of the source pixels under it. Used to cut the
/// current canvas at a region's crop for the refinement model.
pub fn resample_area(image: &Rgb32FImage, transform: &CropTransform, size: usize) -> Vec<f32> {
    let columns = overlaps(transform.x, transform.width, size, image.width());
    let rows = overlaps(transform.y, transform.height, size, image.height());
    let mut out = vec![0.0; 3 * size * size];
    for (v, row) in rows.iter().enumerate() {
        for (u, column) in columns.iter().enumerate() {
            let (mut area, mut color) = (0.0f32, [0.0f32; 3]);
            for &(y, wy) in row {
                for &(x, wx) in column {
                    let p = image.get_pixel(x as u32, y as u32).0;
                    area += wx * wy;
                    (0..3).for_each(|c| color[c] += wx * wy * p[c]);
                }
            }
            (0..3).for_each(|c| out[(c * size + v) * size + u] = color[c] / area.max(f32::MIN_POSITIVE));
        }
    }
    out
}

/// For each of `size` output cells splitting `[start, start + extent)`, the source pixels
/// (within `0..limit`) it overlaps and by how much.
fn overlaps(start: f32, extent: f32, size: usize, limit: u32) -> Vec<Vec<(usize, f32)>> {
    let step = extent / size as f32;
    (0..size)
        .map(|cell| {
            let (a, b) = (start + cell as f32 * step, start + (cell + 1) as f32 * step);
            let first = (a.floor().max(0.0) as usize).min(limit as usize - 1);
            let last = (b.ceil() as usize).clamp(first + 1, limit as usize);
            (first..last)
                .filter_map(|pixel| {
                    let overlap = b.min(pixel as f32 + 1.0) - a.max(pixel as f32);
                    (overlap > 0.0).then_some((pixel, overlap))
                })
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_square_corners_map_to_the_box_corners() {
        let bbox = PixelBox::new(10, 20, 50, 35).unwrap();
        let t = CropTransform::of_box(bbox);
        assert_eq!(t.to_image([0.0, 0.0]), [10.0, 20.0]);
        assert_eq!(t.to_image([1.0, 1.0]), [50.0, 35.0]);
        assert_eq!(t.to_image([1.0, 0.0]), [50.0, 20.0]);
        assert_eq!(t.to_image_unit([1.0, 1.0], 100, 70), [0.5, 0.5]);
    }

    #[test]
    fn overlaps_split_pixels_by_area() {
        let cells = overlaps(1.0, 3.0, 2, 10);
        assert_eq!(cells, vec![vec![(1, 1.0), (2, 0.5)], vec![(2, 0.5), (3, 1.0)]]);
        // Upsampling: every cell lies inside one source pixel.
        let cells = overlaps(4.0, 1.0, 4, 10);
        assert!(cells.iter().all(|c| c.len() == 1 && c[0].0 == 4));
    }

    #[test]
    fn resampling_a_flat_image_keeps_its_colour() {
        let image = Rgb32FImage::from_pixel(9, 7, image::Rgb([0.2, 0.4, 0.6]));
        let t = CropTransform { x: 1.0, y: 2.0, width: 7.0, height: 3.0 };
        let out = resample_area(&image, &t, 5);
        assert!(out[..25].iter().all(|v| (v - 0.2).abs() < 1e-6));
        assert!(out[50..].iter().all(|v| (v - 0.6).abs() < 1e-6));
    }
}
