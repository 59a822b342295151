//! Reading an input image at the working resolution, whatever its format or size.

use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use image::imageops::FilterType;
use image::metadata::Orientation;
use image::{DynamicImage, ImageDecoder, ImageFormat, ImageReader, Limits, Rgb, Rgb32FImage};

/// Images with more pixels than this are never decoded whole: PNGs are streamed row by row into
/// the working resolution, other formats are refused. 64 Mpx of 8-bit RGBA is 256 MiB.
const MAX_DECODED_PIXELS: u64 = 64 << 20;

/// Why an input image cannot be used, with the file.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {problem}")]
pub struct DecodeError {
    /// The input file.
    pub path: PathBuf,
    /// What is wrong with it.
    #[source]
    pub problem: DecodeProblem,
}

/// What is wrong with an input image. The decoders' own errors are shown, not chained: their
/// messages already include their causes.
#[derive(Debug, thiserror::Error)]
pub enum DecodeProblem {
    /// The file cannot be read.
    #[error("{0}")]
    Io(std::io::Error),
    /// The first bytes are no image format this program reads.
    #[error("not an image in a known format")]
    UnknownFormat,
    /// The decoder refused the file.
    #[error("{0}")]
    Image(image::ImageError),
    /// The PNG stream decoder refused the file.
    #[error("{0}")]
    Png(png::DecodingError),
    /// The decoded pixels could not be turned into RGB.
    #[error("{0}")]
    Pixels(superpixel::InputError),
    /// The image has no pixels.
    #[error("the image is empty ({width}×{height})")]
    Empty {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
    },
    /// A JPEG cut short (refused unless truncation is allowed).
    #[error(
        "truncated: the JPEG ends before its end-of-image marker (--allow-truncated draws what is there)"
    )]
    TruncatedJpeg,
    /// A streamed PNG ended early.
    #[error("truncated: {rows} of {height} rows")]
    TruncatedPng {
        /// Rows decoded.
        rows: u32,
        /// Rows the header announced.
        height: u32,
    },
    /// Too many pixels to decode whole, in a format that cannot be streamed.
    #[error(
        "the image is too large to decode ({width}×{height}); convert it to PNG, which is read row by row \
         at any size, or scale it below {max} Mpx",
        max = MAX_DECODED_PIXELS >> 20
    )]
    TooLarge {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
    },
    /// Too many pixels to decode whole, and interlaced, so it cannot be streamed row by row.
    #[error("the image is too large ({width}×{height}) to decode whole, and interlaced")]
    InterlacedTooLarge {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
    },
    /// A PNG whose palette the decoder did not expand.
    #[error("unexpanded palette")]
    UnexpandedPalette,
}

/// An input image scaled to the working resolution.
pub struct Loaded {
    /// RGB in [0, 1] (grey expanded, transparency over white), long side at most the working
    /// size.
    pub image: Rgb32FImage,
    /// Width and height of the file, which the SVG keeps.
    pub original: (u32, u32),
}

/// How [`load_with`] reads an image.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadOptions {
    /// The long side is scaled down to at most this many pixels (never up).
    pub long_side: u32,
    /// Decode a JPEG cut short as far as it goes (the decoder fills the rest) instead of
    /// refusing it.
    pub allow_truncated: bool,
    /// Transparent pixels are composited over this colour (RGB in [0, 1]).
    pub background: [f32; 3],
}

impl Default for LoadOptions {
    fn default() -> Self {
        Self { long_side: 512, allow_truncated: false, background: [1.0; 3] }
    }
}

/// Reads `path` (png, jpeg, webp, gif — first frame —, bmp, tiff; any bit depth), turned as its
/// EXIF orientation says, over white, scaled down so its long side is at most `long_side`
/// (never up). A truncated file is an error.
pub fn load(path: &Path, long_side: u32) -> Result<Loaded, DecodeError> {
    load_with(path, &LoadOptions { long_side, ..LoadOptions::default() })
}

/// [`load`] with every option.
pub fn load_with(path: &Path, options: &LoadOptions) -> Result<Loaded, DecodeError> {
    let (long_side, allow_truncated, background) =
        (options.long_side, options.allow_truncated, options.background);
    let fail = |problem: DecodeProblem| DecodeError { path: path.to_path_buf(), problem };
    let reader = ImageReader::open(path)
        .and_then(ImageReader::with_guessed_format)
        .map_err(|err| fail(DecodeProblem::Io(err)))?;
    let format = reader.format().ok_or_else(|| fail(DecodeProblem::UnknownFormat))?;
    let (width, height) = reader.into_dimensions().map_err(|err| fail(DecodeProblem::Image(err)))?;
    if width == 0 || height == 0 {
        return Err(fail(DecodeProblem::Empty { width, height }));
    }
    if format == ImageFormat::Jpeg && !allow_truncated {
        // The JPEG decoder fills a missing end with grey and says nothing.
        let bytes = std::fs::read(path).map_err(|err| fail(DecodeProblem::Io(err)))?;
        if !jpeg_is_complete(&bytes) {
            return Err(fail(DecodeProblem::TruncatedJpeg));
        }
    }
    let (image, original) = if u64::from(width) * u64::from(height) <= MAX_DECODED_PIXELS {
        let mut reader = ImageReader::open(path)
            .and_then(ImageReader::with_guessed_format)
            .map_err(|err| fail(DecodeProblem::Io(err)))?;
        let mut limits = Limits::default();
        limits.max_alloc = Some(MAX_DECODED_PIXELS * 16);
        reader.limits(limits);
        let mut decoder = reader.into_decoder().map_err(|err| fail(DecodeProblem::Image(err)))?;
        // A camera's EXIF orientation (JPEG, WebP, TIFF): the picture as it is shown.
        let orientation = decoder.orientation().unwrap_or(Orientation::NoTransforms);
        let mut decoded =
            DynamicImage::from_decoder(decoder).map_err(|err| fail(DecodeProblem::Image(err)))?;
        decoded.apply_orientation(orientation);
        let rgb =
            superpixel::to_rgb_over(&decoded, background).map_err(|err| fail(DecodeProblem::Pixels(err)))?;
        let (width, height) = rgb.dimensions();
        let (target_width, target_height) = fit(width, height, long_side);
        let image = if (target_width, target_height) == (width, height) {
            rgb
        } else {
            image::imageops::resize(&rgb, target_width, target_height, FilterType::Triangle)
        };
        (image, (width, height))
    } else if format == ImageFormat::Png {
        let target = fit(width, height, long_side);
        (stream_png(path, (width, height), target, background).map_err(fail)?, (width, height))
    } else {
        return Err(fail(DecodeProblem::TooLarge { width, height }));
    };
    Ok(Loaded { image, original })
}

/// Whether a JPEG's last scan (marker FF DA) is followed by its end-of-image marker (FF D9).
/// Inside a scan, FF is always followed by 00 or a restart marker, so FF D9 there is the real
/// end; data some cameras append after it is allowed.
fn jpeg_is_complete(bytes: &[u8]) -> bool {
    let last = |marker: u8| bytes.windows(2).rposition(|w| w == [0xFF, marker]);
    match (last(0xDA), last(0xD9)) {
        (Some(scan), Some(end)) => end > scan,
        _ => false,
    }
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
fn stream_png(
    path: &Path,
    (width, height): (u32, u32),
    (tw, th): (u32, u32),
    background: [f32; 3],
) -> Result<Rgb32FImage, DecodeProblem> {
    let file = File::open(path).map_err(DecodeProblem::Io)?;
    let mut decoder = png::Decoder::new(BufReader::new(file));
    decoder.set_transformations(png::Transformations::normalize_to_color8());
    let mut reader = decoder.read_info().map_err(DecodeProblem::Png)?;
    if reader.info().interlaced {
        return Err(DecodeProblem::InterlacedTooLarge { width, height });
    }
    let channels = match reader.output_color_type().0 {
        png::ColorType::Grayscale => 1,
        png::ColorType::GrayscaleAlpha => 2,
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        png::ColorType::Indexed => return Err(DecodeProblem::UnexpandedPalette),
    };
    let mut sums = vec![[0.0f64; 4]; (tw * th) as usize];
    let column_cell: Vec<usize> =
        (0..width).map(|x| (x as u64 * tw as u64 / width as u64) as usize).collect();
    let mut y = 0u32;
    while let Some(row) = reader.next_row().map_err(DecodeProblem::Png)? {
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
                cell[c] += rgb[c] as f64 / 255.0 * a + background[c] as f64 * (1.0 - a);
            }
            cell[3] += 1.0;
        }
        y += 1;
    }
    if y != height {
        return Err(DecodeProblem::TruncatedPng { rows: y, height });
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
    fn exif_orientation_turns_the_picture() {
        use image::codecs::jpeg::JpegEncoder;
        use image::{ImageEncoder, RgbImage};
        // 40 × 20, red on the left half. EXIF (little-endian TIFF) with one entry:
        // Orientation (0x0112) = 6, "rotate 90° clockwise to display".
        let picture =
            RgbImage::from_fn(40, 20, |x, _| if x < 20 { Rgb([250, 0, 0]) } else { Rgb([0, 0, 250]) });
        let exif: Vec<u8> = [
            &b"II*\0"[..],
            &8u32.to_le_bytes(),
            &1u16.to_le_bytes(),
            &0x0112u16.to_le_bytes(),
            &3u16.to_le_bytes(),
            &1u32.to_le_bytes(),
            &[6, 0, 0, 0],
            &0u32.to_le_bytes(),
        ]
        .concat();
        let mut bytes = Vec::new();
        let mut encoder = JpegEncoder::new_with_quality(&mut bytes, 95);
        encoder.set_exif_metadata(exif).unwrap();
        encoder.write_image(&picture, 40, 20, image::ExtendedColorType::Rgb8).unwrap();
        let path = std::env::temp_dir().join(format!("supersvg-exif-{}.jpg", std::process::id()));
        std::fs::write(&path, &bytes).unwrap();
        let loaded = load(&path, 512).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(loaded.original, (20, 40), "turned upright");
        assert_eq!(loaded.image.dimensions(), (20, 40));
        // Rotated clockwise, the left (red) half is now on top.
        assert!(loaded.image.get_pixel(10, 5)[0] > 0.8 && loaded.image.get_pixel(10, 35)[2] > 0.8);
    }

    #[test]
    fn truncated_jpegs_are_refused_unless_allowed() {
        let picture = image::RgbImage::from_fn(64, 48, |x, y| Rgb([(x * 4) as u8, (y * 5) as u8, 90]));
        let mut bytes = Vec::new();
        picture.write_to(&mut std::io::Cursor::new(&mut bytes), ImageFormat::Jpeg).unwrap();
        let dir = std::env::temp_dir().join(format!("supersvg-truncated-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (whole, half, trailer) = (dir.join("whole.jpg"), dir.join("half.jpg"), dir.join("trailer.jpg"));
        std::fs::write(&whole, &bytes).unwrap();
        // Cut inside the scan data: the headers are whole, the picture is not.
        let scan = bytes.windows(2).rposition(|w| w == [0xFF, 0xDA]).unwrap();
        std::fs::write(&half, &bytes[..(scan + bytes.len()) / 2]).unwrap();
        std::fs::write(&trailer, [&bytes[..], b"SEFH appended by a camera"].concat()).unwrap();
        assert!(load(&whole, 512).is_ok());
        assert!(load(&trailer, 512).is_ok());
        let Err(err) = load(&half, 512) else { panic!("a truncated JPEG was accepted") };
        assert!(matches!(err.problem, DecodeProblem::TruncatedJpeg) && err.path == half, "{err:?}");
        let allowed = LoadOptions { long_side: 512, allow_truncated: true, ..LoadOptions::default() };
        assert_eq!(load_with(&half, &allowed).unwrap().image.dimensions(), (64, 48));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn fitting_keeps_the_aspect_ratio_and_never_upscales() {
        assert_eq!(fit(1024, 512, 512), (512, 256));
        assert_eq!(fit(300, 200, 512), (300, 200));
        assert_eq!(fit(30000, 1, 512), (512, 1));
    }
}
