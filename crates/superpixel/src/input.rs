//! Turning any decoded image into the RGB buffer the pipeline works on.

use image::{DynamicImage, Rgb32FImage};

/// Why an image cannot be used.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum InputError {
    /// The image has no pixels.
    #[error("the image is empty ({width}×{height})")]
    Empty {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
    },
}

/// RGB in [0, 1] of any decoded image: grey is expanded, 16-bit and float inputs are rescaled,
/// and transparent pixels are composited over white (what a viewer shows on a white page).
pub fn to_rgb_over_white(image: &DynamicImage) -> Result<Rgb32FImage, InputError> {
    to_rgb_over(image, [1.0; 3])
}

/// [`to_rgb_over_white`] with transparent pixels composited over `background` (RGB in [0, 1]).
pub fn to_rgb_over(image: &DynamicImage, background: [f32; 3]) -> Result<Rgb32FImage, InputError> {
    let (width, height) = (image.width(), image.height());
    if width == 0 || height == 0 {
        return Err(InputError::Empty { width, height });
    }
    let rgba = image.to_rgba32f();
    let pixels = rgba
        .pixels()
        .flat_map(|p| {
            let [r, g, b, a] = p.0.map(|v| if v.is_finite() { v.clamp(0.0, 1.0) } else { 0.0 });
            [0, 1, 2].map(|c| [r, g, b][c] * a + background[c] * (1.0 - a))
        })
        .collect();
    Ok(Rgb32FImage::from_raw(width, height, pixels).expect("buffer matches the image"))
}

#[cfg(test)]
mod tests {
    use image::{GrayImage, ImageBuffer, Luma, Rgba};

    use super::*;

    #[test]
    fn grey_rgba_and_16_bit_become_rgb() {
        let grey = DynamicImage::ImageLuma8(GrayImage::from_pixel(2, 1, Luma([51])));
        assert!(to_rgb_over_white(&grey).unwrap().get_pixel(1, 0).0.iter().all(|c| (c - 0.2).abs() < 1e-6));
        let half_red = ImageBuffer::from_pixel(1, 1, Rgba([255u8, 0, 0, 128]));
        let rgb = to_rgb_over_white(&DynamicImage::ImageRgba8(half_red)).unwrap();
        let [r, g, b] = rgb.get_pixel(0, 0).0;
        assert!(r == 1.0 && (g - 0.498).abs() < 0.01 && (b - g).abs() < 1e-6);
        let deep = ImageBuffer::from_pixel(1, 1, Luma([65535u16]));
        assert_eq!(to_rgb_over_white(&DynamicImage::ImageLuma16(deep)).unwrap().get_pixel(0, 0).0, [1.0; 3]);
    }

    #[test]
    fn empty_image_is_an_error() {
        let black = to_rgb_over(
            &DynamicImage::ImageRgba8(ImageBuffer::from_pixel(1, 1, Rgba([255, 0, 0, 0]))),
            [0.0, 0.5, 0.0],
        )
        .unwrap();
        assert_eq!(black.get_pixel(0, 0).0, [0.0, 0.5, 0.0], "fully transparent shows the background");
        let empty = DynamicImage::ImageLuma8(GrayImage::new(0, 3));
        assert_eq!(to_rgb_over_white(&empty), Err(InputError::Empty { width: 0, height: 3 }));
    }
}
