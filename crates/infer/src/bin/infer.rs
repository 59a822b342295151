//! `infer`: turns images into SVG with the trained SuperSVG networks.
//!
//! `infer photo.jpg -o photo.svg [--paths 500] [--preview photo.png] [--metrics photo.json]`
//! `infer a.png b.jpg … -o out/` (a folder for several inputs), `infer - -o - < in.png > out.svg`

use std::io::{Read, Write};
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::{Context, anyhow, bail};
use clap::Parser;
use common::decode::{DecodeError, LoadOptions, decode, open};
use common::progress::Bar;
use common::write::{folder_of, probe_folder, write_atomic, write_png};
use common::{Loaded, WORKING_SIZES};
use image::{Rgb32FImage, RgbImage};
use infer::{
    BUILT_IN_COARSE, BUILT_IN_REFINE, FinetuneOptions, Job, Limit, MAX_PATHS, ModelSource, Models,
    PathBudget, Progress, Refiner, Report, Split, bundled, run_with_progress,
};
use raster::{Backend, MAX_DECIMALS, SvgOptions};
use serde::Serialize;

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
    #[arg(long, default_value = "500", value_parser = str::parse::<PathBudget>)]
    paths: PathBudget,
    /// Coarse-model checkpoint (default: the bundled one, built into this program, or
    /// coarse.ckpt in $SUPERSVG_MODELS when that is set).
    #[arg(long)]
    coarse: Option<PathBuf>,
    /// Refinement-model checkpoint (default: the bundled one, built into this program, or
    /// refine.ckpt in $SUPERSVG_MODELS when that is set).
    #[arg(long)]
    refine: Option<PathBuf>,
    /// Coarse paths only, no refinement.
    #[arg(long, conflicts_with = "refine")]
    no_refine: bool,
    /// Who proposes the refinement stage's paths: `network` (E_r), or `optimizer[:STEPS]`, the
    /// exact optimizer in E_r's place (300 Adam steps a region's crop by default; E_r is not
    /// loaded). It takes 13-23 ms a region at 300 steps on 2 cores, where E_r's forward takes
    /// 3: a yardstick for people who train an E_r (what gradient descent finds in its role).
    #[arg(long, default_value = "network", value_parser = str::parse::<Refiner>,
          conflicts_with_all = ["refine", "no_refine"])]
    refiner: Refiner,
    /// Compute backend: flex, ndarray or wgpu.
    #[arg(long, default_value = "flex")]
    backend: Backend,
    /// Long side of the working resolution in pixels, 16 to 8192 (the SVG keeps the input's size).
    /// Time and memory grow with its pixels: at 4096 a photo takes about 9 s and 0.9 GB, at
    /// 8192 a flat picture about 45 s and 3.5 GB (2 cores).
    #[arg(long, default_value_t = 512, value_parser = working_size)]
    size: u32,
    /// Number of superpixels, below `--paths`. By default the regions fill the budget (less
    /// E_r's share of the operating point stored with the coarse model) and each E_c path kept
    /// takes the place of a region, merged away where that costs least, only where the path
    /// draws better than the region did; a given count is kept, and E_c draws only with what it
    /// leaves. At most one per 16 pixels of the working image: more is lowered, with a warning.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..MAX_PATHS as u64))]
    regions: Option<u64>,
    /// How the budget is split between regions, E_c and E_r: `stored` (the operating point
    /// stored with the coarse model), `COARSE,REFINE` (shares of the budget E_c may buy and E_r
    /// keeps, e.g. `0.2,0.1`), or `paper`: the paper's inference for models trained with the
    /// paper preset (budget/64 SLIC regions, every visible E_c path, one pass of E_r over a
    /// second SLIC; no fallback paths, no acceptance test; a background path under all).
    #[arg(long, default_value = "stored", value_parser = str::parse::<Split>)]
    operating_point: Split,
    /// Write a PNG rendering of the result (`.png` file, or a folder).
    #[arg(long)]
    preview: Option<PathBuf>,
    /// Write input and rendering side by side as PNG (`.png` file, or a folder).
    #[arg(long)]
    compare: Option<PathBuf>,
    /// Write MSE, PSNR, SSIM, path count and seconds per stage as JSON (`.json` file, or a folder).
    #[arg(long)]
    metrics: Option<PathBuf>,
    /// SuperSVG-F: fine-tune every path against the image, this many steps (0 to 100 000; each
    /// moves every path).
    #[arg(long, conflicts_with = "finetune_secs", value_parser = clap::value_parser!(u64).range(0..=MAX_FINETUNE_STEPS))]
    finetune_steps: Option<u64>,
    /// SuperSVG-F: fine-tune every path against the image for this many seconds (0 to 3600).
    #[arg(long, value_parser = seconds, allow_hyphen_values = true)]
    finetune_secs: Option<f64>,
    /// Decimals of the SVG's coordinates (0 to 6; 2 keeps 1/100 pixel, fewer make smaller files).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(0..=MAX_DECIMALS as i64))]
    decimals: u8,
    /// Draw regions along shared boundaries fitted with curves that stray at most this far
    /// (pixels of the working image, 0 to 8) from the traced ones: curves an editor can reshape,
    /// each boundary the same curve on both sides. Larger gives fewer curves and bytes. Default:
    /// each region's traced polygon, which draws data/eval better at equal paths and bytes (at 1:
    /// photos 0.24 dB lower at 500 paths for the same bytes, emoji 1.8 dB lower).
    #[arg(long, value_parser = tolerance)]
    tolerance: Option<f32>,
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

/// The most `--finetune-steps`: at 512 px and 500 paths a step takes about 25 ms, so 100 000
/// steps are most of an hour, what `--finetune-secs` allows.
const MAX_FINETUNE_STEPS: u64 = 100_000;

/// Set by the first Ctrl-C (or SIGTERM) during a job that fine-tunes: fine-tuning stops with the
/// best drawing so far, which is written, and no further input is started.
static STOP: AtomicBool = AtomicBool::new(false);
/// Whether the job under way fine-tunes (a stop then writes its best drawing, instead of ending
/// the program at once).
static FINETUNING: AtomicBool = AtomicBool::new(false);

/// Ctrl-C and SIGTERM: during fine-tuning the first asks for the best drawing so far to be
/// written; otherwise, or the second time, the program ends at once (status 130; every file it
/// writes appears whole or not at all).
fn catch_interrupts() {
    let _ = ctrlc::set_handler(|| {
        if FINETUNING.load(Ordering::SeqCst) && !STOP.swap(true, Ordering::SeqCst) {
            eprintln!("\nstopping: writing the best drawing so far (again to abort)");
        } else {
            std::process::exit(130);
        }
    });
}

/// A bar for SuperSVG-F on stderr: time or steps, with the running PSNR.
fn finetune_bar(limit: Limit, shown: bool) -> Bar {
    match limit {
        Limit::Seconds(seconds) => Bar::new("fine-tuning", (seconds * 1000.0) as u64, "ms", shown),
        Limit::Steps(steps) => Bar::new("fine-tuning", steps as u64, "steps", shown),
    }
}

/// A long side within [`WORKING_SIZES`].
fn working_size(text: &str) -> Result<u32, String> {
    match text.parse::<u32>() {
        Ok(size) if WORKING_SIZES.contains(&size) => Ok(size),
        _ => Err(format!(
            "{text:?} is not a working size: a number of pixels from {} to {}",
            WORKING_SIZES.start(),
            WORKING_SIZES.end()
        )),
    }
}

/// An RGB colour in [0, 1].
#[derive(Clone, Copy, Debug)]
struct Colour([f32; 3]);

/// `#rrggbb` (or `rrggbb`) as a colour: six hexadecimal digits, nothing else (`from_str_radix`
/// alone would take `+f` for `0f`).
fn colour(text: &str) -> Result<Colour, String> {
    let hex = text.strip_prefix('#').unwrap_or(text);
    let digits = hex.bytes().all(|b| b.is_ascii_hexdigit());
    let channel =
        |i: usize| hex.get(i..i + 2).filter(|_| digits).and_then(|h| u8::from_str_radix(h, 16).ok());
    match (hex.len(), channel(0), channel(2), channel(4)) {
        (6, Some(r), Some(g), Some(b)) => Ok(Colour([r, g, b].map(|c| c as f32 / 255.0))),
        _ => Err(format!("{text:?} is not a colour: write it #rrggbb")),
    }
}

/// `text` as a finite number within `range`, else an error saying it must be `what` within it.
fn bounded(text: &str, range: std::ops::RangeInclusive<f64>, what: &str) -> Result<f64, String> {
    let value: f64 = text.parse().map_err(|_| format!("{text:?} is not a number"))?;
    if value.is_finite() && range.contains(&value) {
        Ok(value)
    } else {
        Err(format!("{text} is not {what} within {} to {}", range.start(), range.end()))
    }
}

/// A finite number of seconds within [0, 3600].
fn seconds(text: &str) -> Result<f64, String> {
    bounded(text, 0.0..=3600.0, "a number of seconds")
}

/// A finite tolerance within [0, 8] pixels.
fn tolerance(text: &str) -> Result<f32, String> {
    bounded(text, 0.0..=8.0, "a tolerance in pixels").map(|value| value as f32)
}

fn main() -> ExitCode {
    let args = Args::parse();
    catch_interrupts();
    match run(&args) {
        Ok(_) if STOP.load(Ordering::SeqCst) => ExitCode::from(130),
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
struct Planned {
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

/// Every input with its outputs, and the folders and files to write, or the first reason the
/// command cannot run as asked. Creates nothing ([`Plan::prepare`] does, once the models load).
fn plan(args: &Args) -> anyhow::Result<Plan> {
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
    // (absolute path, what would be written there), for every output file.
    let mut taken: Vec<(PathBuf, String)> = Vec::new();
    let mut files = Vec::new();
    let mut jobs = Vec::new();
    for (index, source) in sources.iter().enumerate() {
        let job = Planned {
            source: source.clone(),
            svg: svg[index].clone().map_or(Sink::Stdout, Sink::File),
            preview: preview[index].clone(),
            compare: compare[index].clone(),
            metrics: metrics[index].clone(),
        };
        let outputs = [
            ("the SVG", job.svg.file()),
            ("the --preview", job.preview.as_ref()),
            ("the --compare", job.compare.as_ref()),
            ("the --metrics", job.metrics.as_ref()),
        ];
        for (what, file) in outputs.into_iter().filter_map(|(what, file)| file.map(|f| (what, f))) {
            let absolute = absolute(file);
            let this = format!("{what} of {}", source.name());
            if let Some((_, input)) = inputs.iter().find(|(path, _)| *path == absolute) {
                return Err(anyhow!("{}: is the input {input}; refusing to overwrite it", file.display()));
            }
            if let Some((_, other)) = taken.iter().find(|(path, _)| *path == absolute) {
                return Err(anyhow!(
                    "{}: both {other} and {this} would be written there; give them different names",
                    file.display()
                ));
            }
            if std::fs::symlink_metadata(file).is_ok_and(|m| m.file_type().is_symlink()) && !file.exists() {
                return Err(anyhow!("{}: a link to nothing; remove it or write elsewhere", file.display()));
            }
            taken.push((absolute, this));
            files.push(file.clone());
        }
        jobs.push(job);
    }
    Ok(Plan { jobs, folders, files })
}

/// What [`plan`] decided: the jobs, the output folders to create and the files to write.
struct Plan {
    jobs: Vec<Planned>,
    folders: Vec<PathBuf>,
    files: Vec<PathBuf>,
}

impl Plan {
    /// Creates the output folders and checks that every output can be written there.
    fn prepare(&self) -> anyhow::Result<()> {
        for folder in &self.folders {
            std::fs::create_dir_all(folder).with_context(|| folder.display().to_string())?;
        }
        self.files.iter().try_for_each(|file| writable(file))
    }
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
    probe_folder(folder).map_err(|err| anyhow!(fail(format!("cannot write in {}: {err}", folder.display()))))
}

/// Loads the models, then vectorizes every input; returns how many inputs failed.
fn run(args: &Args) -> anyhow::Result<usize> {
    if let (PathBudget::Count(paths), Some(regions)) = (args.paths, args.regions)
        && regions as usize >= paths
    {
        bail!(
            "--regions {regions} must be below --paths {paths} (each region takes a path, and so does the background)"
        );
    }
    if let (PathBudget::Auto(_), Some(_)) = (args.paths, args.regions) {
        bail!("--regions needs a number of --paths, not auto");
    }
    if args.operating_point == Split::Paper
        && (args.regions.is_some() || matches!(args.paths, PathBudget::Auto(_)))
    {
        bail!("--operating-point paper needs a number of --paths and cuts its own regions (no --regions)");
    }
    if args.operating_point == Split::Paper && args.refiner != Refiner::Network {
        bail!("--operating-point paper runs E_r as the paper does: it takes no --refiner");
    }
    let plan = plan(args)?;
    let device = args.backend.device()?;
    let coarse = match &args.coarse {
        Some(path) => ModelSource::File(path.clone()),
        None => bundled(&BUILT_IN_COARSE)?,
    };
    let refine = match (&args.refine, args.no_refine) {
        (_, true) => None,
        (None, false) if args.refiner != Refiner::Network => None,
        (Some(path), false) => Some(ModelSource::File(path.clone())),
        (None, false) => Some(bundled(&BUILT_IN_REFINE)?),
    };
    let models = Models::from_sources(&coarse, refine.as_ref(), &device)?;
    plan.prepare()?;
    let jobs = plan.jobs;
    if !args.quiet {
        let (coarse, refine) = &models.identities;
        let refine = match (refine, args.refiner) {
            (_, Refiner::Optimizer { steps }) => format!("the exact optimizer ({steps} steps a region)"),
            (Some(refine), Refiner::Network) => refine.to_string(),
            (None, Refiner::Network) => "none".to_string(),
        };
        eprintln!("models: coarse {coarse}, refine {refine}");
    }
    let keeps_none = match args.operating_point {
        Split::Stored => (models.operating_point.refine_share == 0.0)
            .then(|| format!("stored with {}", coarse.name().display())),
        Split::Point(point) => (point.refine_share == 0.0).then(|| "given".to_string()),
        Split::Paper => None,
    };
    if let Some(which) = keeps_none.filter(|_| args.refine.is_some() || args.no_refine) {
        eprintln!(
            "warning: the operating point {which} keeps no share of the budget for E_r: it only \
             fills what the coarse stage leaves unused, so --refine and --no-refine change little"
        );
    }
    let finetune = match (args.finetune_steps, args.finetune_secs) {
        (Some(steps), _) => Some(Limit::Steps(steps as usize)),
        (None, Some(seconds)) => Some(Limit::Seconds(seconds)),
        (None, None) => None,
    };
    let job = Job {
        paths: args.paths,
        regions: args.regions.map(|r| r as usize),
        finetune: finetune.map(|limit| FinetuneOptions { limit, ..FinetuneOptions::default() }),
        svg: SvgOptions { decimals: args.decimals.into(), ..SvgOptions::default() },
        tolerance: args.tolerance,
        operating_point: args.operating_point,
        refiner: args.refiner,
        ..Job::default()
    };

    let bar = Bar::new("", jobs.len() as u64, "images", jobs.len() > 1 && !args.quiet);
    let mut failed = 0;
    for planned in &jobs {
        if STOP.load(Ordering::SeqCst) {
            break;
        }
        match process(planned, &models, &job, args, &device, &bar) {
            Ok(line) if !args.quiet => bar.println(&line),
            Ok(_) => {}
            Err(message) => {
                // A decoding error names its input and says what is wrong in its own words.
                bar.println(&match message.downcast_ref::<DecodeError>() {
                    Some(decoding) => format!("error: {decoding}"),
                    None => format!("error: {}: {message:#}", planned.source.name()),
                });
                failed += 1;
            }
        }
        bar.inc();
    }
    bar.finish();
    Ok(failed)
}

/// The metrics file: the job's report and the input it was made from.
#[derive(Serialize)]
struct Metrics<'a> {
    input: String,
    #[serde(flatten)]
    report: &'a Report,
}

/// One input: vectorize, write the SVG and whatever extra output was asked for; the line
/// that reports it.
fn process(
    planned: &Planned,
    models: &Models,
    job: &Job,
    args: &Args,
    device: &burn::tensor::Device,
    bar: &Bar,
) -> anyhow::Result<String> {
    let options = LoadOptions {
        long_side: args.size,
        allow_truncated: args.allow_truncated,
        background: args.background.0,
    };
    let loaded: Loaded = match &planned.source {
        Source::File(path) => open(path, &options)?,
        Source::Stdin => {
            let mut bytes = Vec::new();
            std::io::stdin().read_to_end(&mut bytes).context("reading stdin")?;
            decode(&bytes, "<stdin>", &options)?
        }
    };
    let tuning = job.finetune.as_ref().map(|f| finetune_bar(f.limit, !args.quiet && !bar.is_shown()));
    let mut show = |progress: &Progress| {
        if let Some(tuning) = &tuning {
            match progress.total_steps {
                Some(_) => tuning.set_position(progress.steps as u64),
                None => tuning.set_position((progress.seconds * 1000.0) as u64),
            }
            tuning.set_message(format!("{:.2} dB", progress.psnr));
        }
        if STOP.load(Ordering::SeqCst) { ControlFlow::Break(()) } else { ControlFlow::Continue(()) }
    };
    FINETUNING.store(job.finetune.is_some(), Ordering::SeqCst);
    let outcome = run_with_progress(models, &loaded, job, device, &mut show);
    FINETUNING.store(false, Ordering::SeqCst);
    let outcome = outcome?;
    if let Some(tuning) = tuning {
        tuning.finish();
    }
    for warning in &outcome.warnings {
        bar.println(&format!("warning: {}: {warning}", planned.source.name()));
    }
    let written = match &planned.svg {
        Sink::File(path) => {
            write_atomic(path, outcome.svg.as_bytes()).with_context(|| path.display().to_string())?;
            path.display().to_string()
        }
        Sink::Stdout => {
            let mut out = std::io::stdout().lock();
            match out.write_all(outcome.svg.as_bytes()).and_then(|()| out.flush()) {
                // The reader went away (`infer - -o - | head`): end quietly, as Unix tools do.
                Err(err) if err.kind() == std::io::ErrorKind::BrokenPipe => std::process::exit(141),
                result => result.context("stdout")?,
            }
            "stdout".to_string()
        }
    };
    if let Some(path) = &planned.preview {
        write_png(path, &outcome.scene.canvas_rgb8()).with_context(|| path.display().to_string())?;
    }
    if let Some(path) = &planned.compare {
        write_png(path, &side_by_side(&loaded.image, &outcome.scene.canvas_rgb8()))
            .with_context(|| path.display().to_string())?;
    }
    let report = &outcome.report;
    let mut quality = String::new();
    if let Some(path) = &planned.metrics {
        let text = serde_json::to_string_pretty(&Metrics { input: planned.source.name(), report })?;
        write_atomic(path, text.as_bytes()).with_context(|| path.display().to_string())?;
        quality = format!(", PSNR {:.2} dB", report.psnr);
    }
    Ok(format!(
        "{} -> {written}: {} paths{quality}, {:.2} s",
        planned.source.name(),
        report.paths,
        report.seconds.total
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
