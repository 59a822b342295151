//! Other ways to vectorize an image, for comparison: vtracer, potrace on colour layers, filling
//! superpixels with their mean colour (pixel-exact). Plus SVG rendering and path counting that
//! treat every method alike. (SuperSVG's fallback drawing alone is a job of `infer::run`.)

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use image::{Rgb, Rgb32FImage, RgbImage};
use superpixel::{SlicError, SlicOptions, slic};

/// Why a method could not draw an image.
#[derive(Debug, thiserror::Error)]
pub enum PeerError {
    /// An external program could not be started (not installed, not executable).
    #[error("{program}: {source}")]
    Start {
        /// The program.
        program: &'static str,
        /// The operating system's reason.
        source: std::io::Error,
    },
    /// An external program ran and failed.
    #[error("{program} failed: {stderr}")]
    Failed {
        /// The program.
        program: &'static str,
        /// Its error output.
        stderr: String,
    },
    /// A scratch file could not be written or read.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        source: std::io::Error,
    },
    /// An SVG could not be parsed.
    #[error("SVG: {0}")]
    Svg(#[from] resvg::usvg::Error),
    /// A drawing could not be written as SVG.
    #[error("SVG: {0}")]
    Write(#[from] raster::SvgError),
    /// An SVG cannot be rendered at this size.
    #[error("cannot render an SVG onto {width}×{height} pixels")]
    Canvas {
        /// Requested width.
        width: u32,
        /// Requested height.
        height: u32,
    },
    /// The image could not be segmented.
    #[error(transparent)]
    Segmentation(#[from] SlicError),
}

impl PeerError {
    fn io(path: &Path) -> impl FnOnce(std::io::Error) -> Self + '_ {
        move |source| Self::Io { path: path.to_path_buf(), source }
    }

    /// The error for `program` that could not start.
    fn start(program: &'static str) -> impl Fn(std::io::Error) -> Self {
        move |source| Self::Start { program, source }
    }

    /// The error for `program` that exited with an error, from its output.
    fn failed(program: &'static str, output: &std::process::Output) -> Self {
        Self::Failed { program, stderr: String::from_utf8_lossy(&output.stderr).trim().to_string() }
    }
}

/// An SVG made by some method, and the seconds it took.
pub struct Traced {
    /// The document.
    pub svg: String,
    /// Wall time of the method.
    pub seconds: f64,
}

/// Renders an SVG document with resvg onto `width × height` (the document is scaled to fit),
/// over white. Text is not drawn: no method's drawing has any.
pub fn render_svg(svg: &str, width: u32, height: u32) -> Result<Rgb32FImage, PeerError> {
    let pixmap = render_tree(svg, &resvg::usvg::Options::default(), Some((width, height)))?;
    Ok(Rgb32FImage::from_fn(width, height, |x, y| {
        let p = pixmap.pixel(x, y).expect("inside the canvas").demultiply();
        Rgb([p.red() as f32 / 255.0, p.green() as f32 / 255.0, p.blue() as f32 / 255.0])
    }))
}

/// Renders a chart (or any SVG with text) at its own size over white, with the system's fonts.
pub fn render_chart(svg: &str) -> Result<RgbImage, PeerError> {
    let mut options = resvg::usvg::Options::default();
    options.fontdb_mut().load_system_fonts();
    let pixmap = render_tree(svg, &options, None)?;
    Ok(RgbImage::from_fn(pixmap.width(), pixmap.height(), |x, y| {
        let p = pixmap.pixel(x, y).expect("inside the canvas").demultiply();
        Rgb([p.red(), p.green(), p.blue()])
    }))
}

/// `svg` drawn over white onto `size` pixels (the document scaled to fit), or at its own size.
fn render_tree(
    svg: &str,
    options: &resvg::usvg::Options,
    size: Option<(u32, u32)>,
) -> Result<resvg::tiny_skia::Pixmap, PeerError> {
    let tree = resvg::usvg::Tree::from_str(svg, options)?;
    let own = tree.size();
    let (width, height) = size.unwrap_or((own.width().ceil() as u32, own.height().ceil() as u32));
    let mut pixmap =
        resvg::tiny_skia::Pixmap::new(width, height).ok_or(PeerError::Canvas { width, height })?;
    pixmap.fill(resvg::tiny_skia::Color::WHITE);
    let scale =
        resvg::tiny_skia::Transform::from_scale(width as f32 / own.width(), height as f32 / own.height());
    resvg::render(&tree, scale, &mut pixmap.as_mut());
    Ok(pixmap)
}

/// Number of closed shapes an SVG draws: the subpaths (moveto commands) of all `d` attributes,
/// so a compound path with holes counts each outline — the same unit for every method.
pub fn count_shapes(svg: &str) -> usize {
    svg.split(" d=\"")
        .skip(1)
        .map(|rest| rest.split('"').next().unwrap_or("").chars().filter(|c| matches!(c, 'M' | 'm')).count())
        .sum()
}

/// Whether an external program can be run.
pub fn available(program: &str) -> bool {
    Command::new(program).arg("--help").output().is_ok()
}

/// The vtracer settings the evaluation varies (everything else stays at vtracer's default:
/// colour, stacked, spline).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct VtracerSettings {
    /// Patches smaller than this many pixels are dropped (`--filter_speckle`, default 4).
    pub filter_speckle: usize,
    /// Significant bits per colour channel, 1 to 8 (`--color_precision`, default 6).
    pub color_precision: u8,
    /// Colour difference between layers (`--gradient_step`, default 16).
    pub gradient_step: usize,
}

impl Default for VtracerSettings {
    /// vtracer's own defaults.
    fn default() -> Self {
        Self { filter_speckle: 4, color_precision: 6, gradient_step: 16 }
    }
}

impl VtracerSettings {
    /// The grid eval's rate–distortion sweep draws vtracer's curve from: speckle sizes 0 to 16
    /// (detail against bytes; vtracer refuses more than 16) at colour precisions 3, 4, 6 and 8
    /// (fewer colours, fewer layers), the two knobs vtracer offers for file size.
    pub fn sweep() -> Vec<Self> {
        let mut grid = Vec::new();
        for color_precision in [3, 4, 6, 8] {
            for filter_speckle in [0, 2, 4, 8, 16] {
                grid.push(Self { filter_speckle, color_precision, ..Self::default() });
            }
        }
        grid
    }

    /// As the report names it.
    pub fn label(&self) -> String {
        format!("speckle {}, precision {}", self.filter_speckle, self.color_precision)
    }
}

/// vtracer on a PNG with these settings.
pub fn vtracer_with(png: &Path, settings: VtracerSettings, scratch: &Path) -> Result<Traced, PeerError> {
    let VtracerSettings { filter_speckle, color_precision, gradient_step } = settings;
    let out = scratch.join(format!("vtracer-{filter_speckle}-{color_precision}-{gradient_step}.svg"));
    let started = Instant::now();
    let status = Command::new("vtracer")
        .args(["--input", &png.to_string_lossy(), "--output", &out.to_string_lossy()])
        .args(["--filter_speckle", &filter_speckle.to_string()])
        .args(["--color_precision", &color_precision.to_string()])
        .args(["--gradient_step", &gradient_step.to_string()])
        .output()
        .map_err(PeerError::start("vtracer"))?;
    let seconds = started.elapsed().as_secs_f64();
    if !status.status.success() {
        return Err(PeerError::failed("vtracer", &status));
    }
    let svg = std::fs::read_to_string(&out).map_err(PeerError::io(&out))?;
    Ok(Traced { svg, seconds })
}

/// vtracer (colour, stacked, spline) on a PNG. With a shape budget, one knob is searched for
/// at most `shapes` shapes and as many as possible: knob k sets the speckle filter to
/// min(16, 4 + k) px and, past that, the colour gradient step to 16 + (k − 12) (fewer layers);
/// `None` keeps vtracer's defaults (speckle 4, gradient step 16).
pub fn vtracer(png: &Path, shapes: Option<usize>, scratch: &Path) -> Result<Traced, PeerError> {
    let run = |knob: usize| {
        let settings = VtracerSettings {
            filter_speckle: (4 + knob).min(16),
            gradient_step: (16 + knob.saturating_sub(12)).min(255),
            ..VtracerSettings::default()
        };
        vtracer_with(png, settings, scratch)
    };
    match shapes {
        None => run(0),
        Some(target) => search(target, run, 0, 251),
    }
}

/// potrace on colour layers: the image quantized to `colors` colours (k-means in RGB), layers
/// painted from the most to the least frequent colour, each layer's bitmap being its colour and
/// every colour painted after it (so layers stack without gaps), each traced with potrace. The
/// speck size is searched for at most `shapes` shapes.
pub fn potrace_colors(
    image: &Rgb32FImage,
    colors: usize,
    shapes: Option<usize>,
    scratch: &Path,
) -> Result<Traced, PeerError> {
    let started = Instant::now();
    let start = PeerError::start("potrace");
    let (palette, labels) = quantize(image, colors);
    let quantize_seconds = started.elapsed().as_secs_f64();
    let mut order: Vec<usize> = (0..palette.len()).collect();
    let counts: Vec<usize> = (0..palette.len()).map(|k| labels.iter().filter(|&&l| l == k).count()).collect();
    order.sort_by(|a, b| counts[*b].cmp(&counts[*a]));
    let rank: Vec<usize> = {
        let mut rank = vec![0; palette.len()];
        order.iter().enumerate().for_each(|(r, &k)| rank[k] = r);
        rank
    };
    let (width, height) = image.dimensions();
    let run = |turd: usize| -> Result<Traced, PeerError> {
        let started = Instant::now();
        let mut body = String::new();
        for (layer, &k) in order.iter().enumerate() {
            let pbm = scratch.join(format!("layer-{layer}.pbm"));
            let mut bits = format!("P1\n{width} {height}\n").into_bytes();
            for (i, &label) in labels.iter().enumerate() {
                bits.extend_from_slice(if rank[label] >= layer { b"1 " } else { b"0 " });
                if (i + 1) % width as usize == 0 {
                    bits.push(b'\n');
                }
            }
            std::fs::write(&pbm, bits).map_err(PeerError::io(&pbm))?;
            let out = Command::new("potrace")
                .args(["-b", "svg", "-t", &turd.to_string(), "-o", "-"])
                .arg(&pbm)
                .output()
                .map_err(&start)?;
            if !out.status.success() {
                return Err(PeerError::failed("potrace", &out));
            }
            let svg = String::from_utf8_lossy(&out.stdout);
            let [r, g, b] = palette[k].map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8);
            if let Some(group) = svg.split("<g ").nth(1).and_then(|g| g.split("</g>").next()) {
                let group = group.replace("fill=\"#000000\"", &format!("fill=\"#{r:02x}{g:02x}{b:02x}\""));
                body.push_str(&format!("<g {group}</g>\n"));
            }
        }
        let svg = format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{width}\" height=\"{height}\" viewBox=\"0 0 {width} {height}\">\n{body}</svg>\n"
        );
        Ok(Traced { svg, seconds: quantize_seconds + started.elapsed().as_secs_f64() })
    };
    match shapes {
        None => run(2),
        Some(target) => search(target, run, 0, 4096),
    }
}

/// The pixel-exact mosaic of [`mean_color_superpixels`].
pub struct Mosaic {
    /// Every pixel in its region's mean colour.
    pub image: Rgb32FImage,
    /// Regions.
    pub regions: usize,
    /// Seconds it took.
    pub seconds: f64,
}

/// Every superpixel of a SLIC segmentation into `regions` regions, filled with its mean colour:
/// the baseline a region-based vectorizer must beat.
pub fn mean_color_superpixels(image: &Rgb32FImage, regions: usize) -> Result<Mosaic, PeerError> {
    let started = Instant::now();
    let options = SlicOptions {
        n_segments: regions.clamp(1, (image.width() * image.height()) as usize),
        ..Default::default()
    };
    let segmentation = slic(image, &options)?;
    let filled = Rgb32FImage::from_fn(image.width(), image.height(), |x, y| {
        Rgb(segmentation.regions[segmentation.label(x, y) as usize].mean_color)
    });
    Ok(Mosaic {
        image: filled,
        regions: segmentation.regions.len(),
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// The result of `run` with the most shapes not above `target`, over knob values `low..=high`
/// (a larger knob gives fewer shapes), by bisection in at most 8 runs; the fewest shapes seen if
/// nothing fits.
fn search(
    target: usize,
    run: impl Fn(usize) -> Result<Traced, PeerError>,
    low: usize,
    high: usize,
) -> Result<Traced, PeerError> {
    let (mut low, mut high) = (low, high);
    let mut fitting: Option<(usize, Traced)> = None;
    let mut fewest: Option<(usize, Traced)> = None;
    for _ in 0..8 {
        let knob = (low + high) / 2;
        let traced = run(knob)?;
        let shapes = count_shapes(&traced.svg);
        if shapes <= target {
            if fitting.as_ref().is_none_or(|(best, _)| shapes > *best) {
                fitting = Some((shapes, traced));
            }
            if knob == low {
                break;
            }
            high = knob - 1;
        } else {
            if fewest.as_ref().is_none_or(|(best, _)| shapes < *best) {
                fewest = Some((shapes, traced));
            }
            if knob == high {
                break;
            }
            low = knob + 1;
        }
    }
    // The loop runs at least once, and a run that did not fail is kept as fitting or fewest.
    Ok(fitting.or(fewest).map(|(_, traced)| traced).expect("at least one run was kept"))
}

/// k-means in RGB (10 rounds, centres started at luminance quantiles): palette and labels.
fn quantize(image: &Rgb32FImage, k: usize) -> (Vec<[f32; 3]>, Vec<usize>) {
    let pixels: Vec<[f32; 3]> = image.pixels().map(|p| p.0).collect();
    let mut sorted = pixels.clone();
    sorted.sort_by(|a, b| (a[0] + a[1] + a[2]).total_cmp(&(b[0] + b[1] + b[2])));
    let k = k.clamp(1, pixels.len());
    let mut centers: Vec<[f32; 3]> = (0..k).map(|i| sorted[(2 * i + 1) * sorted.len() / (2 * k)]).collect();
    let mut labels = vec![0; pixels.len()];
    for _ in 0..10 {
        for (label, p) in labels.iter_mut().zip(&pixels) {
            let distance = |c: &[f32; 3]| (0..3).map(|i| (p[i] - c[i]).powi(2)).sum::<f32>();
            *label = (0..k).min_by(|a, b| distance(&centers[*a]).total_cmp(&distance(&centers[*b]))).unwrap();
        }
        let mut sums = vec![[0.0f64; 4]; k];
        for (label, p) in labels.iter().zip(&pixels) {
            (0..3).for_each(|i| sums[*label][i] += p[i] as f64);
            sums[*label][3] += 1.0;
        }
        for (center, sum) in centers.iter_mut().zip(&sums) {
            if sum[3] > 0.0 {
                *center = [0, 1, 2].map(|i| (sum[i] / sum[3]) as f32);
            }
        }
    }
    (centers, labels)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shapes_are_counted_per_subpath() {
        let svg = r#"<svg><path d="M0 0L1 1Z"/><path d="M0 0L1 0Z m5 5l1 1z"/><rect/></svg>"#;
        assert_eq!(count_shapes(svg), 3);
    }

    #[test]
    fn rendering_an_svg_fills_its_canvas() {
        let svg = r##"<svg xmlns="http://www.w3.org/2000/svg" width="10" height="10" viewBox="0 0 10 10"><rect x="0" y="0" width="5" height="10" fill="#ff0000"/></svg>"##;
        let image = render_svg(svg, 20, 20).unwrap();
        assert_eq!(image.get_pixel(2, 10).0, [1.0, 0.0, 0.0]);
        assert_eq!(image.get_pixel(15, 10).0, [1.0, 1.0, 1.0]);
        let err = render_svg("not an svg", 4, 4).err().expect("garbage is refused");
        assert!(matches!(err, PeerError::Svg(_)), "{err}");
        assert!(matches!(render_svg(svg, 0, 4), Err(PeerError::Canvas { width: 0, height: 4 })));
    }

    #[test]
    fn mean_colour_baseline_is_exact_on_flat_regions() {
        let image =
            Rgb32FImage::from_fn(
                40,
                20,
                |x, _| if x < 20 { Rgb([1.0, 0.0, 0.0]) } else { Rgb([0.0, 0.0, 1.0]) },
            );
        let mosaic = mean_color_superpixels(&image, 2).unwrap();
        assert!(mosaic.regions >= 2);
        assert!(common::psnr(&mosaic.image, &image) > 20.0);
    }
}
