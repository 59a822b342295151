//! `infer`: turns images into SVG with the trained SuperSVG networks.
//!
//! `infer photo.jpg -o photo.svg [--paths 500] [--preview photo.png] [--metrics photo.json]`
//! `infer a.png b.jpg … -o out/` (a folder for several inputs), `infer - -o - < in.png > out.svg`

use std::io::{IsTerminal, Read, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, anyhow, bail};
use clap::Parser;
use image::{Rgb32FImage, RgbImage};
use indicatif::ProgressBar;
use infer::decode::{LoadOptions, load_with};
use infer::finetune::{Budget, FinetuneOptions, Progress, finetune_with_progress};
use infer::metrics::{mse, psnr, ssim};
use infer::models::{Models, bundled};
use infer::pipeline::{
    AutoBudget, MAX_PATHS, MIN_REGION_PIXELS, Options, auto_budget, max_regions, operating_point, vectorize,
};
use infer::write::{folder_of, write_atomic, write_png};
use raster::{Backend, MAX_DECIMALS, SvgOptions, render_exact, to_svg_with};

/// Vectorize images into SVG with SuperSVG.
///
/// Outputs: a path ending in `/` (or an existing folder) is a folder that gets one file per
/// input, named after it; anything else is a file, which needs exactly one input. Several
/// inputs need folders. `-` reads the input from stdin or writes the SVG to stdout. Every
/// output is checked before any work: extensions, name collisions, an output that is an input,
/// folders that cannot be written.
#[derive(Parser, Debug)]
#[command(name = "infer", version)]
struct Args {
    /// Input images (png, jpeg, webp, gif, bmp, tiff), or `-` for stdin.
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// The SVG: a `.svg` file for one input, a folder (`out/`) for any number, or `-` (stdout).
    #[arg(short, long)]
    output: PathBuf,
    /// The most paths in the result (2 to 20000; fewer only when no further path lowers the
    /// error), or `auto`: per image, double from 8 paths until the drawing reaches 30 dB PSNR,
    /// and keep the fewest past which more paths gain less than 0.25 dB a doubling, at most 2000
    /// (flat art gets few paths, photos many).
    #[arg(long, default_value = "500", value_parser = path_budget)]
    paths: PathBudget,
    /// Coarse-model checkpoint (default: the bundled one).
    #[arg(long)]
    coarse: Option<PathBuf>,
    /// Refinement-model checkpoint (default: the bundled one).
    #[arg(long)]
    refine: Option<PathBuf>,
    /// Coarse paths only, no refinement.
    #[arg(long, conflicts_with = "refine")]
    no_refine: bool,
    /// Compute backend: flex, ndarray or wgpu.
    #[arg(long, default_value = "flex")]
    backend: Backend,
    /// Long side of the working resolution in pixels (the SVG keeps the input's size).
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(16..=MAX_SIZE as i64))]
    size: u32,
    /// Number of superpixels, below `--paths` (default: the operating point stored with the
    /// coarse model, for the budget). At most one per 16 pixels of the working image: more is
    /// lowered, with a warning.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..MAX_PATHS as u64))]
    regions: Option<u64>,
    /// Write a PNG rendering of the result (`.png` file, or a folder).
    #[arg(long)]
    preview: Option<PathBuf>,
    /// Write input and rendering side by side as PNG (`.png` file, or a folder).
    #[arg(long)]
    compare: Option<PathBuf>,
    /// Write MSE, PSNR, SSIM, path count and seconds per stage as JSON (`.json` file, or a folder).
    #[arg(long)]
    metrics: Option<PathBuf>,
    /// SuperSVG-F: fine-tune every path against the image, this many steps (each moves every path).
    #[arg(long, conflicts_with = "finetune_secs")]
    finetune_steps: Option<usize>,
    /// SuperSVG-F: fine-tune every path against the image for this many seconds (0 to 3600).
    #[arg(long, value_parser = seconds, allow_hyphen_values = true)]
    finetune_secs: Option<f64>,
    /// Decimals of the SVG's coordinates (0 to 6; 2 keeps 1/100 pixel, fewer make smaller files).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(0..=MAX_DECIMALS as i64))]
    decimals: u8,
    /// The colour transparent pixels are composited over (`#rrggbb`); the SVG is opaque.
    #[arg(long, default_value = "#ffffff", value_parser = colour)]
    background: Colour,
    /// Draw what a truncated JPEG holds instead of refusing it.
    #[arg(long)]
    allow_truncated: bool,
    /// No line per file and no progress bar; errors and warnings only.
    #[arg(short, long)]
    quiet: bool,
}

/// The largest `--size`: a working image of 8192² is already 64 Mpx of f32 canvases.
const MAX_SIZE: u32 = 8192;

/// A bar for SuperSVG-F on stderr: time or steps, with the running PSNR.
fn finetune_bar(budget: Budget) -> ProgressBar {
    let (length, unit) = match budget {
        Budget::Seconds(seconds) => ((seconds * 1000.0) as u64, "ms"),
        Budget::Steps(_) => (0, "steps"),
    };
    let bar = ProgressBar::new(length);
    let template = format!("fine-tuning {{bar:30}} {{pos}}/{{len}} {unit}, {{msg}}");
    if let Ok(style) = indicatif::ProgressStyle::with_template(&template) {
        bar.set_style(style);
    }
    bar
}

/// What `--paths` asks for.
#[derive(Clone, Copy, Debug)]
enum PathBudget {
    /// This many paths at most.
    Count(usize),
    /// A budget per image by [`auto_budget`].
    Auto,
}

fn path_budget(text: &str) -> Result<PathBudget, String> {
    match text.parse::<usize>() {
        _ if text == "auto" => Ok(PathBudget::Auto),
        Ok(paths) if (2..=MAX_PATHS).contains(&paths) => Ok(PathBudget::Count(paths)),
        _ => Err(format!("{text:?} is not a path budget: a number from 2 to {MAX_PATHS}, or auto")),
    }
}

/// An RGB colour in [0, 1].
#[derive(Clone, Copy, Debug)]
struct Colour([f32; 3]);

/// `#rrggbb` (or `rrggbb`) as a colour.
fn colour(text: &str) -> Result<Colour, String> {
    let hex = text.strip_prefix('#').unwrap_or(text);
    let channel = |i: usize| hex.get(i..i + 2).and_then(|h| u8::from_str_radix(h, 16).ok());
    match (hex.len(), channel(0), channel(2), channel(4)) {
        (6, Some(r), Some(g), Some(b)) => Ok(Colour([r, g, b].map(|c| c as f32 / 255.0))),
        _ => Err(format!("{text:?} is not a colour: write it #rrggbb")),
    }
}

/// A finite number of seconds within [0, 3600].
fn seconds(text: &str) -> Result<f64, String> {
    let value: f64 = text.parse().map_err(|_| format!("{text:?} is not a number"))?;
    if value.is_finite() && (0.0..=3600.0).contains(&value) {
        Ok(value)
    } else {
        Err(format!("{text} is not a number of seconds within 0 to 3600"))
    }
}

fn main() -> ExitCode {
    let args = Args::parse();
    match run(&args) {
        Ok(0) => ExitCode::SUCCESS,
        Ok(failed) => {
            eprintln!("{failed} of {} inputs failed", args.inputs.len());
            ExitCode::FAILURE
        }
        Err(err) => {
            eprintln!("error: {err:#}");
            ExitCode::FAILURE
        }
    }
}

/// Where one input comes from.
#[derive(Clone, Debug)]
enum Source {
    File(PathBuf),
    Stdin,
}

impl Source {
    fn name(&self) -> String {
        match self {
            Source::File(path) => path.display().to_string(),
            Source::Stdin => "<stdin>".into(),
        }
    }
}

/// Where the SVG of one input goes.
#[derive(Clone, Debug, PartialEq)]
enum Sink {
    File(PathBuf),
    Stdout,
}

/// One input and every output it gets, decided before any work.
struct Job {
    source: Source,
    svg: Sink,
    preview: Option<PathBuf>,
    compare: Option<PathBuf>,
    metrics: Option<PathBuf>,
}

/// What an output argument names.
enum Place {
    Folder(PathBuf),
    File(PathBuf),
    Stdout,
}

fn place(path: &Path, stdout_allowed: bool) -> Place {
    let text = path.to_string_lossy();
    if stdout_allowed && text == "-" {
        Place::Stdout
    } else if text.ends_with('/') || path.is_dir() {
        Place::Folder(path.to_path_buf())
    } else {
        Place::File(path.to_path_buf())
    }
}

/// Every input with its outputs, or the first reason the command cannot run as asked. Creates
/// the output folders (only once every check passed).
fn plan(args: &Args) -> anyhow::Result<Vec<Job>> {
    let many = args.inputs.len() > 1;
    let sources: Vec<Source> = args
        .inputs
        .iter()
        .map(|path| if path.as_os_str() == "-" { Source::Stdin } else { Source::File(path.clone()) })
        .collect();
    if sources.iter().filter(|s| matches!(s, Source::Stdin)).count() > 1 {
        bail!("stdin (-) can be read only once");
    }
    let mut folders = Vec::new();
    // (flag, path, extension): each output argument resolved to a destination per input.
    let mut resolve = |flag: &str,
                       path: &Path,
                       extension: &str,
                       stdout: bool|
     -> anyhow::Result<Vec<Option<PathBuf>>> {
        match place(path, stdout) {
            Place::Stdout if many => Err(anyhow!("{flag} -: several inputs cannot all go to stdout")),
            Place::Stdout => Ok(vec![None]),
            Place::File(file) if many => {
                Err(anyhow!("{flag} {}: several inputs need a folder (end the path with /)", file.display()))
            }
            Place::File(file) => {
                // A device or a pipe (`/dev/null`) has no extension to check.
                let special = std::fs::metadata(&file).is_ok_and(|m| !m.is_file());
                let ok = special || file.extension().is_some_and(|e| e.eq_ignore_ascii_case(extension));
                if !ok {
                    return Err(anyhow!("{flag} {}: the file name must end in .{extension}", file.display()));
                }
                Ok(vec![Some(file)])
            }
            Place::Folder(folder) => {
                if folder.exists() && !folder.is_dir() {
                    return Err(anyhow!("{flag} {}: not a folder", folder.display()));
                }
                folders.push(folder.clone());
                Ok(sources
                    .iter()
                    .map(|source| {
                        let stem = match source {
                            Source::File(path) => {
                                path.file_stem().map(|s| s.to_os_string()).unwrap_or_default()
                            }
                            Source::Stdin => "stdin".into(),
                        };
                        Some(folder.join(Path::new(&stem).with_extension(extension)))
                    })
                    .collect())
            }
        }
    };
    let svg = resolve("-o", &args.output, "svg", true)?;
    let optional = |files: Option<Vec<Option<PathBuf>>>| files.unwrap_or_else(|| vec![None; sources.len()]);
    let preview =
        optional(args.preview.as_deref().map(|p| resolve("--preview", p, "png", false)).transpose()?);
    let compare =
        optional(args.compare.as_deref().map(|p| resolve("--compare", p, "png", false)).transpose()?);
    let metrics =
        optional(args.metrics.as_deref().map(|p| resolve("--metrics", p, "json", false)).transpose()?);

    let inputs: Vec<(PathBuf, String)> = sources
        .iter()
        .filter_map(|s| match s {
            Source::File(path) => Some((absolute(path), s.name())),
            Source::Stdin => None,
        })
        .collect();
    let mut taken: Vec<(PathBuf, String)> = Vec::new();
    let mut jobs = Vec::new();
    for (index, source) in sources.iter().enumerate() {
        let job = Job {
            source: source.clone(),
            svg: svg[index].clone().map_or(Sink::Stdout, Sink::File),
            preview: preview[index].clone(),
            compare: compare[index].clone(),
            metrics: metrics[index].clone(),
        };
        let files = [job.svg.file(), job.preview.as_ref(), job.compare.as_ref(), job.metrics.as_ref()];
        for file in files.into_iter().flatten() {
            let absolute = absolute(file);
            if let Some((_, input)) = inputs.iter().find(|(path, _)| *path == absolute) {
                return Err(anyhow!("{}: is the input {input}; refusing to overwrite it", file.display()));
            }
            if let Some((_, other)) = taken.iter().find(|(path, _)| *path == absolute) {
                return Err(anyhow!(
                    "{}: both {other} and {} would be written there; rename one input or use separate runs",
                    file.display(),
                    source.name()
                ));
            }
            taken.push((absolute, source.name()));
        }
        jobs.push(job);
    }
    for folder in &folders {
        std::fs::create_dir_all(folder).with_context(|| folder.display().to_string())?;
    }
    for (file, _) in &taken {
        writable(file)?;
    }
    Ok(jobs)
}

impl Sink {
    fn file(&self) -> Option<&PathBuf> {
        match self {
            Sink::File(path) => Some(path),
            Sink::Stdout => None,
        }
    }
}

/// `path` made absolute, with its folder resolved through links where it exists.
fn absolute(path: &Path) -> PathBuf {
    if let Ok(resolved) = std::fs::canonicalize(path) {
        return resolved;
    }
    let folder = folder_of(path);
    let folder = std::fs::canonicalize(folder).unwrap_or_else(|_| folder.to_path_buf());
    folder.join(path.file_name().unwrap_or_default())
}

/// Whether `file` can be written: it is not a folder, and its folder exists and takes a new
/// file (what the atomic write needs), unless it is a device or a pipe.
fn writable(file: &Path) -> anyhow::Result<()> {
    let fail = |message: String| format!("{}: {message}", file.display());
    if file.is_dir() {
        return Err(anyhow!(fail("is a folder".into())));
    }
    if std::fs::metadata(file).is_ok_and(|m| !m.is_file()) {
        return Ok(()); // a device or a pipe: written in place, its errors reported then
    }
    let folder = folder_of(file);
    if !folder.is_dir() {
        return Err(anyhow!(fail(format!("the folder {} does not exist", folder.display()))));
    }
    let probe = folder.join(format!(".supersvg-probe-{}", std::process::id()));
    std::fs::File::create(&probe)
        .map_err(|err| anyhow!(fail(format!("cannot write in {}: {err}", folder.display()))))?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

/// Loads the models, then vectorizes every input; returns how many inputs failed.
fn run(args: &Args) -> anyhow::Result<usize> {
    let jobs = plan(args)?;
    let device = args.backend.device()?;
    let coarse = match &args.coarse {
        Some(path) => path.clone(),
        None => bundled("coarse.ckpt")?,
    };
    let refine = match (&args.refine, args.no_refine) {
        (_, true) => None,
        (Some(path), false) => Some(path.clone()),
        (None, false) => Some(bundled("refine.ckpt")?),
    };
    let models = Models::load(&coarse, refine.as_deref(), &device)?;
    if !args.quiet {
        let refine = refine.as_ref().map_or("none".to_string(), |p| p.display().to_string());
        eprintln!("models: coarse {}, refine {refine}", coarse.display());
    }
    let paths = match (args.paths, args.regions) {
        (PathBudget::Auto, Some(_)) => bail!("--regions needs a number of --paths, not auto"),
        (PathBudget::Count(paths), Some(regions)) if regions as usize >= paths => bail!(
            "--regions {regions} must be below --paths {paths} (each region takes a path, and so does the background)"
        ),
        (PathBudget::Count(paths), _) => paths,
        (PathBudget::Auto, None) => 0, // chosen per image
    };
    let options = Options { paths, regions: args.regions.map(|r| r as usize), ..Options::default() };

    let bar = (jobs.len() > 1 && !args.quiet && std::io::stderr().is_terminal())
        .then(|| ProgressBar::new(jobs.len() as u64));
    let say = |line: String| match &bar {
        Some(bar) => bar.println(line),
        None => eprintln!("{line}"),
    };
    let mut failed = 0;
    for job in &jobs {
        match process(job, &models, &options, args, &device, &say) {
            Ok(line) if !args.quiet => say(line),
            Ok(_) => {}
            Err(message) => {
                say(format!("error: {}: {message:#}", job.source.name()));
                failed += 1;
            }
        }
        if let Some(bar) = &bar {
            bar.inc(1);
        }
    }
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    Ok(failed)
}

/// One input: vectorize, write the SVG and whatever extra output was asked for; the line
/// that reports it.
fn process(
    job: &Job,
    models: &Models,
    options: &Options,
    args: &Args,
    device: &burn::tensor::Device,
    say: &dyn Fn(String),
) -> anyhow::Result<String> {
    let started = Instant::now();
    let load_options = LoadOptions {
        long_side: args.size,
        allow_truncated: args.allow_truncated,
        background: args.background.0,
    };
    let load = |path: &Path| load_with(path, &load_options);
    let loaded = match &job.source {
        Source::File(path) => load(path).map_err(|err| anyhow::Error::new(err.problem))?,
        Source::Stdin => {
            // The decoder wants a file (it reads the header, then streams large PNGs).
            let mut bytes = Vec::new();
            std::io::stdin().read_to_end(&mut bytes).context("reading stdin")?;
            let spool = std::env::temp_dir().join(format!("supersvg-stdin-{}", std::process::id()));
            std::fs::write(&spool, &bytes).with_context(|| spool.display().to_string())?;
            let loaded = load(&spool).map_err(|err| anyhow::Error::new(err.problem));
            let _ = std::fs::remove_file(&spool);
            loaded?
        }
    };
    let decoded = started.elapsed().as_secs_f64();
    let (w, h) = loaded.image.dimensions();
    if let Some(regions) = options.regions
        && regions > max_regions(w, h)
    {
        say(format!(
            "warning: {}: --regions {regions} lowered to {} (one region per {MIN_REGION_PIXELS} pixels of the {w}×{h} working image)",
            job.source.name(),
            max_regions(w, h)
        ));
    }
    let options = match args.paths {
        PathBudget::Count(_) => options.clone(),
        PathBudget::Auto => {
            let point = operating_point(models, options);
            let paths = auto_budget(&loaded.image, &point, options.compactness, &AutoBudget::default())?;
            Options { paths, ..options.clone() }
        }
    };
    let mut result = vectorize(models, &loaded.image, &options, device)?;
    let budget = match (args.finetune_steps, args.finetune_secs) {
        (Some(steps), _) => Some(Budget::Steps(steps)),
        (None, Some(seconds)) => Some(Budget::Seconds(seconds)),
        (None, None) => None,
    };
    if let Some(budget) = budget {
        let tuning = Instant::now();
        let options = FinetuneOptions { budget, ..FinetuneOptions::default() };
        let bar = (!args.quiet && std::io::stderr().is_terminal()).then(|| finetune_bar(budget));
        let mut show = |progress: &Progress| {
            if let Some(bar) = &bar {
                match progress.total_steps {
                    Some(total) => {
                        bar.set_length(total as u64);
                        bar.set_position(progress.steps as u64);
                    }
                    None => bar.set_position((progress.seconds * 1000.0) as u64),
                }
                bar.set_message(format!("{:.2} dB", progress.psnr));
            }
        };
        finetune_with_progress(&mut result.scene, &options, &mut show);
        if let Some(bar) = bar {
            bar.finish_and_clear();
        }
        result.timings.push(("finetune", tuning.elapsed().as_secs_f64()));
    }
    let scene = result.scene.scene();

    let export = Instant::now();
    let (width, height) = loaded.original;
    // One group per superpixel region, so editors select a region's paths together.
    let layers: Vec<Option<u32>> = result.scene.paths().iter().map(|placed| placed.region).collect();
    let svg_options = SvgOptions { decimals: args.decimals.into(), ..SvgOptions::default() };
    let svg = to_svg_with(&scene, &layers, width, height, &svg_options)?;
    let written = match &job.svg {
        Sink::File(path) => {
            write_atomic(path, svg.as_bytes()).with_context(|| path.display().to_string())?;
            path.display().to_string()
        }
        Sink::Stdout => {
            let mut out = std::io::stdout().lock();
            out.write_all(svg.as_bytes()).and_then(|()| out.flush()).context("stdout")?;
            "stdout".to_string()
        }
    };

    let needs_render = job.preview.is_some() || job.compare.is_some() || job.metrics.is_some();
    let rendering = needs_render.then(|| render_exact(&scene, w, h, [1.0; 3]));
    if let (Some(path), Some(rendering)) = (&job.preview, &rendering) {
        write_png(path, rendering).with_context(|| path.display().to_string())?;
    }
    if let (Some(path), Some(rendering)) = (&job.compare, &rendering) {
        write_png(path, &side_by_side(&loaded.image, rendering))
            .with_context(|| path.display().to_string())?;
    }
    let export_seconds = export.elapsed().as_secs_f64();
    let mut quality = String::new();
    if let (Some(path), Some(rendering)) = (&job.metrics, &rendering) {
        let drawn = image::DynamicImage::ImageRgb8(rendering.clone()).to_rgb32f();
        let mut seconds = serde_json::Map::new();
        seconds.insert("decode".into(), decoded.into());
        for (stage, value) in &result.timings {
            seconds.insert((*stage).into(), (*value).into());
        }
        seconds.insert("export".into(), export_seconds.into());
        seconds.insert("total".into(), started.elapsed().as_secs_f64().into());
        let value = psnr(&drawn, &loaded.image);
        quality = format!(", PSNR {value:.2} dB");
        let report = serde_json::json!({
            "input": job.source.name(),
            "width": width,
            "height": height,
            "working_width": w,
            "working_height": h,
            "paths": scene.len(),
            "paths_by_stage": result
                .scene
                .counts()
                .into_iter()
                .map(|(origin, count)| (origin.name().to_string(), serde_json::Value::from(count)))
                .collect::<serde_json::Map<_, _>>(),
            "regions": result.scene.segmentation().regions.len(),
            "operating_point": {
                "coarse_share": result.operating_point.coarse_share,
                "refine_share": result.operating_point.refine_share,
            },
            "mse": mse(&drawn, &loaded.image),
            "psnr": value,
            "ssim": ssim(&drawn, &loaded.image),
            "seconds": seconds,
        });
        let text = serde_json::to_string_pretty(&report)?;
        write_atomic(path, text.as_bytes()).with_context(|| path.display().to_string())?;
    }
    Ok(format!(
        "{} -> {written}: {} paths{quality}, {:.2} s",
        job.source.name(),
        scene.len(),
        started.elapsed().as_secs_f64()
    ))
}

/// The input and the rendering next to each other.
fn side_by_side(input: &Rgb32FImage, rendering: &RgbImage) -> RgbImage {
    let (w, h) = rendering.dimensions();
    let input = image::DynamicImage::ImageRgb32F(input.clone()).to_rgb8();
    let mut sheet = RgbImage::from_pixel(2 * w + 4, h, image::Rgb([255, 255, 255]));
    image::imageops::replace(&mut sheet, &input, 0, 0);
    image::imageops::replace(&mut sheet, rendering, (w + 4).into(), 0);
    sheet
}
