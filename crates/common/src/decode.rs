//! Reading an input image at the working resolution, whatever its format or size, from a file
//! or from bytes in memory (stdin, a Python caller): the one decoder inference, evaluation and
//! training share, so every crate sees the same pixels of the same file.

use std::fs::File;
use std::io::{BufRead, BufReader, Cursor, Read, Seek};
use std::ops::RangeInclusive;
use std::path::Path;

use image::imageops::FilterType;
use image::metadata::Orientation;
use image::{DynamicImage, ImageDecoder, ImageFormat, ImageReader, Limits, Rgb, Rgb32FImage};

use crate::readable::{self, Readable, StreamError};

/// Images with more pixels than this are never decoded whole: PNGs are streamed row by row into
/// the working resolution, other formats are refused. 64 Mpx of 8-bit RGBA is 256 MiB.
const MAX_DECODED_PIXELS: u64 = 64 << 20;

/// An image with more than this many times the working image's pixels (shrunk to less than half
/// on each side) is not held in floating point at its own size: a PNG is streamed row by row
/// into the working size, another format is shrunk in its own bit depth first. Memory then
/// follows the working size, not the file (an 8192² 16-bit RGBA PNG read at 512 px peaked at
/// 2.4 GB decoded whole and converted). Images closer to the working size are read in floating
/// point and resized with a triangle filter, as before.
const SHRINK_FACTOR: u64 = 4;

/// The most bytes read from an input that cannot seek (stdin, a pipe, a device): such an input is
/// read whole before decoding, so without a cap `/dev/zero` would fill memory. Regular files are
/// read in place and need none.
pub const MAX_STREAMED_BYTES: u64 = 256 << 20;

/// The most bytes a PNG's chunks before its pixels (an ICC profile, text) may inflate to beyond
/// what its pixels need: real profiles are kilobytes, and a crafted 1 MB file could otherwise
/// ask for a gigabyte. A larger profile is dropped (the decoder's choice); the pixels are read.
const MAX_PNG_METADATA_BYTES: u64 = 16 << 20;

/// The long sides a working image may have: below 16 pixels no region can be cut at the
/// models' crop sizes, and at 8192² the working image is already 64 Mpx of f32 canvases.
pub const WORKING_SIZES: RangeInclusive<u32> = 16..=8192;

/// Why an input image cannot be used, with the input's name (its file, or `<stdin>`).
#[derive(Debug, thiserror::Error)]
#[error("{input}: {problem}")]
pub struct DecodeError {
    /// The input: a file's path as given, or a name for bytes (`<stdin>`).
    pub input: String,
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
    #[error("{}", plain(&.0.to_string()))]
    Image(image::ImageError),
    /// The PNG stream decoder refused the file.
    #[error("{}", plain(&.0.to_string()))]
    Png(png::DecodingError),
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
    /// Pixels in memory whose length does not match the size they were given with.
    #[error("{bytes} bytes are not {width}×{height} pixels of {} bytes each", layout.channels())]
    PixelCount {
        /// Bytes given.
        bytes: usize,
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
        /// Their layout.
        layout: PixelLayout,
    },
    /// An input that cannot seek (a pipe, stdin, a device) that gave nothing, or more than
    /// [`MAX_STREAMED_BYTES`].
    #[error("{0}")]
    Stream(StreamError),
    /// A PNG whose palette the decoder did not expand.
    #[error("unexpanded palette")]
    UnexpandedPalette,
    /// The caller stopped the read ([`LoadOptions::cancel`]).
    #[error("stopped while it was read")]
    Cancelled,
}

/// A decoder's message in plain words on one line: the PNG decoder names a chunk by its Rust
/// value (`ChunkType { type: IDAT, critical: true, … }`), which becomes its name (`IDAT`), and
/// line breaks become spaces.
fn plain(message: &str) -> String {
    const CHUNK: &str = "ChunkType { type: ";
    let mut out = String::new();
    let mut rest = message;
    while let Some(at) = rest.find(CHUNK) {
        out.push_str(&rest[..at]);
        let after = &rest[at + CHUNK.len()..];
        let name = after.split([',', ' ', '}']).next().unwrap_or("");
        out.push_str(name);
        rest = after.find('}').map_or("", |end| &after[end + 1..]);
    }
    out.push_str(rest);
    out.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// An input image scaled to the working resolution.
#[derive(Clone, Debug)]
pub struct Loaded {
    /// RGB in [0, 1] (grey expanded, transparency over the background), long side at most the
    /// working size.
    pub image: Rgb32FImage,
    /// Width and height of the file, which the SVG keeps.
    pub original: (u32, u32),
    /// Seconds spent reading and scaling it.
    pub seconds: f64,
}

impl Loaded {
    /// An image already in memory at its working size (a caller's own pixels).
    pub fn from_image(image: Rgb32FImage) -> Self {
        Self { original: image.dimensions(), image, seconds: 0.0 }
    }
}

/// How an image is read.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadOptions {
    /// The long side is scaled down to at most this many pixels (never up).
    pub long_side: u32,
    /// Decode a JPEG cut short as far as it goes (the decoder fills the rest) instead of
    /// refusing it.
    pub allow_truncated: bool,
    /// Transparent pixels are composited over this colour (RGB in [0, 1]).
    pub background: [f32; 3],
    /// Raised by the caller to stop reading an image streamed row by row (a huge PNG, which
    /// takes seconds): the read ends with [`DecodeProblem::Cancelled`].
    pub cancel: Cancel,
}

impl Default for LoadOptions {
    fn default() -> Self {
        Self { long_side: 512, allow_truncated: false, background: [1.0; 3], cancel: Cancel::default() }
    }
}

/// A flag a caller raises to stop a long read ([`LoadOptions::cancel`]); none by default.
/// Clones share the flag; two are equal when they are the same flag.
#[derive(Clone, Debug, Default)]
pub struct Cancel(Option<std::sync::Arc<std::sync::atomic::AtomicBool>>);

impl Cancel {
    /// A flag not raised yet.
    pub fn new() -> Self {
        Self(Some(Default::default()))
    }

    /// Raises it.
    pub fn raise(&self) {
        if let Some(flag) = &self.0 {
            flag.store(true, std::sync::atomic::Ordering::SeqCst);
        }
    }

    /// Whether it was raised.
    pub fn is_raised(&self) -> bool {
        self.0.as_ref().is_some_and(|flag| flag.load(std::sync::atomic::Ordering::SeqCst))
    }
}

impl PartialEq for Cancel {
    fn eq(&self, other: &Self) -> bool {
        match (&self.0, &other.0) {
            (Some(a), Some(b)) => std::sync::Arc::ptr_eq(a, b),
            (None, None) => true,
            _ => false,
        }
    }
}

/// Reads `path` (png, jpeg, webp, gif — first frame —, bmp, tiff; any bit depth), turned as its
/// EXIF orientation says, over white, scaled down so its long side is at most `long_side`
/// (never up). A truncated file is an error.
pub fn load(path: &Path, long_side: u32) -> Result<Loaded, DecodeError> {
    open(path, &LoadOptions { long_side, ..LoadOptions::default() })
}

/// Reads the image file `path` as `options` say.
/// A named pipe, `/dev/stdin` or a shell's `<(…)` cannot seek: such an input is read whole first
/// (a pipe no program writes to is an empty input, not a wait: [`readable::open`]).
pub fn open(path: &Path, options: &LoadOptions) -> Result<Loaded, DecodeError> {
    let name = path.display().to_string();
    let fail = |problem| DecodeError { input: name.clone(), problem };
    if let Readable::Stream(stream) = readable::open(path).map_err(|err| fail(DecodeProblem::Io(err)))? {
        let bytes = read_stream(stream).map_err(fail)?;
        return decode(&bytes, &name, options);
    }
    let reader = || File::open(path).map(BufReader::new);
    timed(|| read(reader, options)).map_err(fail)
}

/// The whole of a stream that holds an image (stdin, a pipe, a device), refused as soon as its
/// first bytes are no image format this program reads, or once it passes [`MAX_STREAMED_BYTES`]:
/// `/dev/zero` or an endless pipe ends with an error, not with memory full; an empty stream
/// says so.
pub fn read_stream(mut stream: impl Read) -> Result<Vec<u8>, DecodeProblem> {
    /// Enough bytes for every format's signature.
    const SIGNATURE: usize = 16;
    let mut bytes = Vec::new();
    (&mut stream).take(SIGNATURE as u64).read_to_end(&mut bytes).map_err(DecodeProblem::Io)?;
    if bytes.is_empty() {
        return Err(DecodeProblem::Stream(StreamError::Empty));
    }
    if bytes.len() == SIGNATURE && image::guess_format(&bytes).is_err() {
        return Err(DecodeProblem::UnknownFormat);
    }
    let rest = match readable::read_whole(stream, MAX_STREAMED_BYTES - SIGNATURE as u64) {
        Err(StreamError::Empty) => Vec::new(),
        Err(StreamError::Io(err)) => return Err(DecodeProblem::Io(err)),
        Err(StreamError::TooLong { .. }) => {
            return Err(DecodeProblem::Stream(StreamError::TooLong { max: MAX_STREAMED_BYTES }));
        }
        Ok(rest) => rest,
    };
    bytes.extend(rest);
    Ok(bytes)
}

/// Reads an image held in memory (a whole file's bytes), named `input` in errors.
pub fn decode(bytes: &[u8], input: &str, options: &LoadOptions) -> Result<Loaded, DecodeError> {
    let reader = || Ok(Cursor::new(bytes));
    timed(|| read(reader, options)).map_err(|problem| DecodeError { input: input.to_string(), problem })
}

/// `read`'s image with the seconds it took.
fn timed(read: impl FnOnce() -> Result<Loaded, DecodeProblem>) -> Result<Loaded, DecodeProblem> {
    let started = web_time::Instant::now();
    read().map(|loaded| Loaded { seconds: started.elapsed().as_secs_f64(), ..loaded })
}

/// The image behind `reader` (which opens it again at its start each time it is called).
fn read<R: BufRead + Seek>(
    reader: impl Fn() -> std::io::Result<R>,
    options: &LoadOptions,
) -> Result<Loaded, DecodeProblem> {
    let (long_side, allow_truncated, background) =
        (options.long_side, options.allow_truncated, options.background);
    let guessed = |r: R| ImageReader::new(r).with_guessed_format().map_err(DecodeProblem::Io);
    let mut probe = guessed(reader().map_err(DecodeProblem::Io)?)?;
    let format = probe.format().ok_or(DecodeProblem::UnknownFormat)?;
    if format == ImageFormat::Png {
        // The header is read up to the pixels, ICC profile included, which the PNG decoder
        // inflates only within its memory limit (and drops beyond it): the header needs little.
        let mut limits = Limits::default();
        limits.max_alloc = Some(MAX_PNG_METADATA_BYTES);
        probe.limits(limits);
    }
    let (width, height) = probe.into_dimensions().map_err(DecodeProblem::Image)?;
    if width == 0 || height == 0 {
        return Err(DecodeProblem::Empty { width, height });
    }
    if format == ImageFormat::Jpeg && !allow_truncated {
        // The JPEG decoder fills a missing end with grey and says nothing.
        let mut bytes = Vec::new();
        reader().and_then(|mut r| r.read_to_end(&mut bytes)).map_err(DecodeProblem::Io)?;
        if !jpeg_is_complete(&bytes) {
            return Err(DecodeProblem::TruncatedJpeg);
        }
    }
    let pixels = u64::from(width) * u64::from(height);
    let target = fit(width, height, long_side);
    let streamed =
        format == ImageFormat::Png && (shrinks((width, height), target) || pixels > MAX_DECODED_PIXELS);
    let (image, original) = if streamed {
        let source = reader().map_err(DecodeProblem::Io)?;
        (stream_png(source, (width, height), target, background, &options.cancel)?, (width, height))
    } else if pixels <= MAX_DECODED_PIXELS {
        let mut whole = guessed(reader().map_err(DecodeProblem::Io)?)?;
        let mut limits = Limits::default();
        // What the pixels need (16-bit RGBA, and a copy); a PNG's profile or text inflates only
        // within the same limit, so a small image cannot carry a gigabyte of metadata.
        let need = if format == ImageFormat::Png { pixels * 16 + MAX_PNG_METADATA_BYTES } else { u64::MAX };
        limits.max_alloc = Some(need.min(MAX_DECODED_PIXELS * 16));
        whole.limits(limits);
        let mut decoder = whole.into_decoder().map_err(DecodeProblem::Image)?;
        // A camera's EXIF orientation (JPEG, WebP, TIFF): the picture as it is shown.
        let orientation = decoder.orientation().unwrap_or(Orientation::NoTransforms);
        let mut decoded = DynamicImage::from_decoder(decoder).map_err(DecodeProblem::Image)?;
        decoded.apply_orientation(orientation);
        (working(&decoded, long_side, background), (decoded.width(), decoded.height()))
    } else {
        return Err(DecodeProblem::TooLarge { width, height });
    };
    Ok(Loaded { image, original, seconds: 0.0 })
}

/// `decoded` as the working image: RGB over `background`, its long side at most `long_side`.
/// Much larger images are shrunk in their own bit depth first (see [`SHRINK_FACTOR`]).
fn working(decoded: &DynamicImage, long_side: u32, background: [f32; 3]) -> Rgb32FImage {
    let (width, height) = (decoded.width(), decoded.height());
    let target = fit(width, height, long_side);
    if target == (width, height) {
        to_rgb_over(decoded, background)
    } else if shrinks((width, height), target) {
        shrink_native(decoded, target, background)
    } else {
        resized(&to_rgb_over(decoded, background), long_side)
    }
}

/// Whether an image of `size` is shrunk to `target` in its own bit depth, not in floating point.
fn shrinks(size: (u32, u32), target: (u32, u32)) -> bool {
    let pixels = |(w, h): (u32, u32)| u64::from(w) * u64::from(h);
    pixels(size) > SHRINK_FACTOR * pixels(target)
}

/// The layouts [`from_pixels`] reads: 8 bits a channel, rows top to bottom, channels
/// interleaved (what a `H×W×C` `uint8` array holds in C order).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PixelLayout {
    /// One grey value a pixel.
    Grey,
    /// Red, green, blue.
    Rgb,
    /// Red, green, blue and opacity (composited over the background).
    Rgba,
}

impl PixelLayout {
    /// The layout with this many channels a pixel (1, 3 or 4).
    pub fn from_channels(channels: usize) -> Option<Self> {
        match channels {
            1 => Some(Self::Grey),
            3 => Some(Self::Rgb),
            4 => Some(Self::Rgba),
            _ => None,
        }
    }

    /// Bytes a pixel.
    pub fn channels(self) -> usize {
        match self {
            Self::Grey => 1,
            Self::Rgb => 3,
            Self::Rgba => 4,
        }
    }
}

/// Pixels a caller holds in memory (a numpy array, a frame of video) as the working image,
/// exactly as a file of those pixels is read: transparency over `options.background`, the long
/// side scaled down to `options.long_side`. `input` names them in errors.
pub fn from_pixels(
    pixels: &[u8],
    (width, height): (u32, u32),
    layout: PixelLayout,
    input: &str,
    options: &LoadOptions,
) -> Result<Loaded, DecodeError> {
    let fail = |problem| DecodeError { input: input.to_string(), problem };
    if width == 0 || height == 0 {
        return Err(fail(DecodeProblem::Empty { width, height }));
    }
    let expected = u64::from(width) * u64::from(height) * layout.channels() as u64;
    if pixels.len() as u64 != expected {
        return Err(fail(DecodeProblem::PixelCount { bytes: pixels.len(), width, height, layout }));
    }
    if u64::from(width) * u64::from(height) > MAX_DECODED_PIXELS {
        return Err(fail(DecodeProblem::TooLarge { width, height }));
    }
    let started = web_time::Instant::now();
    let buffer = pixels.to_vec();
    let decoded = match layout {
        PixelLayout::Grey => image::GrayImage::from_raw(width, height, buffer).map(DynamicImage::ImageLuma8),
        PixelLayout::Rgb => image::RgbImage::from_raw(width, height, buffer).map(DynamicImage::ImageRgb8),
        PixelLayout::Rgba => image::RgbaImage::from_raw(width, height, buffer).map(DynamicImage::ImageRgba8),
    }
    .expect("the length was checked against the size");
    let image = working(&decoded, options.long_side, options.background);
    Ok(Loaded { image, original: (width, height), seconds: started.elapsed().as_secs_f64() })
}

/// `decoded` shrunk to `target` in its own bit depth (8 or 16 bits; transparency composited over
/// `background` first), then turned to floating point: no copy of the whole image in f32.
fn shrink_native(decoded: &DynamicImage, (tw, th): (u32, u32), background: [f32; 3]) -> Rgb32FImage {
    let (width, height) = (decoded.width(), decoded.height());
    // More than 8 bits a channel (16-bit or float sources) is kept as 16 bits.
    let wide = decoded.color().bytes_per_pixel() > decoded.color().channel_count();
    let composite = |value: f32, alpha: f32, c: usize| value * alpha + background[c] * (1.0 - alpha);
    if wide {
        let rgba = decoded.to_rgba16();
        let rgb = image::ImageBuffer::<Rgb<u16>, Vec<u16>>::from_fn(width, height, |x, y| {
            let [r, g, b, a] = rgba.get_pixel(x, y).0.map(|v| v as f32 / 65535.0);
            Rgb(std::array::from_fn(|c| (composite([r, g, b][c], a, c) * 65535.0).round() as u16))
        });
        drop(rgba);
        let small = image::imageops::resize(&rgb, tw, th, FilterType::Triangle);
        Rgb32FImage::from_fn(tw, th, |x, y| Rgb(small.get_pixel(x, y).0.map(|v| v as f32 / 65535.0)))
    } else {
        let rgba = decoded.to_rgba8();
        let rgb = image::RgbImage::from_fn(width, height, |x, y| {
            let [r, g, b, a] = rgba.get_pixel(x, y).0.map(|v| v as f32 / 255.0);
            Rgb(std::array::from_fn(|c| (composite([r, g, b][c], a, c) * 255.0).round() as u8))
        });
        drop(rgba);
        let small = image::imageops::resize(&rgb, tw, th, FilterType::Triangle);
        Rgb32FImage::from_fn(tw, th, |x, y| Rgb(small.get_pixel(x, y).0.map(|v| v as f32 / 255.0)))
    }
}

/// RGB in [0, 1] of a decoded image: grey is expanded, 16-bit and float inputs are rescaled,
/// and transparent pixels are composited over `background` (what a viewer shows on a page of
/// that colour).
fn to_rgb_over(image: &DynamicImage, background: [f32; 3]) -> Rgb32FImage {
    let rgba = image.to_rgba32f();
    let pixels = rgba
        .pixels()
        .flat_map(|p| {
            let [r, g, b, a] = p.0.map(|v| if v.is_finite() { v.clamp(0.0, 1.0) } else { 0.0 });
            [0, 1, 2].map(|c| [r, g, b][c] * a + background[c] * (1.0 - a))
        })
        .collect();
    Rgb32FImage::from_raw(image.width(), image.height(), pixels).expect("buffer matches the image")
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

/// `image` with its long side at most `long_side` (the aspect ratio kept, never enlarged),
/// resampled with a triangle filter: the resizing every stage shares.
pub fn resized(image: &Rgb32FImage, long_side: u32) -> Rgb32FImage {
    let (width, height) = fit(image.width(), image.height(), long_side);
    if (width, height) == image.dimensions() {
        return image.clone();
    }
    image::imageops::resize(image, width, height, FilterType::Triangle)
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

/// Decodes a non-interlaced PNG row by row into the cells of a `target` grid, each cell the
/// mean of the source area it covers (source pixels split between cells by how much of them
/// each covers), so memory holds one source row and the small output.
fn stream_png(
    source: impl BufRead + Seek,
    (width, height): (u32, u32),
    (tw, th): (u32, u32),
    background: [f32; 3],
    cancel: &Cancel,
) -> Result<Rgb32FImage, DecodeProblem> {
    let mut decoder = png::Decoder::new(source);
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
    let columns = cover(width, tw);
    let rows = cover(height, th);
    let mut sums = vec![[0.0f64; 3]; (tw * th) as usize];
    let mut line = vec![[0.0f64; 3]; tw as usize];
    let mut y = 0u32;
    while let Some(row) = reader.next_row().map_err(DecodeProblem::Png)? {
        if y % 64 == 0 && cancel.is_raised() {
            return Err(DecodeProblem::Cancelled);
        }
        line.iter_mut().for_each(|cell| *cell = [0.0; 3]);
        for (pixel, shares) in row.data().chunks_exact(channels).zip(&columns) {
            let (rgb, alpha) = match pixel {
                [g] => ([*g; 3], 255),
                [g, a] => ([*g; 3], *a),
                [r, g, b] => ([*r, *g, *b], 255),
                [r, g, b, a] => ([*r, *g, *b], *a),
                _ => unreachable!("chunks of the channel count"),
            };
            let a = alpha as f64 / 255.0;
            let value: [f64; 3] =
                std::array::from_fn(|c| rgb[c] as f64 / 255.0 * a + background[c] as f64 * (1.0 - a));
            for &(cell, share) in shares {
                (0..3).for_each(|c| line[cell][c] += share * value[c]);
            }
        }
        let Some(shares) = rows.get(y as usize) else { break };
        for &(cell_row, share) in shares {
            let target = &mut sums[cell_row * tw as usize..(cell_row + 1) * tw as usize];
            for (sum, value) in target.iter_mut().zip(&line) {
                (0..3).for_each(|c| sum[c] += share * value[c]);
            }
        }
        y += 1;
    }
    if y != height {
        return Err(DecodeProblem::TruncatedPng { rows: y, height });
    }
    // Every cell covers (width / tw) × (height / th) source pixels.
    let area = (width as f64 / tw as f64) * (height as f64 / th as f64);
    Ok(Rgb32FImage::from_fn(tw, th, |x, y| Rgb(sums[(y * tw + x) as usize].map(|v| (v / area) as f32))))
}

/// For each of `source` pixels along an axis shrunk to `target` cells: the cells it overlaps and
/// by how much of a pixel (the shares of one pixel sum to 1).
fn cover(source: u32, target: u32) -> Vec<Vec<(usize, f64)>> {
    let scale = target as f64 / source as f64;
    (0..source)
        .map(|i| {
            let (start, end) = (i as f64 * scale, (i + 1) as f64 * scale);
            let (first, last) =
                (start.floor() as usize, ((end.ceil() as usize).max(1) - 1).min(target as usize - 1));
            (first..=last)
                .map(|cell| {
                    let overlap = (end.min(cell as f64 + 1.0) - start.max(cell as f64)).max(0.0);
                    (cell, overlap / scale)
                })
                .filter(|&(_, share)| share > 0.0)
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn endless_streams_end_with_an_error() {
        // /dev/zero: no image signature, refused after its first bytes.
        assert!(matches!(read_stream(std::io::repeat(0)), Err(DecodeProblem::UnknownFormat)));
        // A PNG's signature, then no end: refused at the cap, not when memory runs out.
        let endless = Cursor::new(b"\x89PNG\r\n\x1a\n".to_vec()).chain(std::io::repeat(0));
        assert!(matches!(
            read_stream(endless),
            Err(DecodeProblem::Stream(StreamError::TooLong { max: MAX_STREAMED_BYTES }))
        ));
        // Nothing at all is said as such.
        assert!(matches!(read_stream(std::io::empty()), Err(DecodeProblem::Stream(StreamError::Empty))));
        // What fits is read whole.
        let mut png = Vec::new();
        image::RgbImage::new(3, 2).write_to(&mut Cursor::new(&mut png), ImageFormat::Png).unwrap();
        assert_eq!(read_stream(Cursor::new(&png)).unwrap(), png);
    }

    /// A damaged file is said in plain words, on one line.
    #[test]
    fn decoder_messages_are_plain() {
        let mut png = Vec::new();
        image::RgbImage::from_pixel(8, 8, Rgb([9, 90, 200]))
            .write_to(&mut Cursor::new(&mut png), ImageFormat::Png)
            .unwrap();
        // The IDAT chunk's checksum, wrong: the decoder names the chunk.
        let at = png.windows(4).position(|w| w == b"IDAT").unwrap();
        let len = u32::from_be_bytes(png[at - 4..at].try_into().unwrap()) as usize;
        png[at + 4 + len] ^= 0xff;
        let err = decode(&png, "bad.png", &LoadOptions::default()).unwrap_err().to_string();
        assert!(err.starts_with("bad.png: ") && err.contains("IDAT"), "{err}");
        assert!(!err.contains("ChunkType") && !err.contains('{') && !err.contains('\n'), "{err}");
        assert_eq!(plain("a ChunkType { type: IHDR, critical: true } chunk.\n"), "a IHDR chunk.");
    }

    /// A PNG read row by row stops when its caller raises the flag; others are read.
    #[test]
    fn a_streamed_read_stops_when_asked() {
        let mut png = Vec::new();
        image::RgbImage::from_pixel(400, 300, Rgb([9, 90, 200]))
            .write_to(&mut Cursor::new(&mut png), ImageFormat::Png)
            .unwrap();
        let cancel = Cancel::new();
        let options = LoadOptions { long_side: 64, cancel: cancel.clone(), ..LoadOptions::default() };
        assert_eq!(decode(&png, "big.png", &options).unwrap().image.dimensions(), (64, 48));
        cancel.raise();
        let err = decode(&png, "big.png", &options).unwrap_err();
        assert!(matches!(err.problem, DecodeProblem::Cancelled), "{err}");
        assert_ne!(options.cancel, Cancel::new());
        assert_eq!(LoadOptions::default().cancel, Cancel::default());
    }

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
        assert!(
            matches!(err.problem, DecodeProblem::TruncatedJpeg) && err.input == half.display().to_string(),
            "{err:?}"
        );
        let allowed = LoadOptions { long_side: 512, allow_truncated: true, ..LoadOptions::default() };
        assert_eq!(open(&half, &allowed).unwrap().image.dimensions(), (64, 48));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn bytes_decode_as_their_file_does() {
        let picture = image::RgbImage::from_fn(30, 20, |x, y| Rgb([(x * 8) as u8, (y * 12) as u8, 40]));
        let mut bytes = Vec::new();
        picture.write_to(&mut Cursor::new(&mut bytes), ImageFormat::Png).unwrap();
        let path = std::env::temp_dir().join(format!("supersvg-bytes-{}.png", std::process::id()));
        std::fs::write(&path, &bytes).unwrap();
        let options = LoadOptions { long_side: 16, ..LoadOptions::default() };
        let (from_file, from_bytes) =
            (open(&path, &options).unwrap(), decode(&bytes, "mem", &options).unwrap());
        std::fs::remove_file(&path).unwrap();
        assert_eq!(from_file.image, from_bytes.image);
        assert_eq!((from_bytes.original, from_bytes.image.dimensions()), ((30, 20), (16, 11)));
        let err = decode(b"GIF89a-and-nothing-else", "<stdin>", &options).unwrap_err();
        assert!(err.to_string().starts_with("<stdin>: "), "{err}");
        let err = decode(b"plain text", "<stdin>", &options).unwrap_err();
        assert!(matches!(err.problem, DecodeProblem::UnknownFormat), "{err}");
    }

    #[test]
    fn pixels_in_memory_read_as_their_file_does() {
        // RGBA with transparency, larger than the working size: the same pixels as the PNG.
        let picture = image::RgbaImage::from_fn(60, 40, |x, y| {
            image::Rgba([(x * 4) as u8, (y * 6) as u8, 200, if x < 30 { 255 } else { (y * 6) as u8 }])
        });
        let mut bytes = Vec::new();
        picture.write_to(&mut Cursor::new(&mut bytes), ImageFormat::Png).unwrap();
        let options = LoadOptions { long_side: 32, ..LoadOptions::default() };
        let from_png = decode(&bytes, "mem.png", &options).unwrap();
        let from_pixels =
            from_pixels(picture.as_raw(), (60, 40), PixelLayout::Rgba, "array", &options).unwrap();
        assert_eq!(from_pixels.image, from_png.image);
        assert_eq!(from_pixels.original, (60, 40));
        let rgb = image::RgbImage::from_fn(3, 2, |x, y| Rgb([(x * 80) as u8, (y * 200) as u8, 7]));
        let loaded = super::from_pixels(rgb.as_raw(), (3, 2), PixelLayout::Rgb, "array", &options).unwrap();
        assert_eq!(loaded.image.get_pixel(2, 1).0, [160.0 / 255.0, 200.0 / 255.0, 7.0 / 255.0]);
        let err = super::from_pixels(&[0; 17], (3, 2), PixelLayout::Rgb, "array", &options).unwrap_err();
        assert_eq!(err.to_string(), "array: 17 bytes are not 3×2 pixels of 3 bytes each");
        let err = super::from_pixels(&[], (0, 2), PixelLayout::Grey, "array", &options).unwrap_err();
        assert!(matches!(err.problem, DecodeProblem::Empty { .. }), "{err}");
    }

    #[test]
    fn grey_transparent_and_16_bit_pixels_become_rgb() {
        use image::{GrayImage, ImageBuffer, Luma, Rgba};
        let grey = DynamicImage::ImageLuma8(GrayImage::from_pixel(2, 1, Luma([51])));
        assert!(to_rgb_over(&grey, [1.0; 3]).get_pixel(1, 0).0.iter().all(|c| (c - 0.2).abs() < 1e-6));
        let half_red = ImageBuffer::from_pixel(1, 1, Rgba([255u8, 0, 0, 128]));
        let [r, g, b] = to_rgb_over(&DynamicImage::ImageRgba8(half_red), [1.0; 3]).get_pixel(0, 0).0;
        assert!(r == 1.0 && (g - 0.498).abs() < 0.01 && (b - g).abs() < 1e-6);
        let deep = ImageBuffer::from_pixel(1, 1, Luma([65535u16]));
        assert_eq!(to_rgb_over(&DynamicImage::ImageLuma16(deep), [1.0; 3]).get_pixel(0, 0).0, [1.0; 3]);
        let clear = DynamicImage::ImageRgba8(ImageBuffer::from_pixel(1, 1, Rgba([255, 0, 0, 0])));
        assert_eq!(to_rgb_over(&clear, [0.0, 0.5, 0.0]).get_pixel(0, 0).0, [0.0, 0.5, 0.0]);
    }

    #[test]
    fn images_much_larger_than_the_working_size_are_shrunk_by_area() {
        // 900 × 300, three vertical bands: shrunk to 90 × 30 every cell lies in one band, and the
        // streamed PNG and the shrunk-in-place JPEG agree with what the bands are.
        let bands = |x: u32| match x / 300 {
            0 => [250u8, 10, 10],
            1 => [10, 250, 10],
            _ => [10, 10, 250],
        };
        let picture = image::RgbImage::from_fn(900, 300, |x, _| Rgb(bands(x)));
        let options = LoadOptions { long_side: 90, ..LoadOptions::default() };
        for format in [ImageFormat::Png, ImageFormat::Bmp] {
            let mut bytes = Vec::new();
            picture.write_to(&mut Cursor::new(&mut bytes), format).unwrap();
            let loaded = decode(&bytes, "bands", &options).unwrap();
            assert_eq!((loaded.image.dimensions(), loaded.original), ((90, 30), (900, 300)));
            for (x, y, pixel) in
                loaded.image.enumerate_pixels().filter(|(x, _, _)| x % 30 != 0 && x % 30 != 29)
            {
                let want = bands(x * 10).map(|v| v as f32 / 255.0);
                assert!(
                    (0..3).all(|c| (pixel.0[c] - want[c]).abs() < 0.01),
                    "{format:?} ({x}, {y}): {pixel:?}"
                );
            }
        }
        // Area shares: 5 source pixels over 2 cells split 1, 1, ½ | ½, 1, 1.
        let shares = cover(5, 2);
        assert!(
            matches!(shares[2][..], [(0, a), (1, b)] if (a - 0.5f64).abs() < 1e-9 && (b - 0.5f64).abs() < 1e-9)
        );
        assert_eq!(shares[0].len(), 1, "{shares:?}");
        assert!(shares.iter().all(|s| (s.iter().map(|(_, w)| w).sum::<f64>() - 1.0).abs() < 1e-12));
    }

    #[test]
    fn fitting_keeps_the_aspect_ratio_and_never_upscales() {
        assert_eq!(fit(1024, 512, 512), (512, 256));
        assert_eq!(fit(300, 200, 512), (300, 200));
        assert_eq!(fit(30000, 1, 512), (512, 1));
    }
}
