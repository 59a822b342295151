//! Reading an input image at the working resolution, whatever its format or size.

use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use image::imageops::FilterType;
use image::{ImageFormat, ImageReader, Limits, Rgb, Rgb32FImage};

/// Images with more pixels than this are never decoded whole: PNGs are streamed row by row into
/// the working resolution, other formats are refused. 64 Mpx of 8-bit RGBA is 256 MiB.
const MAX_DECODED_PIXELS: u64 = 64 << 20;

/// Why an input image cannot be used; the message names the file.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {message}")]
pub struct DecodeError {
    /// The input file.
    pub path: PathBuf,
    /// What is wrong with it.
    pub message: String,
}

/// An input image scaled to the working resolution.
pub struct Loaded {
    /// RGB in [0, 1] (grey expanded, transparency over white), long side at most the working
    /// size.
    pub image: Rgb32FImage,
    /// Width and height of the file, which the SVG keeps.
    pub original: (u32, u32),
}

/// Reads `path` (png, jpeg, webp, gif — first frame —, bmp, tiff; any bit depth), scaled down
/// so its long side is at most `long_side` (never up).
pub fn load(path: &Path, long_side: u32) -> Result<Loaded, DecodeError> {
    let fail = |message: String| DecodeError { path: path.to_path_buf(), message };
    let reader = ImageReader::open(path)
        .and_then(ImageReader::with_guessed_format)
        .map_err(|err| fail(err.to_string()))?;
    let format = reader.format().ok_or_else(|| fail("not an image in a known format".into()))?;
    let (width, height) = reader.into_dimensions().map_err(|err| fail(err.to_string()))?;
    if width == 0 || height == 0 {
        return Err(fail(format!("the image is empty ({width}×{height})")));
    }
    let (target_width, target_height) = fit(width, height, long_side);
    let image = if u64::from(width) * u64::from(height) <= MAX_DECODED_PIXELS {
        let mut reader = ImageReader::open(path)
            .and_then(ImageReader::with_guessed_format)
            .map_err(|err| fail(err.to_string()))?;
        let mut limits = Limits::default();
        limits.max_alloc = Some(MAX_DECODED_PIXELS * 16);
        reader.limits(limits);
        let decoded = reader.decode().map_err(|err| fail(err.to_string()))?;
        let rgb = superpixel::to_rgb_over_white(&decoded).map_err(|err| fail(err.to_string()))?;
        if (target_width, target_height) == (width, height) {
            rgb
        } else {
            image::imageops::resize(&rgb, target_width, target_height, FilterType::Triangle)
        }
    } else if format == ImageFormat::Png {
        stream_png(path, (width, height), (target_width, target_height)).map_err(fail)?
    } else {
        return Err(fail(format!(
            "the image is too large to decode ({width}×{height}); convert it to PNG, which is read \
             row by row at any size, or scale it below {} Mpx",
            MAX_DECODED_PIXELS >> 20
        )));
    };
    Ok(Loaded { image, original: (width, height) })
}

/// The size with the same aspect ratio whose long side is at most `long_side`.
fn fit(width: u32, height: u32, long_side: u32) -> (u32, u32) {
    let long = width.max(height);
    if long <= long_side {
        return (width, height);
    }
    let scale = long_side as f64 / long as f64;
    (((width as f64 * scale).round() as u32).max(1), ((height as f64 * scale).round() as u32).max(1))
}

/// Decodes a non-interlaced PNG row by row, averaging source pixels into the cells of a
/// `target` grid, so memory holds one source row and the small output.
fn stream_png(path: &Path, (width, height): (u32, u32), (tw, th): (u32, u32)) -> Result<Rgb32FImage, String> {
    let file = File::open(path).map_err(|err| err.to_string())?;
    let mut decoder = png::Decoder::new(BufReader::new(file));
    decoder.set_transformations(png::Transformations::normalize_to_color8());
    let mut reader = decoder.read_info().map_err(|err| err.to_string())?;
    if reader.info().interlaced {
        return Err(format!("the image is too large ({width}×{height}) to decode whole, and interlaced"));
    }
    let channels = match reader.output_color_type().0 {
        png::ColorType::Grayscale => 1,
        png::ColorType::GrayscaleAlpha => 2,
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        png::ColorType::Indexed => return Err("unexpanded palette".into()),
    };
    let mut sums = vec![[0.0f64; 4]; (tw * th) as usize];
    let column_cell: Vec<usize> =
        (0..width).map(|x| (x as u64 * tw as u64 / width as u64) as usize).collect();
    let mut y = 0u32;
    while let Some(row) = reader.next_row().map_err(|err| err.to_string())? {
        let cell_row = (y as u64 * th as u64 / height as u64) as usize;
        for (x, pixel) in row.data().chunks_exact(channels).enumerate() {
            let (rgb, alpha) = match pixel {
                [g] => ([*g; 3], 255),
                [g, a] => ([*g; 3], *a),
                [r, g, b] => ([*r, *g, *b], 255),
                [r, g, b, a] => ([*r, *g, *b], *a),
                _ => unreachable!("chunks of the channel count"),
            };
            let a = alpha as f64 / 255.0;
            let cell = &mut sums[cell_row * tw as usize + column_cell[x]];
            for c in 0..3 {
                cell[c] += rgb[c] as f64 / 255.0 * a + (1.0 - a);
            }
            cell[3] += 1.0;
        }
        y += 1;
    }
    if y != height {
        return Err(format!("truncated: {y} of {height} rows"));
    }
    Ok(Rgb32FImage::from_fn(tw, th, |x, y| {
        let cell = sums[(y * tw + x) as usize];
        let n = cell[3].max(1.0);
        Rgb([(cell[0] / n) as f32, (cell[1] / n) as f32, (cell[2] / n) as f32])
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fitting_keeps_the_aspect_ratio_and_never_upscales() {
        assert_eq!(fit(1024, 512, 512), (512, 256));
        assert_eq!(fit(300, 200, 512), (300, 200));
        assert_eq!(fit(30000, 1, 512), (512, 1));
    }
}
