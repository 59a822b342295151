//! `infer`: turns images into SVG with the trained SuperSVG networks.
//!
//! `infer photo.jpg -o photo.svg [--paths 500] [--preview photo.png] [--metrics photo.json]`
//! `infer a.png b.jpg … -o out/` (a folder for several inputs), `infer - -o - < in.png > out.svg`

use std::io::Write;
use std::ops::ControlFlow;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use anyhow::Context;
use clap::error::ErrorKind;
use clap::{CommandFactory, Parser};
use common::Loaded;
use common::decode::{DecodeError, LoadOptions, decode, open, read_stream};
use common::progress::Bar;
use common::say;
use common::write::{write_atomic, write_png};
use image::{Rgb32FImage, RgbImage};
use infer::cli::{Outputs, Planned, colour, plan, stdout_closed, working_size};
use infer::{
    BUILT_IN_COARSE, BUILT_IN_MOVER, BUILT_IN_REFINE, Fills, FinetuneOptions, InvalidJob, Job, Limit,
    ModelSource, Models, Moves, PathBudget, Progress, Refiner, Report, Split, bundled, run_with_progress,
};
use raster::{Backend, SvgOptions};
use rayon::prelude::*;
use serde::Serialize;

/// Vectorize images into SVG with SuperSVG.
///
/// Outputs: a path ending in `/` (or an existing folder) is a folder that gets one file per
/// input, named after it; anything else is a file, which needs exactly one input. `-` reads the
/// input from stdin or writes the SVG to stdout. Every output is checked before any work:
/// extensions, name collisions, an output that is an input, folders that cannot be written.
#[derive(Parser, Debug)]
#[command(name = "infer", version)]
struct Args {
    /// Input images (png, jpeg, webp, gif, bmp, tiff), or `-` for stdin.
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// The SVG: a `.svg` file for one input, a folder (`out/`) for any number, or `-` (stdout).
    #[arg(short, long)]
    output: PathBuf,
    /// The most paths (2 to 20000; fewer only when no further path lowers the error), or
    /// `auto`: per image, as many as it needs (flat art gets few paths, photos many, at most
    /// 2000).
    #[arg(long, default_value = "500", value_parser = str::parse::<PathBudget>)]
    paths: PathBudget,
    /// Coarse-model checkpoint (default: the bundled one, or coarse.ckpt in $SUPERSVG_MODELS).
    #[arg(long)]
    coarse: Option<PathBuf>,
    /// Refinement-model checkpoint (default: the bundled one, or refine.ckpt in
    /// $SUPERSVG_MODELS).
    #[arg(long)]
    refine: Option<PathBuf>,
    /// No refinement networks: neither E_r's paths nor the mover's moves (what B draws without
    /// them: the regions and E_c).
    #[arg(long, conflicts_with_all = ["refine", "mover"])]
    no_refine: bool,
    /// Who proposes the refinement stage's paths: `network` (E_r), or `optimizer[:STEPS]`, the
    /// exact optimizer in E_r's place (300 Adam steps a region's crop by default; E_r is not
    /// loaded): a yardstick for people who train an E_r.
    #[arg(long, default_value = "network", value_parser = str::parse::<Refiner>,
          conflicts_with_all = ["refine", "no_refine"])]
    refiner: Refiner,
    /// Where the mover E_m moves what SuperSVG-B drew onto the image's edges: `auto` (where B
    /// fills regions with ramps: photos, not flat art, and not with --fills flat),
    /// `on` or `off` (as with --no-refine).
    #[arg(long, default_value = "auto", value_parser = str::parse::<Moves>, conflicts_with = "no_refine")]
    moves: Moves,
    /// The mover's checkpoint (default: the bundled one, or mover.ckpt in $SUPERSVG_MODELS).
    #[arg(long)]
    mover: Option<PathBuf>,
    /// A learned optimizer E_o (`train-optimizer`'s file): SuperSVG-F takes its steps first,
    /// then Adam's (default: Adam alone).
    #[arg(long)]
    optimizer: Option<PathBuf>,
    /// Compute backend: flex, ndarray or wgpu.
    #[arg(long, default_value = "flex")]
    backend: Backend,
    /// Long side of the working resolution in pixels, 16 to 8192 (the SVG keeps the input's
    /// size); time and memory grow with its pixels.
    #[arg(long, default_value_t = 512, value_parser = working_size)]
    size: u32,
    /// Number of superpixels, below `--paths`. By default the regions fill the budget and a
    /// network's path takes a region's place only where it draws better; a given count is
    /// kept. At most one per 16 pixels of the working image: more is lowered, with a warning.
    #[arg(long)]
    regions: Option<usize>,
    /// How the budget is split between regions, E_c and E_r: `stored` (the operating point
    /// stored with the coarse model), `COARSE,REFINE` (shares, e.g. `0.2,0.1`), or `paper`: the
    /// paper's inference, for models trained with the paper preset.
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
    /// SuperSVG-F: fine-tune every shape against the image, this many steps (0 to 100000).
    #[arg(long, conflicts_with = "finetune_secs")]
    finetune_steps: Option<usize>,
    /// SuperSVG-F: fine-tune every shape against the image for this many seconds (0 to 3600).
    #[arg(long, allow_hyphen_values = true)]
    finetune_secs: Option<f64>,
    /// Decimals of the SVG's coordinates (0 to 6; 2 keeps 1/100 pixel, fewer make smaller files).
    #[arg(long, default_value_t = 2)]
    decimals: usize,
    /// Draw regions along shared boundaries fitted with curves that stray at most this far
    /// (pixels of the working image, 0 to 8) from the traced ones: curves an editor can reshape.
    /// Larger gives fewer curves and bytes. Default: each region's traced polygon.
    #[arg(long, allow_hyphen_values = true)]
    tolerance: Option<f32>,
    /// What regions are filled with: `flat` (each its mean colour), `linear` (a colour ramp
    /// where one fits), or `auto` (a ramp where it draws better than its bytes would as regions).
    /// Default: auto, but flat for flat art (icons, emoji). SuperSVG-F starts from what B draws
    /// with the same fills.
    #[arg(long, value_parser = str::parse::<Fills>)]
    fills: Option<Fills>,
    /// The colour transparent pixels are composited over (`#rrggbb`); the SVG is opaque.
    #[arg(long, default_value = "#ffffff", value_parser = colour)]
    background: [f32; 3],
    /// Draw what a truncated JPEG holds instead of refusing it.
    #[arg(long)]
    allow_truncated: bool,
    /// No line per file and no progress bar; errors and warnings only.
    #[arg(short, long)]
    quiet: bool,
}

impl Args {
    /// The job these flags ask for, checked by the library; its error names the flag.
    fn job(&self) -> Result<Job, String> {
        let limit = match (self.finetune_steps, self.finetune_secs) {
            (Some(steps), _) => Some(Limit::Steps(steps)),
            (None, Some(seconds)) => Some(Limit::Seconds(seconds)),
            (None, None) => None,
        };
        let job = Job {
            paths: self.paths,
            regions: self.regions,
            finetune: limit.map(|limit| FinetuneOptions { limit, ..FinetuneOptions::default() }),
            svg: SvgOptions { decimals: self.decimals, ..SvgOptions::default() },
            tolerance: self.tolerance,
            fills: self.fills,
            operating_point: self.operating_point,
            refiner: self.refiner,
            moves: if self.no_refine { Moves::Off } else { self.moves },
            ssim: self.metrics.is_some(),
            ..Job::default()
        };
        job.validate().map_err(|err| format!("{}: {err}", self.flag(&err)))?;
        Ok(job)
    }

    /// The flag that sets what `err` is about.
    fn flag(&self, err: &InvalidJob) -> &'static str {
        match err.field() {
            "regions" => "--regions",
            "operating_point" => "--operating-point",
            "refiner" => "--refiner",
            "tolerance" => "--tolerance",
            "finetune" if self.finetune_steps.is_some() => "--finetune-steps",
            "finetune" => "--finetune-secs",
            "svg" => "--decimals",
            _ => "--paths",
        }
    }
}

/// Set by the first Ctrl-C (or SIGTERM) in a job that fine-tunes: fine-tuning stops with the
/// best drawings so far, which are written, and no further input is started.
static STOP: AtomicBool = AtomicBool::new(false);
/// Whether the job fine-tunes (a stop then writes the drawings under way, instead of ending the
/// program at once).
static FINETUNING: AtomicBool = AtomicBool::new(false);

/// A stop delivered again within this long is the same stop: `timeout` signals the program and
/// then its process group, so one stop arrives twice, and must not count as "again to abort"
/// (a person pressing Ctrl-C twice within a second means it once).
const SAME_STOP: Duration = Duration::from_secs(1);

/// How long a stop lets the drawings under way be written before the program ends anyway: a
/// picture still being drawn (a huge one, thousands of paths) does not hold a stop.
const STOP_GRACE: Duration = Duration::from_secs(2);

/// Ctrl-C, SIGTERM and SIGHUP: in a job that fine-tunes the first asks for the drawings under
/// way to be written (the program ends [`STOP_GRACE`] later at the latest); otherwise, or again
/// after [`SAME_STOP`], the program ends at once. The status is 130 either way, and every file
/// it writes appears whole or not at all ([`common::write::exit`]).
fn catch_interrupts() {
    static FIRST: Mutex<Option<Instant>> = Mutex::new(None);
    let _ = ctrlc::set_handler(|| {
        if !FINETUNING.load(Ordering::SeqCst) {
            common::write::exit(130);
        }
        let mut first = FIRST.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        match *first {
            None => {
                *first = Some(Instant::now());
                STOP.store(true, Ordering::SeqCst);
                say!("\nstopping: writing the best drawing so far (again to abort)");
                std::thread::spawn(|| {
                    std::thread::sleep(STOP_GRACE);
                    say!("stopped: the drawings under way could not be written in time");
                    common::write::exit(130);
                });
            }
            Some(at) if at.elapsed() < SAME_STOP => {}
            Some(_) => common::write::exit(130),
        }
    });
}

fn main() -> ExitCode {
    let args = Args::parse();
    // A value out of range is a usage error, as clap reports one it finds itself (status 2).
    let job = args.job().unwrap_or_else(|err| Args::command().error(ErrorKind::ValueValidation, err).exit());
    if args.output.as_os_str() == "-" && stdout_closed() {
        say!("error: -o -: stdout is closed, so the SVG would go nowhere");
        return ExitCode::FAILURE;
    }
    FINETUNING.store(job.finetune.is_some(), Ordering::SeqCst);
    catch_interrupts();
    match run(&args, &job) {
        Ok(_) if STOP.load(Ordering::SeqCst) => ExitCode::from(130),
        Ok(0) => ExitCode::SUCCESS,
        Ok(failed) => {
            say!("{failed} of {} inputs failed", args.inputs.len());
            ExitCode::FAILURE
        }
        Err(err) => {
            say!("error: {}", common::say::chain(err.as_ref()));
            ExitCode::FAILURE
        }
    }
}

/// Loads the models, then vectorizes every input; returns how many inputs failed.
fn run(args: &Args, job: &Job) -> anyhow::Result<usize> {
    let outputs = Outputs {
        svg: &args.output,
        preview: args.preview.as_deref(),
        compare: args.compare.as_deref(),
        metrics: args.metrics.as_deref(),
    };
    let named: Vec<PathBuf> =
        [&args.coarse, &args.refine, &args.mover].into_iter().flatten().cloned().collect();
    let plan = plan(&args.inputs, &named, outputs)?;
    let device = args.backend.device()?;
    // A model file given is read and verified now, whatever the job; a bundled one is loaded
    // only for a job that can use it, and its weights verified when first used.
    let coarse = match &args.coarse {
        Some(path) => ModelSource::File(path.clone()),
        None => bundled(&BUILT_IN_COARSE)?,
    };
    let refine = match (&args.refine, args.no_refine || args.refiner != Refiner::Network) {
        (_, true) => None,
        (Some(path), false) => Some(ModelSource::File(path.clone())),
        (None, false) => Some(bundled(&BUILT_IN_REFINE)?),
    };
    let mut models = Models::from_sources(&coarse, refine.as_ref(), &device)?;
    let mover = match &args.mover {
        Some(path) => Some(ModelSource::File(path.clone())),
        None if job.may_move() => Some(bundled(&BUILT_IN_MOVER)?),
        None => None,
    };
    if let Some(mover) = mover {
        models = models.with_mover(&mover, &device)?;
    }
    if let Some(path) = &args.optimizer {
        models = models.with_optimizer(&ModelSource::File(path.clone()), &device)?;
    }
    plan.prepare()?;
    let jobs = plan.jobs;
    if !args.quiet {
        let (coarse, refine) = (&models.coarse.identity, &models.refine);
        let refine = match (refine, args.refiner) {
            (_, Refiner::Optimizer { steps }) => format!("the exact optimizer ({steps} steps a region)"),
            (Some(refine), Refiner::Network) => refine.identity.to_string(),
            (None, Refiner::Network) => "none".to_string(),
        };
        let mover = match (&models.mover, job.may_move()) {
            (Some(mover), true) => mover.identity.to_string(),
            (Some(mover), false) => format!("{}, not used by this job", mover.identity),
            (None, _) => "none".to_string(),
        };
        let optimizer = match &models.optimizer {
            Some(optimizer) => format!(", optimizer {}", optimizer.identity),
            None => String::new(),
        };
        say!("models: coarse {coarse}, refine {refine}, mover {mover}{optimizer}");
    }
    let keeps_none = match args.operating_point {
        Split::Stored => (models.operating_point.refine_share == 0.0)
            .then(|| format!("stored with {}", coarse.name().display())),
        Split::Point(point) => (point.refine_share == 0.0).then(|| "given".to_string()),
        Split::Paper => None,
    };
    if let Some(which) = keeps_none.filter(|_| args.refine.is_some() || args.no_refine) {
        say!(
            "warning: the operating point {which} keeps no share of the budget for E_r: it only \
             fills what the coarse stage leaves unused, so --refine changes little, and \
             --no-refine little but the mover's moves"
        );
    }
    let bar = Bar::new("", jobs.len() as u64, "images", jobs.len() > 1 && !args.quiet);
    let failed = AtomicUsize::new(0);
    // Images in parallel, each taking the next free core; the stages of one image split over
    // the cores that are idle (the same rayon pool), so one large image still uses them all.
    // Each drawing depends on its image alone: the SVGs are those of one run per image.
    jobs.par_iter().for_each(|planned| {
        if STOP.load(Ordering::SeqCst) {
            return;
        }
        match process(planned, &models, job, args, &device, &bar) {
            Ok(line) if !args.quiet => bar.println(&line),
            Ok(_) => {}
            Err(message) => {
                // A decoding error names its input and says what is wrong in its own words.
                bar.println(&match message.downcast_ref::<DecodeError>() {
                    Some(decoding) => format!("error: {decoding}"),
                    None => format!("error: {}: {}", planned.name(), common::say::chain(message.as_ref())),
                });
                failed.fetch_add(1, Ordering::SeqCst);
            }
        }
        bar.inc();
    });
    bar.finish();
    Ok(failed.into_inner())
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
        background: args.background,
        ..LoadOptions::default()
    };
    let loaded: Loaded = match &planned.input {
        Some(path) => open(path, &options)?,
        None => {
            let bytes = read_stream(std::io::stdin().lock())
                .map_err(|problem| DecodeError { input: "<stdin>".into(), problem })?;
            decode(&bytes, "<stdin>", &options)?
        }
    };
    let shown = !args.quiet && !bar.is_shown();
    let tuning = job.finetune.as_ref().map(|f| match f.limit {
        Limit::Seconds(seconds) => Bar::new("fine-tuning", (seconds * 1000.0) as u64, "ms", shown),
        Limit::Steps(steps) => Bar::new("fine-tuning", steps as u64, "steps", shown),
    });
    // Where no bar is drawn, a line says when SuperSVG-F begins (after B).
    let mut said = !shown || tuning.as_ref().is_some_and(Bar::is_shown);
    let mut show = |progress: &Progress| {
        if let Some(tuning) = &tuning {
            let position =
                progress.total_steps.map_or((progress.seconds * 1000.0) as u64, |_| progress.steps as u64);
            tuning.set_position(position);
            tuning.set_message(format!("{:.2} dB", progress.psnr));
        }
        if !said {
            said = true;
            bar.println(&format!("{}: fine-tuning", planned.name()));
        }
        if STOP.load(Ordering::SeqCst) { ControlFlow::Break(()) } else { ControlFlow::Continue(()) }
    };
    let outcome = run_with_progress(models, &loaded, job, device, &mut show)?;
    if let Some(tuning) = tuning {
        tuning.finish();
    }
    for warning in &outcome.warnings {
        bar.println(&format!("warning: {}: {warning}", planned.name()));
    }
    let written = match &planned.svg {
        Some(path) => {
            write_atomic(path, outcome.svg.as_bytes()).with_context(|| path.display().to_string())?;
            path.display().to_string()
        }
        None => {
            let mut out = std::io::stdout().lock();
            match out.write_all(outcome.svg.as_bytes()).and_then(|()| out.flush()) {
                // The reader went away (`infer - -o - | head`): end quietly, as Unix tools do.
                Err(err) if err.kind() == std::io::ErrorKind::BrokenPipe => common::write::exit(141),
                result => result.context("stdout")?,
            }
            "stdout".to_string()
        }
    };
    let canvas = outcome.written.canvas_rgb8();
    if let Some(path) = &planned.preview {
        write_png(path, &canvas).with_context(|| path.display().to_string())?;
    }
    if let Some(path) = &planned.compare {
        write_png(path, &side_by_side(&loaded.image, &canvas)).with_context(|| path.display().to_string())?;
    }
    let report = &outcome.report;
    let mut quality = String::new();
    if let Some(path) = &planned.metrics {
        let text = serde_json::to_string_pretty(&Metrics { input: planned.name(), report })?;
        write_atomic(path, text.as_bytes()).with_context(|| path.display().to_string())?;
        quality = format!(", PSNR {:.2} dB", report.psnr);
    }
    let seconds = report.seconds.total;
    Ok(format!("{} -> {written}: {} paths{quality}, {seconds:.2} s", planned.name(), report.paths))
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
