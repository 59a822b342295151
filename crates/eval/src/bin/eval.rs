//! `eval`: SuperSVG (B, and F when asked) against other vectorizers on a folder of images.
//!
//! `eval DIR --paths 500,2000,4000 [--finetune-secs 10] [--sweep 64,250,1000,4000] --out report.md`
//!
//! Every SVG is rendered with resvg, independently of the project's renderers, at the working
//! resolution, and compared with the input scaled to it (MSE, PSNR, SSIM, and LPIPS when
//! `scripts/fetch-lpips.sh` has provided its weights). Writes a markdown report and a contact
//! sheet (input | each method) next to it; with `--sweep`, also the rate–distortion chart
//! (PSNR and LPIPS against SVG kilobytes), so methods are compared at equal file size.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, bail};
use clap::{Parser, ValueEnum};
use common::chart::{self, Mark, Panel, Series};
use common::decode::load;
use common::folder::files_in;
use common::write::{create_temporary_folder, folder_of, probe_folder, write_atomic, write_png};
use common::{WORKING_SIZES, mse, psnr, ssim};
use eval::cli::{command_line, finish, load_models};
use eval::lpips::Lpips;
use eval::peers::{
    PeerError, VtracerSettings, available, count_shapes, mean_color_superpixels, potrace_colors,
    render_chart, render_svg, vtracer, vtracer_with,
};
use eval::rate::{RatePoint, at, frontier};
use eval::spill::spill;
use image::{Rgb32FImage, RgbImage};
use infer::{AutoRule, Job, MAX_PATHS, Outcome, PathBudget, Split, run};
use infer::{FinetuneOptions, Limit};
use infer::{OPTIMIZER_STEPS, RefineTally, Refiner};
use infer::{Origin, StageCounts};
use raster::Backend;

/// What `--peers` can add beside SuperSVG.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum Peer {
    /// vtracer (colour, stacked, spline), when installed.
    Vtracer,
    /// potrace on 16 colour layers, when installed.
    Potrace,
    /// SLIC regions filled with their mean colour, pixel-exact.
    Slic,
    /// SuperSVG's fallback drawing alone: as `infer --paths N --regions N-1 --no-refine` draws it.
    Fallback,
    /// SuperSVG-B without E_r: as `infer --paths N --no-refine` draws it (what E_r adds).
    NoRefine,
    /// The paper's inference with the same models: as `infer --paths N --operating-point paper`
    /// draws it (for models trained with the paper preset, beside the paper's tables).
    Paper,
    /// SuperSVG-B with the exact optimizer proposing in E_r's place: as `infer --paths N
    /// --refiner optimizer` draws it (what E_r's role can reach, for judging a trained E_r).
    Optimizer,
}

/// Dilation (pixels) of a region's mask before its paths' spill is measured: the margin the
/// training's boundary loss allows (`dpw::BOUNDARY_DILATION`).
const SPILL_DILATION: u32 = dpw::BOUNDARY_DILATION as u32;

/// Evaluate SuperSVG and other vectorizers on a folder of images.
#[derive(Parser, Debug)]
#[command(name = "eval", version)]
struct Args {
    /// Folder of images.
    dir: PathBuf,
    /// Path budgets, comma separated (each 2 to 20 000).
    #[arg(long, value_delimiter = ',', default_value = "500,2000", allow_hyphen_values = true)]
    paths: Vec<usize>,
    /// Also run SuperSVG-F, fine-tuning for this many seconds per image.
    #[arg(long, allow_hyphen_values = true)]
    finetune_secs: Option<f64>,
    /// The markdown report to write; the contact sheet goes next to it as PNG.
    #[arg(long)]
    out: PathBuf,
    /// Also write SuperSVG's SVGs into this folder (`IMAGE-b-500.svg`, `IMAGE-f-500.svg`,
    /// `IMAGE-auto.svg`, `IMAGE-fallback-500.svg`, `IMAGE-no-refine-500.svg`,
    /// `IMAGE-paper-500.svg`, `IMAGE-optimizer-500.svg`): the files `infer`
    /// writes with the same settings.
    #[arg(long)]
    svgs: Option<PathBuf>,
    /// Coarse-model checkpoint (default: the bundled one).
    #[arg(long)]
    coarse: Option<PathBuf>,
    /// Refinement-model checkpoint (default: the bundled one).
    #[arg(long)]
    refine: Option<PathBuf>,
    /// Compute backend: flex, ndarray or wgpu.
    #[arg(long, default_value = "flex")]
    backend: Backend,
    /// Long side of the working resolution.
    #[arg(long, default_value_t = 512, allow_hyphen_values = true)]
    size: u32,
    /// Peers, comma separated; empty for none.
    #[arg(long, value_delimiter = ',', default_value = "vtracer,potrace,slic,fallback,no-refine")]
    peers: Vec<PeerArg>,
    /// Evaluate only the first N images.
    #[arg(long)]
    limit: Option<usize>,
    /// Rate–distortion sweep: SuperSVG-B (and the fallback alone, when it is a peer) at these
    /// path budgets, comma separated, and vtracer (when it is a peer) over its settings grid.
    /// The report gets a section reading each method at vtracer's file sizes, and the chart
    /// goes beside it (`REPORT-rate.png` and `.svg`).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    sweep: Vec<usize>,
    /// How SuperSVG-B splits each budget (`infer --operating-point`): `stored`, or
    /// `COARSE,REFINE` shares (`0,0.1` gives E_r a tenth; the `no-refine` row then shows what it
    /// is worth). The paper's inference is the `paper` peer.
    #[arg(long, default_value = "stored", value_parser = str::parse::<Split>)]
    operating_point: Split,
    /// SuperSVG's regions drawn along shared boundary curves fitted within this many pixels
    /// (`infer --tolerance`, 0 to 8), in every drawing of ours; by default traced polygons.
    #[arg(long)]
    tolerance: Option<f32>,
}

/// One entry of `--peers`: a peer, or nothing (`--peers ''`).
#[derive(Clone, Copy, Debug, PartialEq)]
struct PeerArg(Option<Peer>);

impl std::str::FromStr for PeerArg {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, String> {
        if text.is_empty() {
            return Ok(Self(None));
        }
        Peer::from_str(text, true).map(|peer| Self(Some(peer))).map_err(|_| {
            let known: Vec<String> = Peer::value_variants()
                .iter()
                .filter_map(|p| p.to_possible_value())
                .map(|v| v.get_name().into())
                .collect();
            format!("unknown peer `{text}` (known: {})", known.join(", "))
        })
    }
}

/// A way of drawing an image that the report has rows for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Method {
    /// SuperSVG-B at the budget.
    OursB,
    /// SuperSVG-F: B fine-tuned.
    OursF,
    /// SuperSVG-B with `--paths auto`.
    OursAuto,
    /// SuperSVG-B without E_r.
    OursNoRefine,
    /// SuperSVG-B at the paper's operating point.
    OursPaper,
    /// SuperSVG-B with the exact optimizer in E_r's place.
    OursOptimizer,
    /// The fallback drawing alone.
    Fallback,
    /// vtracer with one knob searched to the budget.
    Vtracer,
    /// vtracer's default settings.
    VtracerDefault,
    /// potrace on colour layers.
    Potrace,
    /// The SLIC mosaic.
    Slic,
}

impl Method {
    /// The row's name in the report.
    fn name(self) -> &'static str {
        match self {
            Method::OursB => "SuperSVG-B (ours)",
            Method::OursF => "SuperSVG-F (ours)",
            Method::OursAuto => "SuperSVG-B (ours), --paths auto",
            Method::OursNoRefine => "SuperSVG-B without E_r (--no-refine)",
            Method::OursPaper => "SuperSVG-B, the paper's inference (--operating-point paper)",
            Method::OursOptimizer => "SuperSVG-B, the exact optimizer in E_r's place (--refiner optimizer)",
            Method::Fallback => "fallback alone (traced regions, mean colour)",
            Method::Vtracer => "vtracer",
            Method::VtracerDefault => "vtracer (default settings)",
            Method::Potrace => "potrace, 16 colour layers",
            Method::Slic => "SLIC regions, mean colour",
        }
    }
}

/// The budget a table is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Table {
    /// Every method at this many paths (or shapes).
    Paths(usize),
    /// Each method chooses: `--paths auto`, vtracer's defaults.
    Own,
    /// One point of the rate–distortion sweep (reported as curves, not as a table).
    Sweep(Setting),
}

/// A point of the rate–distortion sweep: what was set.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Setting {
    /// SuperSVG's path budget.
    Paths(usize),
    /// vtracer's settings.
    Vtracer(VtracerSettings),
}

impl Table {
    fn title(self) -> String {
        match self {
            Table::Paths(paths) | Table::Sweep(Setting::Paths(paths)) => format!("{paths} paths"),
            Table::Own => "each method's own budget".to_string(),
            Table::Sweep(Setting::Vtracer(settings)) => settings.label(),
        }
    }
}

/// One method's result on one image at one budget.
struct Row {
    /// The image's file name.
    image: String,
    shapes: usize,
    /// Size of the SVG file (none for the pixel-exact mosaic, which is no SVG).
    bytes: Option<usize>,
    mse: f64,
    psnr: f64,
    ssim: f64,
    lpips: Option<f64>,
    seconds: f64,
    /// Paths per stage and spill, for SuperSVG's own drawings.
    anatomy: Option<Anatomy>,
}

/// A method's picture of one image: its rendering, shapes and SVG size.
struct Drawn {
    image: Rgb32FImage,
    shapes: usize,
    bytes: Option<usize>,
}

/// What a SuperSVG drawing is made of.
#[derive(Clone)]
struct Anatomy {
    stages: StageCounts,
    spill: f64,
    refinement: RefineTally,
}

fn main() -> ExitCode {
    finish(run_eval(Args::parse()))
}

fn run_eval(args: Args) -> anyhow::Result<()> {
    for (flag, budgets) in [("--paths", &args.paths), ("--sweep", &args.sweep)] {
        if let Some(bad) = budgets.iter().find(|&&p| !(2..=MAX_PATHS).contains(&p)) {
            bail!("{flag}: {bad} is out of range (2, the background and one region, to {MAX_PATHS})");
        }
    }
    if !WORKING_SIZES.contains(&args.size) {
        bail!(
            "--size: {} is out of range ({} to {} pixels)",
            args.size,
            WORKING_SIZES.start(),
            WORKING_SIZES.end()
        );
    }
    if let Some(seconds) = args.finetune_secs.filter(|s| !(s.is_finite() && *s >= 0.0)) {
        bail!("--finetune-secs: {seconds} is not a number of seconds");
    }
    if args.operating_point == Split::Paper {
        bail!("--operating-point paper: the paper's inference is a peer here (--peers paper)");
    }
    if let Some(tolerance) = args.tolerance.filter(|t| !(0.0..=8.0).contains(t)) {
        bail!("--tolerance: {tolerance} is not a tolerance in pixels (0 to 8)");
    }
    let mut images = files_in(&args.dir)?;
    images.truncate(args.limit.unwrap_or(usize::MAX));
    if images.is_empty() {
        bail!("{}: no images", args.dir.display());
    }
    // The report is written last: a folder it cannot go in is said now, before any work.
    let report_folder = folder_of(&args.out);
    probe_folder(report_folder)
        .with_context(|| format!("{}: cannot write in {}", args.out.display(), report_folder.display()))?;
    if let Some(folder) = &args.svgs {
        std::fs::create_dir_all(folder).with_context(|| folder.display().to_string())?;
    }
    let device = args.backend.device()?;
    let models = load_models(args.coarse.as_deref(), args.refine.as_deref(), &device)?;
    // The fallback and no-refine rows draw without E_r (for the fallback: a region that lowers
    // nothing is not drawn, and E_r would spend what it leaves), as `infer --no-refine` does.
    let regions_only =
        infer::Models { refine: None, identities: (models.identities.0.clone(), None), ..models.clone() };
    // The peers read the input's format from its extension: the scratch folder is made new,
    // so the fixed names inside it are safe.
    let scratch = create_temporary_folder(&std::env::temp_dir(), "supersvg-eval")
        .with_context(|| format!("scratch folder in {}", std::env::temp_dir().display()))?;

    let wanted = |peer: Peer| args.peers.contains(&PeerArg(Some(peer)));
    let use_vtracer = wanted(Peer::Vtracer) && available("vtracer");
    let use_potrace = wanted(Peer::Potrace) && available("potrace");
    let mut notes = Vec::new();
    for (peer, used) in [("vtracer", use_vtracer), ("potrace", use_potrace)] {
        if args
            .peers
            .iter()
            .any(|p| p.0.and_then(|p| p.to_possible_value()).is_some_and(|v| v.get_name() == peer))
            && !used
        {
            notes.push(format!("{peer} is not installed: its rows are missing."));
        }
    }
    let lpips = match Lpips::load(&Lpips::default_folder(), &device) {
        Ok(lpips) => Some(lpips),
        Err(err) => {
            notes.push(format!("LPIPS skipped: {err}."));
            None
        }
    };

    let mut results: BTreeMap<(Table, Method), Vec<Row>> = BTreeMap::new();
    // Per image: the input (no method), then each method's drawing at the first budget.
    let mut sheet_rows: Vec<Vec<(Option<Method>, Rgb32FImage)>> = Vec::new();
    let mut evaluated = 0;
    for (index, path) in images.iter().enumerate() {
        let loaded = match load(path, args.size) {
            Ok(loaded) => loaded,
            Err(err) => {
                eprintln!("skipping {err}");
                continue;
            }
        };
        evaluated += 1;
        let image = &loaded.image;
        let (width, height) = image.dimensions();
        let name = path.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        let stem = path.file_stem().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        let png = scratch.join("input.png");
        write_png(&png, &to_rgb8(image))?;
        let mut tiles = vec![(None, image.clone())];
        let first = Table::Paths(args.paths[0]);
        let mut record = |table: Table,
                          method: Method,
                          drawn: &Result<Drawn, PeerError>,
                          seconds: f64,
                          anatomy: Option<Anatomy>,
                          tiles: &mut Vec<(Option<Method>, Rgb32FImage)>| {
            match drawn {
                Ok(Drawn { image: drawn, shapes, bytes }) => {
                    let row = Row {
                        image: name.clone(),
                        shapes: *shapes,
                        bytes: *bytes,
                        mse: mse(drawn, image),
                        psnr: psnr(drawn, image),
                        ssim: ssim(drawn, image),
                        lpips: lpips.as_ref().map(|net| net.distance(drawn, image)),
                        seconds,
                        anatomy,
                    };
                    if table == first {
                        tiles.push((Some(method), drawn.clone()));
                    }
                    results.entry((table, method)).or_default().push(row);
                }
                Err(err) => eprintln!("{}: {} at {}: {err}", path.display(), method.name(), table.title()),
            }
        };
        let rendered = |svg: &str| {
            render_svg(svg, width, height).map(|drawn| Drawn {
                image: drawn,
                shapes: count_shapes(svg),
                bytes: Some(svg.len()),
            })
        };
        // Ours: the SVG `infer` writes, rendered by resvg like every peer's, and kept if asked.
        let ours = |table: Table, method: Method, outcome: &Outcome| {
            if let Some(folder) = &args.svgs {
                let suffix = match (method, table) {
                    (Method::OursAuto, _) => "auto".to_string(),
                    (Method::OursF, Table::Paths(n)) => format!("f-{n}"),
                    (Method::Fallback, Table::Paths(n)) => format!("fallback-{n}"),
                    (Method::OursNoRefine, Table::Paths(n)) => format!("no-refine-{n}"),
                    (Method::OursPaper, Table::Paths(n)) => format!("paper-{n}"),
                    (Method::OursOptimizer, Table::Paths(n)) => format!("optimizer-{n}"),
                    (_, Table::Paths(n)) => format!("b-{n}"),
                    (_, Table::Own | Table::Sweep(_)) => "own".to_string(),
                };
                let file = folder.join(format!("{stem}-{suffix}.svg"));
                if let Err(err) = write_atomic(&file, outcome.svg.as_bytes()) {
                    eprintln!("{}: {err}", file.display());
                }
            }
            let anatomy = Anatomy {
                stages: outcome.report.paths_by_stage,
                spill: spill(outcome.scene.paths(), outcome.scene.segmentation(), SPILL_DILATION),
                refinement: outcome.report.refinement,
            };
            (rendered(&outcome.svg), outcome.report.seconds.total, Some(anatomy))
        };
        // The fixed budgets in their order, then the sweep's other budgets: SuperSVG-B and the
        // fallback are drawn once per budget and recorded in every table that has it.
        let mut budgets: Vec<usize> = Vec::new();
        for &budget in args.paths.iter().chain(&args.sweep) {
            if !budgets.contains(&budget) {
                budgets.push(budget);
            }
        }
        for &budget in &budgets {
            let table = Table::Paths(budget);
            let mut tables = Vec::new();
            if args.paths.contains(&budget) {
                tables.push(table);
            }
            if args.sweep.contains(&budget) {
                tables.push(Table::Sweep(Setting::Paths(budget)));
            }
            let job = Job {
                paths: PathBudget::Count(budget),
                tolerance: args.tolerance,
                operating_point: args.operating_point,
                ..Job::default()
            };
            let outcome = run(&models, &loaded, &job, &device)?;
            let (drawn, seconds, anatomy) = ours(table, Method::OursB, &outcome);
            for &table in &tables {
                record(table, Method::OursB, &drawn, seconds, anatomy.clone(), &mut tiles);
            }
            if wanted(Peer::Fallback) {
                let alone = Job { regions: Some(budget - 1), ..job.clone() };
                let outcome = run(&regions_only, &loaded, &alone, &device)?;
                let (drawn, seconds, anatomy) = ours(table, Method::Fallback, &outcome);
                for &table in &tables {
                    record(table, Method::Fallback, &drawn, seconds, anatomy.clone(), &mut tiles);
                }
            }
            if !args.paths.contains(&budget) {
                continue;
            }
            if let Some(limit) = args.finetune_secs {
                let options = FinetuneOptions { limit: Limit::Seconds(limit), ..FinetuneOptions::default() };
                let tuned = outcome.finetuned(&loaded, &job, &options, &mut |_| ControlFlow::Continue(()))?;
                let (drawn, seconds, anatomy) = ours(table, Method::OursF, &tuned);
                record(table, Method::OursF, &drawn, seconds, anatomy, &mut tiles);
            }
            if wanted(Peer::NoRefine) {
                let outcome = run(&regions_only, &loaded, &job, &device)?;
                let (drawn, seconds, anatomy) = ours(table, Method::OursNoRefine, &outcome);
                record(table, Method::OursNoRefine, &drawn, seconds, anatomy, &mut tiles);
            }
            if wanted(Peer::Paper) {
                let paper = Job { operating_point: Split::Paper, ..job.clone() };
                let outcome = run(&models, &loaded, &paper, &device)?;
                let (drawn, seconds, anatomy) = ours(table, Method::OursPaper, &outcome);
                record(table, Method::OursPaper, &drawn, seconds, anatomy, &mut tiles);
            }
            if wanted(Peer::Optimizer) {
                let optimized = Job { refiner: Refiner::Optimizer { steps: OPTIMIZER_STEPS }, ..job.clone() };
                let outcome = run(&regions_only, &loaded, &optimized, &device)?;
                let (drawn, seconds, anatomy) = ours(table, Method::OursOptimizer, &outcome);
                record(table, Method::OursOptimizer, &drawn, seconds, anatomy, &mut tiles);
            }
            if use_vtracer {
                let traced = vtracer(&png, Some(budget), &scratch);
                let seconds = traced.as_ref().map_or(0.0, |t| t.seconds);
                let drawn = traced.and_then(|t| rendered(&t.svg));
                record(table, Method::Vtracer, &drawn, seconds, None, &mut tiles);
            }
            if use_potrace {
                let traced = potrace_colors(image, 16, Some(budget), &scratch);
                let seconds = traced.as_ref().map_or(0.0, |t| t.seconds);
                let drawn = traced.and_then(|t| rendered(&t.svg));
                record(table, Method::Potrace, &drawn, seconds, None, &mut tiles);
            }
            if wanted(Peer::Slic) {
                let mosaic = mean_color_superpixels(image, budget);
                let seconds = mosaic.as_ref().map_or(0.0, |m| m.seconds);
                let drawn = mosaic.map(|m| Drawn { image: m.image, shapes: m.regions, bytes: None });
                record(table, Method::Slic, &drawn, seconds, None, &mut tiles);
            }
        }
        if use_vtracer && !args.sweep.is_empty() {
            for settings in VtracerSettings::sweep() {
                let traced = vtracer_with(&png, settings, &scratch);
                let seconds = traced.as_ref().map_or(0.0, |t| t.seconds);
                let drawn = traced.and_then(|t| rendered(&t.svg));
                let table = Table::Sweep(Setting::Vtracer(settings));
                record(table, Method::Vtracer, &drawn, seconds, None, &mut tiles);
            }
        }
        let auto = PathBudget::Auto(AutoRule::default());
        let job = Job {
            paths: auto,
            tolerance: args.tolerance,
            operating_point: args.operating_point,
            ..Job::default()
        };
        let outcome = run(&models, &loaded, &job, &device)?;
        let (drawn, seconds, anatomy) = ours(Table::Own, Method::OursAuto, &outcome);
        record(Table::Own, Method::OursAuto, &drawn, seconds, anatomy, &mut tiles);
        if use_vtracer {
            let traced = vtracer(&png, None, &scratch);
            let seconds = traced.as_ref().map_or(0.0, |t| t.seconds);
            let drawn = traced.and_then(|t| rendered(&t.svg));
            record(Table::Own, Method::VtracerDefault, &drawn, seconds, None, &mut tiles);
        }
        let _ = std::fs::remove_file(&png);
        if sheet_rows.len() < 8 {
            sheet_rows.push(tiles);
        }
        eprintln!("[{}/{}] {}", index + 1, images.len(), path.display());
    }
    let _ = std::fs::remove_dir_all(&scratch);
    if evaluated == 0 {
        bail!("{}: no readable images", args.dir.display());
    }

    let sheet_path = args.out.with_extension("png");
    write_png(&sheet_path, &contact_sheet(&sheet_rows, 160))
        .with_context(|| sheet_path.display().to_string())?;
    let columns: Vec<&str> = sheet_rows
        .first()
        .map(|row| row.iter().map(|(method, _)| method.map_or("input", Method::name)).collect())
        .unwrap_or_default();
    let mut report = report(&args, evaluated, &results, &notes, (&sheet_path, &columns));
    if !args.sweep.is_empty() {
        let points = sweep_points(&results, evaluated);
        let stem = args.out.file_stem().map_or_else(|| "report".into(), |s| s.to_string_lossy().into_owned());
        let chart_svg = args.out.with_file_name(format!("{stem}-rate.svg"));
        let chart_png = chart_svg.with_extension("png");
        let document = rate_chart(&points);
        write_atomic(&chart_svg, document.as_bytes()).with_context(|| chart_svg.display().to_string())?;
        let pixels = render_chart(&document).with_context(|| chart_svg.display().to_string())?;
        write_png(&chart_png, &pixels).with_context(|| chart_png.display().to_string())?;
        report.push_str(&rate_section(&points, &chart_png));
    }
    write_atomic(&args.out, report.as_bytes()).with_context(|| args.out.display().to_string())?;
    eprintln!("wrote {} and {}", args.out.display(), sheet_path.display());
    Ok(())
}

fn to_rgb8(image: &Rgb32FImage) -> RgbImage {
    image::DynamicImage::ImageRgb32F(image.clone()).to_rgb8()
}

/// The markdown report: one table per budget with the mean over images, then where SuperSVG's
/// paths came from.
fn report(
    args: &Args,
    images: usize,
    results: &BTreeMap<(Table, Method), Vec<Row>>,
    notes: &[String],
    (sheet, columns): (&Path, &[&str]),
) -> String {
    let mut text = format!(
        "# Evaluation on `{}`\n\n{images} images, working resolution {} px (long side). Every SVG rendered \
         with resvg and compared with the input at that size; means over images. \"shapes\" counts closed \
         subpaths, the same unit for every method.\n\nCommand: `{}`\n\n",
        args.dir.display(),
        args.size,
        command_line("eval", std::env::args().skip(1))
    );
    for table in tables(results) {
        let title = table.title();
        let title = title[..1].to_uppercase() + &title[1..];
        let _ = writeln!(
            text,
            "## {title}\n\n| method | shapes | SVG KB | PSNR (dB) | SSIM | MSE | LPIPS | seconds / image |\n| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"
        );
        let rows_here = results.iter().filter(|((t, _), _)| *t == table);
        for ((_, method), rows) in rows_here.clone() {
            let method = method.name();
            let mean = |f: &dyn Fn(&Row) -> f64| rows.iter().map(f).sum::<f64>() / rows.len() as f64;
            let kilobytes = if rows.iter().all(|r| r.bytes.is_some()) {
                format!("{:.1}", mean(&|r| r.bytes.unwrap_or(0) as f64) / 1000.0)
            } else {
                "—".to_string()
            };
            let lpips = if rows.iter().all(|r| r.lpips.is_some()) {
                format!("{:.4}", mean(&|r| r.lpips.unwrap_or(f64::NAN)))
            } else {
                "—".to_string()
            };
            let _ = writeln!(
                text,
                "| {method} | {:.0} | {kilobytes} | {:.2} | {:.4} | {:.5} | {lpips} | {:.2} |",
                mean(&|r| r.shapes as f64),
                mean(&|r| r.psnr),
                mean(&|r| r.ssim),
                mean(&|r| r.mse),
                mean(&|r| r.seconds)
            );
        }
        let ours: Vec<_> = rows_here.filter(|(_, rows)| rows.iter().all(|r| r.anatomy.is_some())).collect();
        if !ours.is_empty() {
            let stages: Vec<&str> = Origin::ALL.iter().map(|o| o.name()).collect();
            let _ = writeln!(
                text,
                "\nWhere SuperSVG's paths come from (mean paths per image by stage), spill (share of \
                 region paths' area outside their region dilated by {SPILL_DILATION} px), and what E_r \
                 did (paths kept of those it proposed, summed over images; the PSNR its kept paths \
                 added, mean):\n\n| method | {} | spill | E_r kept / proposed | E_r dB |\n| --- |{} ---: | \
                 ---: | ---: |",
                stages.join(" | "),
                " ---: |".repeat(stages.len())
            );
            for ((_, method), rows) in ours {
                let anatomy = || rows.iter().filter_map(|r| r.anatomy.as_ref());
                let per_stage: Vec<String> = Origin::ALL
                    .iter()
                    .map(|&origin| {
                        let count: usize = anatomy().map(|a| a.stages.of(origin)).sum();
                        format!("{:.1}", count as f64 / rows.len() as f64)
                    })
                    .collect();
                let spill = anatomy().map(|a| a.spill).sum::<f64>() / rows.len() as f64;
                let kept: usize = anatomy().map(|a| a.refinement.kept).sum();
                let proposed: usize = anatomy().map(|a| a.refinement.proposed).sum();
                let gain = anatomy().map(|a| a.refinement.gain_db).sum::<f64>() / rows.len() as f64;
                let _ = writeln!(
                    text,
                    "| {} | {} | {spill:.3} | {kept} / {proposed} | {gain:+.2} |",
                    method.name(),
                    per_stage.join(" | ")
                );
            }
        }
        text.push('\n');
    }
    text.push_str(&per_image(results));
    for note in notes {
        let _ = writeln!(text, "- {note}");
    }
    let _ = writeln!(
        text,
        "\nContact sheet at {} paths: `{}` (columns: {}).",
        args.paths[0],
        sheet.display(),
        columns.join(" | ")
    );
    text
}

/// The tables the results fill, in order.
fn tables(results: &BTreeMap<(Table, Method), Vec<Row>>) -> Vec<Table> {
    let mut tables: Vec<Table> =
        results.keys().map(|(table, _)| *table).filter(|t| !matches!(t, Table::Sweep(_))).collect();
    tables.dedup();
    tables
}

/// One setting of the sweep, averaged over the images.
struct SweepPoint {
    setting: Setting,
    point: RatePoint,
    seconds: f64,
}

/// The sweep's means per method, settings in order. A setting that did not draw every one of
/// the `images` is left out (its error was printed), so every point averages the same images.
fn sweep_points(
    results: &BTreeMap<(Table, Method), Vec<Row>>,
    images: usize,
) -> BTreeMap<Method, Vec<SweepPoint>> {
    let mut points: BTreeMap<Method, Vec<SweepPoint>> = BTreeMap::new();
    for ((table, method), rows) in results {
        let (Table::Sweep(setting), true) = (table, rows.len() == images) else { continue };
        let Some(bytes) = rows.iter().map(|r| r.bytes).sum::<Option<usize>>() else { continue };
        let mean = |f: &dyn Fn(&Row) -> f64| rows.iter().map(f).sum::<f64>() / rows.len() as f64;
        let lpips = rows.iter().map(|r| r.lpips).sum::<Option<f64>>().map(|sum| sum / rows.len() as f64);
        let point = RatePoint {
            kilobytes: bytes as f64 / rows.len() as f64 / 1000.0,
            psnr: mean(&|r| r.psnr),
            lpips,
        };
        points.entry(*method).or_default().push(SweepPoint {
            setting: *setting,
            point,
            seconds: mean(&|r| r.seconds),
        });
    }
    points
}

/// Colour of a method's series in the chart: the same in both panels.
fn colour(method: Method) -> usize {
    match method {
        Method::OursB => 0,
        Method::Fallback => 1,
        Method::Vtracer => 2,
        _ => 3,
    }
}

/// The rate–distortion chart: PSNR, and LPIPS where it was measured, against SVG kilobytes;
/// our budgets as lines, vtracer's settings as dots with their frontier dashed.
fn rate_chart(points: &BTreeMap<Method, Vec<SweepPoint>>) -> String {
    let quality: [(&str, &str, fn(&RatePoint) -> Option<f64>, fn(&RatePoint) -> Option<f64>); 2] = [
        ("PSNR against file size", "PSNR (dB), higher is better", |p| Some(p.psnr), |p| Some(p.psnr)),
        ("LPIPS against file size", "LPIPS, lower is better", |p| p.lpips, |p| p.lpips.map(|l| -l)),
    ];
    let measured =
        |pick: fn(&RatePoint) -> Option<f64>| points.values().flatten().all(|p| pick(&p.point).is_some());
    let panels: Vec<Panel> = quality
        .iter()
        .filter(|(_, _, value, _)| measured(*value))
        .map(|&(title, y_label, value, better)| {
            let mut series = Vec::new();
            // Ours last, so they are drawn over the peers.
            for (&method, sweep) in points.iter().rev() {
                let xy = |list: &[RatePoint]| {
                    list.iter().filter_map(|p| value(p).map(|v| (p.kilobytes, v))).collect()
                };
                let rates: Vec<RatePoint> = sweep.iter().map(|p| p.point).collect();
                if method == Method::Vtracer {
                    series.push(Series {
                        name: format!("{} settings", method.name()),
                        colour: colour(method),
                        mark: Mark::Dots,
                        points: xy(&rates),
                    });
                    series.push(Series {
                        name: format!("{}, best at each size", method.name()),
                        colour: colour(method),
                        mark: Mark::Dashed,
                        points: xy(&frontier(&rates, better)),
                    });
                } else {
                    series.push(Series {
                        name: format!("{}, by path budget", method.name()),
                        colour: colour(method),
                        mark: Mark::LineAndDots,
                        points: xy(&rates),
                    });
                }
            }
            Panel {
                title: title.to_string(),
                x_label: "SVG size (KB, log scale)".to_string(),
                y_label: y_label.to_string(),
                log_x: true,
                series,
            }
        })
        .collect();
    chart::svg(&panels)
}

/// The report's rate–distortion section: each method's sweep, then every vtracer setting
/// beside our methods at the same file size.
fn rate_section(points: &BTreeMap<Method, Vec<SweepPoint>>, chart: &Path) -> String {
    let mut text = format!(
        "## Rate and distortion\n\nMeans over the images at each setting: SuperSVG at each `--sweep` budget, \
         vtracer over speckle 0–16 at colour precision 3, 4, 6 and 8. Chart: `{}` (PSNR and LPIPS against SVG \
         KB).\n\n| method | setting | SVG KB | PSNR (dB) | LPIPS | seconds / image |\n| --- | --- | ---: | ---: | ---: | ---: |\n",
        chart.display()
    );
    let lpips = |value: Option<f64>| value.map_or_else(|| "—".to_string(), |l| format!("{l:.4}"));
    for (method, sweep) in points {
        for SweepPoint { setting, point, seconds } in sweep {
            let _ = writeln!(
                text,
                "| {} | {} | {:.1} | {:.2} | {} | {seconds:.2} |",
                method.name(),
                Table::Sweep(*setting).title(),
                point.kilobytes,
                point.psnr,
                lpips(point.lpips)
            );
        }
    }
    let Some(vtracer) = points.get(&Method::Vtracer) else { return text };
    let ours: Vec<(Method, Vec<RatePoint>)> = points
        .iter()
        .filter(|(m, _)| **m != Method::Vtracer)
        .map(|(m, sweep)| (*m, sweep.iter().map(|p| p.point).collect()))
        .collect();
    let header: Vec<String> = ours.iter().map(|(m, _)| format!("{} PSNR / LPIPS", m.name())).collect();
    let _ = writeln!(
        text,
        "\n### At vtracer's file sizes\n\nEach vtracer setting beside our methods at the same SVG size, read \
         off their curves (linear in log KB between budgets). Past the largest file a method drew, its \
         largest drawing is shown, marked ≤ (a smaller file); — where the size is below what the sweep \
         covers.\n\n| vtracer setting | SVG KB | vtracer PSNR / LPIPS | {} |\n| --- | ---: | ---: |{}",
        header.join(" | "),
        " ---: |".repeat(ours.len())
    );
    // Per method: (sizes covered, PSNR above vtracer, LPIPS below vtracer, settings past its
    // largest file that its largest drawing beats on both).
    let mut wins = vec![(0, 0, 0, 0); ours.len()];
    for SweepPoint { setting, point, .. } in vtracer {
        let cells: Vec<String> = ours
            .iter()
            .zip(&mut wins)
            .map(|((_, curve), wins)| match at(curve, point.kilobytes, |p| Some(p.psnr)) {
                Some(psnr) => {
                    let ours_lpips = at(curve, point.kilobytes, |p| p.lpips);
                    wins.0 += 1;
                    wins.1 += usize::from(psnr > point.psnr);
                    wins.2 += usize::from(ours_lpips.zip(point.lpips).is_some_and(|(o, v)| o < v));
                    format!("{psnr:.2} ({:+.2}) / {}", psnr - point.psnr, lpips(ours_lpips))
                }
                None => match curve.iter().max_by(|a, b| a.kilobytes.total_cmp(&b.kilobytes)) {
                    Some(largest) if largest.kilobytes < point.kilobytes => {
                        let beats = largest.psnr > point.psnr
                            && largest.lpips.zip(point.lpips).is_some_and(|(o, v)| o < v);
                        wins.3 += usize::from(beats);
                        format!(
                            "≤ {:.2} ({:+.2}) / {}",
                            largest.psnr,
                            largest.psnr - point.psnr,
                            lpips(largest.lpips)
                        )
                    }
                    _ => "—".to_string(),
                },
            })
            .collect();
        let _ = writeln!(
            text,
            "| {} | {:.1} | {:.2} / {} | {} |",
            Table::Sweep(*setting).title(),
            point.kilobytes,
            point.psnr,
            lpips(point.lpips),
            cells.join(" | ")
        );
    }
    text.push('\n');
    for ((method, _), (covered, psnr, lpips, beyond)) in ours.iter().zip(wins) {
        let _ = writeln!(
            text,
            "- {}: of the {} vtracer settings, {covered} fall within its sizes; at {psnr} of them its PSNR is \
             higher, at {lpips} its LPIPS lower. Of those larger than its largest file, {beyond} draw worse \
             than that smaller file on both measures.",
            method.name(),
            vtracer.len()
        );
    }
    text.push('\n');
    text
}

/// Each image's PSNR / LPIPS per method, one table per budget: where a mean hides one image
/// that loses.
fn per_image(results: &BTreeMap<(Table, Method), Vec<Row>>) -> String {
    let mut text = String::from("## Per image (PSNR dB / LPIPS)\n");
    for table in tables(results) {
        let methods: Vec<(Method, &Vec<Row>)> =
            results.iter().filter(|((t, _), _)| *t == table).map(|((_, m), rows)| (*m, rows)).collect();
        let mut images: Vec<&str> =
            methods.iter().flat_map(|(_, rows)| rows.iter().map(|r| r.image.as_str())).collect();
        images.sort_unstable();
        images.dedup();
        let title = table.title();
        let names: Vec<&str> = methods.iter().map(|(m, _)| m.name()).collect();
        let _ = writeln!(
            text,
            "\n{title}:\n\n| image | {} |\n| --- |{}",
            names.join(" | "),
            " ---: |".repeat(names.len())
        );
        for image in images {
            let cells: Vec<String> = methods
                .iter()
                .map(|(_, rows)| match rows.iter().find(|r| r.image == image) {
                    Some(row) => match row.lpips {
                        Some(lpips) => format!("{:.2} / {lpips:.4}", row.psnr),
                        None => format!("{:.2}", row.psnr),
                    },
                    None => "—".to_string(),
                })
                .collect();
            let _ = writeln!(text, "| {image} | {} |", cells.join(" | "));
        }
    }
    text.push('\n');
    text
}

/// Rows of tiles (input, then each method) scaled to `tile` px, with their names.
fn contact_sheet(rows: &[Vec<(Option<Method>, Rgb32FImage)>], tile: u32) -> RgbImage {
    let columns = rows.iter().map(Vec::len).max().unwrap_or(1) as u32;
    let mut sheet = RgbImage::from_pixel(
        columns * (tile + 4) + 4,
        rows.len() as u32 * (tile + 4) + 4,
        image::Rgb([255, 255, 255]),
    );
    for (r, row) in rows.iter().enumerate() {
        for (c, (_, image)) in row.iter().enumerate() {
            let scale = tile as f32 / image.width().max(image.height()) as f32;
            let (w, h) = (
                ((image.width() as f32 * scale) as u32).max(1),
                ((image.height() as f32 * scale) as u32).max(1),
            );
            let small = image::imageops::resize(&to_rgb8(image), w, h, image::imageops::FilterType::Triangle);
            let (x, y) = (4 + c as u32 * (tile + 4), 4 + r as u32 * (tile + 4));
            image::imageops::replace(&mut sheet, &small, x.into(), y.into());
        }
    }
    sheet
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each vtracer setting is set beside our curve at its own size, never extrapolated, and the
    /// summary counts where we draw better.
    #[test]
    fn vtracer_settings_are_read_against_our_curve_at_their_size() {
        let point = |kilobytes, psnr, lpips| RatePoint { kilobytes, psnr, lpips: Some(lpips) };
        let at_budget = |paths, point| SweepPoint { setting: Setting::Paths(paths), point, seconds: 1.0 };
        let vtracer = |filter_speckle, point| SweepPoint {
            setting: Setting::Vtracer(VtracerSettings { filter_speckle, ..VtracerSettings::default() }),
            point,
            seconds: 0.1,
        };
        let points = BTreeMap::from([
            (
                Method::OursB,
                vec![at_budget(100, point(10.0, 30.0, 0.1)), at_budget(1000, point(100.0, 40.0, 0.02))],
            ),
            (
                Method::Vtracer,
                vec![
                    vtracer(64, point(5.0, 20.0, 0.3)),
                    vtracer(8, point(10f64.powf(1.5), 34.0, 0.04)),
                    vtracer(1, point(100.0, 41.0, 0.01)),
                    vtracer(0, point(400.0, 39.0, 0.03)),
                ],
            ),
        ]);
        let text = rate_section(&points, Path::new("rate.png"));
        assert!(text.contains("| speckle 64, precision 6 | 5.0 | 20.00 / 0.3000 | — |"), "{text}");
        assert!(
            text.contains("| speckle 8, precision 6 | 31.6 | 34.00 / 0.0400 | 35.00 (+1.00) / 0.0600 |"),
            "{text}"
        );
        assert!(
            text.contains("| speckle 1, precision 6 | 100.0 | 41.00 / 0.0100 | 40.00 (-1.00) / 0.0200 |"),
            "{text}"
        );
        assert!(
            text.contains("of the 4 vtracer settings, 2 fall within its sizes; at 1 of them its PSNR is higher, at 0 its LPIPS lower. Of those larger than its largest file, 1 draw worse"),
            "{text}"
        );
        assert!(
            text.contains("| speckle 0, precision 6 | 400.0 | 39.00 / 0.0300 | ≤ 40.00 (+1.00) / 0.0200 |"),
            "{text}"
        );
        let chart = rate_chart(&points);
        assert_eq!(chart.matches("<polyline").count(), 2 * 2, "ours and vtracer's frontier, in both panels");
    }
}
