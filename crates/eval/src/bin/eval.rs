//! `eval`: SuperSVG (B, and F when asked) against other vectorizers on a folder of images.
//!
//! `eval DIR --paths 500,2000,4000 [--finetune-secs 10] [--sweep 64,250,1000,4000] --out report.md`
//!
//! Every SVG is rendered with resvg, independently of the project's renderers, at the working
//! resolution, and compared with the input scaled to it (MSE, PSNR, SSIM, and LPIPS when
//! `scripts/fetch-lpips.sh` has provided its weights). Writes a markdown report and a contact
//! sheet (input | each method) next to it; with `--sweep`, also the rate–distortion chart
//! (PSNR and LPIPS against SVG kilobytes), so methods are compared at equal file size.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, bail};
use clap::{Parser, ValueEnum};
use common::decode::load;
use common::folder::files_in;
use common::outputs::{check_output, check_replaceable, create_folder};
use common::say;
use common::write::{create_temporary_folder, write_atomic, write_png_marked};
use eval::{
    Budget, DrawError, Finetuned, Header, Input, Lpips, MARK, Method, Ours, Potrace, Results, SlicMosaic,
    Table, Vectorizer, Vtracer, VtracerSettings, available, command_line, finish, load_models, rate_chart,
    rate_section, render_chart, report, sweep_points, time_chart, time_points, time_section,
};
use infer::{
    AutoRule, Fills, FinetuneOptions, Job, Limit, Moves, OPTIMIZER_STEPS, PathBudget, Refiner, Split,
};
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
    /// SuperSVG's fallback drawing alone: as `infer --paths N --regions N-1 --no-refine --moves
    /// off` draws it.
    Fallback,
    /// SuperSVG-B without its refinement networks, E_r and the mover: as `infer --paths N
    /// --no-refine` draws it (what they add).
    NoRefine,
    /// SuperSVG-B without the mover: as `infer --paths N --moves off` draws it (what the mover
    /// adds; swept, so the chart compares them at equal file size).
    NoMoves,
    /// The paper's inference with the same models: as `infer --paths N --operating-point paper`
    /// draws it (for models trained with the paper preset, beside the paper's tables).
    Paper,
    /// SuperSVG-B with the exact optimizer proposing in E_r's place: as `infer --paths N
    /// --refiner optimizer` draws it (what E_r's role can reach, for judging a trained E_r).
    Optimizer,
    /// SuperSVG-B with its regions filled otherwise than by default (ramps where they pay): as
    /// `infer --paths N --fills linear` and `--fills flat` draw it (swept, so the chart
    /// compares fills at equal file size).
    Fills,
}

/// Evaluate SuperSVG and other vectorizers on a folder of images.
#[derive(Parser, Debug)]
#[command(name = "eval", version)]
struct Args {
    /// Folder of images.
    dir: PathBuf,
    /// Path budgets, comma separated (each 2 to 20 000).
    #[arg(long, value_delimiter = ',', default_value = "500,2000", allow_hyphen_values = true)]
    paths: Vec<usize>,
    /// Also run SuperSVG-F, fine-tuning for this many seconds per image: from B's drawing as
    /// `infer --finetune-secs` does, and as F was before it started there (from B with flat
    /// fills and no mover, the outlines fitted with one path where that writes less).
    #[arg(long, allow_hyphen_values = true)]
    finetune_secs: Option<f64>,
    /// SuperSVG-F's quality against time: both of `--finetune-secs`' rows at each of these
    /// seconds (comma separated) and each of `--paths`; the report gets a section and the chart
    /// goes beside it (`REPORT-time.png` and `.svg`).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    time_chart: Vec<f64>,
    /// The markdown report to write; the contact sheet goes next to it as PNG.
    #[arg(long)]
    out: PathBuf,
    /// Also write SuperSVG's SVGs into this folder (`IMAGE-b-500.svg`, `IMAGE-f-500.svg`,
    /// `IMAGE-f-moved-500.svg`, `IMAGE-auto.svg`, `IMAGE-fallback-500.svg`, `IMAGE-no-refine-500.svg`,
    /// `IMAGE-no-moves-500.svg`,
    /// `IMAGE-paper-500.svg`, `IMAGE-optimizer-500.svg`, `IMAGE-linear-500.svg`, `IMAGE-flat-500.svg`): the files `infer`
    /// writes with the same settings.
    #[arg(long)]
    svgs: Option<PathBuf>,
    /// Coarse-model checkpoint (default: the bundled one).
    #[arg(long)]
    coarse: Option<PathBuf>,
    /// Refinement-model checkpoint (default: the bundled one).
    #[arg(long)]
    refine: Option<PathBuf>,
    /// The mover's checkpoint (default: the bundled one).
    #[arg(long)]
    mover: Option<PathBuf>,
    /// Compute backend: flex, ndarray or wgpu.
    #[arg(long, default_value = "flex")]
    backend: Backend,
    /// Long side of the working resolution.
    #[arg(long, default_value_t = 512, allow_hyphen_values = true)]
    size: u32,
    /// Peers, comma separated; empty for none.
    #[arg(long, value_delimiter = ',', default_value = "vtracer,potrace,slic,fallback,no-refine,no-moves")]
    peers: Vec<PeerArg>,
    /// Evaluate only the first N images.
    #[arg(long)]
    limit: Option<usize>,
    /// Rate–distortion sweep: SuperSVG-B (and the fallback alone and the fills, when they are peers) at these
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
    /// What SuperSVG's regions are filled with (`infer --fills`: `flat`, `linear` or `auto`),
    /// in every drawing of ours but the `fills` peer's; by default `infer`'s default.
    #[arg(long, value_parser = str::parse::<Fills>)]
    fills: Option<Fills>,
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

fn main() -> ExitCode {
    finish(run_eval(Args::parse()))
}

/// SuperSVG-F's two rows with `limit`: F from B's drawing (`job`), and F as it was (from B with
/// flat fills and no mover, the outlines fitted where that writes less, opacity moved).
fn f_variants(job: &Job, limit: Limit) -> [(Method, Job, FinetuneOptions); 2] {
    let now = FinetuneOptions { limit, ..FinetuneOptions::default() };
    let was = FinetuneOptions { as_drawn: false, fixed_alpha: false, ..now.clone() };
    let flat = Job { fills: Some(Fills::Flat), moves: Moves::Off, ..job.clone() };
    [(Method::OursF, job.clone(), now), (Method::OursFWas, flat, was)]
}

impl Args {
    /// SuperSVG's job at every budget, checked by the library's rules (those `infer` applies),
    /// its refusals named by the flag they are about.
    fn job(&self) -> anyhow::Result<Job> {
        if self.operating_point == Split::Paper {
            bail!("--operating-point paper: the paper's inference is a peer here (--peers paper)");
        }
        let finetune = self
            .finetune_secs
            .map(|s| FinetuneOptions { limit: Limit::Seconds(s), ..FinetuneOptions::default() });
        let job = Job {
            tolerance: self.tolerance,
            fills: self.fills,
            operating_point: self.operating_point,
            ..Job::default()
        };
        for (flag, budgets) in [("--paths", &self.paths), ("--sweep", &self.sweep)] {
            for &paths in budgets.iter() {
                let checked =
                    Job { paths: PathBudget::Count(paths), finetune: finetune.clone(), ..job.clone() };
                checked.validate().map_err(|err| {
                    let flag = match err.field() {
                        "finetune" => "--finetune-secs",
                        "tolerance" => "--tolerance",
                        "operating_point" => "--operating-point",
                        _ => flag,
                    };
                    anyhow::anyhow!("{flag}: {err}")
                })?;
            }
        }
        for &seconds in &self.time_chart {
            let options = FinetuneOptions { limit: Limit::Seconds(seconds), ..FinetuneOptions::default() };
            let checked = Job { finetune: Some(options), ..job.clone() };
            checked.validate().map_err(|err| anyhow::anyhow!("--time-chart: {err}"))?;
        }
        Ok(job)
    }

    fn wants(&self, peer: Peer) -> bool {
        self.peers.contains(&PeerArg(Some(peer)))
    }
}

fn run_eval(args: Args) -> anyhow::Result<()> {
    let job = args.job()?;
    if !common::WORKING_SIZES.contains(&args.size) {
        bail!(
            "--size: {} is out of range ({} to {} pixels)",
            args.size,
            common::WORKING_SIZES.start(),
            common::WORKING_SIZES.end()
        );
    }
    let folder = files_in(&args.dir)?;
    let images = &folder[..folder.len().min(args.limit.unwrap_or(usize::MAX))];
    if images.is_empty() {
        bail!("{}: no images", args.dir.display());
    }
    // Every file the report run writes is checked now, before any work: none may be an image of
    // the folder or a model file it reads, and the files named after the report are replaced
    // only when this program wrote them.
    let stem = args.out.file_stem().map_or_else(|| "report".into(), |s| s.to_string_lossy().into_owned());
    let sheet_path = args.out.with_extension("png");
    let chart_svg = args.out.with_file_name(format!("{stem}-rate.svg"));
    let chart_png = chart_svg.with_extension("png");
    let time_svg = args.out.with_file_name(format!("{stem}-time.svg"));
    let time_png = time_svg.with_extension("png");
    let models = [&args.coarse, &args.refine, &args.mover].into_iter().flatten();
    let inputs: Vec<&PathBuf> = folder.iter().chain(models).collect();
    let mut derived = vec![&sheet_path];
    if !args.sweep.is_empty() {
        derived.extend([&chart_svg, &chart_png]);
    }
    if !args.time_chart.is_empty() {
        derived.extend([&time_svg, &time_png]);
    }
    for output in std::iter::once(&args.out).chain(derived.iter().copied()) {
        check_output(output, &inputs)?;
    }
    for output in derived {
        check_replaceable(output, MARK, "eval")?;
    }
    if let Some(folder) = &args.svgs {
        create_folder(folder)?;
    }
    let device = args.backend.device()?;
    let models = load_models(args.coarse.as_deref(), args.refine.as_deref(), args.mover.as_deref(), &device)?;
    // The fallback and no-refine rows draw without E_r (for the fallback: a region that lowers
    // nothing is not drawn, and E_r would spend what it leaves) and unmoved, as `infer
    // --no-refine` does.
    let regions_only = infer::Models { refine: None, ..models.clone() };
    // The peers read the input's format from its extension: the scratch folder is made new,
    // so the fixed names inside it are safe.
    let scratch = create_temporary_folder(&std::env::temp_dir(), "supersvg-eval")
        .with_context(|| format!("scratch folder in {}", std::env::temp_dir().display()))?;

    let mut notes = Vec::new();
    let mut installed = |peer: Peer, program: &str| {
        let here = available(program);
        if args.wants(peer) && !here {
            notes.push(format!("{program} is not installed: its rows are missing."));
        }
        args.wants(peer) && here
    };
    let (use_vtracer, use_potrace) =
        (installed(Peer::Vtracer, "vtracer"), installed(Peer::Potrace, "potrace"));
    let lpips = match Lpips::load(&Lpips::default_folder(), &device) {
        Ok(lpips) => Some(lpips),
        Err(err) => {
            notes.push(format!("LPIPS skipped: {err}."));
            None
        }
    };

    // Every method, in the contact sheet's column order; the report orders rows by `Method`.
    let ours = |method, models, job: Job| Ours { method, models, job, device: &device };
    let mut methods: Vec<Box<dyn Vectorizer + '_>> =
        vec![Box::new(ours(Method::OursB, &models, job.clone()))];
    let unmoved = Job { moves: Moves::Off, ..job.clone() };
    if args.wants(Peer::Fallback) {
        methods.push(Box::new(ours(Method::Fallback, &regions_only, unmoved.clone())));
    }
    if let Some(seconds) = args.finetune_secs {
        for (method, job, options) in f_variants(&job, Limit::Seconds(seconds)) {
            methods.push(Box::new(Finetuned { base: ours(method, &models, job), options }));
        }
    }
    if args.wants(Peer::NoRefine) {
        methods.push(Box::new(ours(Method::OursNoRefine, &regions_only, unmoved.clone())));
    }
    if args.wants(Peer::NoMoves) {
        methods.push(Box::new(ours(Method::OursNoMoves, &models, unmoved.clone())));
    }
    if args.wants(Peer::Paper) {
        let paper = Job { operating_point: Split::Paper, ..job.clone() };
        methods.push(Box::new(ours(Method::OursPaper, &models, paper)));
    }
    if args.wants(Peer::Optimizer) {
        let optimized = Job { refiner: Refiner::Optimizer { steps: OPTIMIZER_STEPS }, ..job.clone() };
        methods.push(Box::new(ours(Method::OursOptimizer, &regions_only, optimized)));
    }
    if args.wants(Peer::Fills) {
        for (method, fills) in [(Method::OursLinear, Fills::Linear), (Method::OursFlat, Fills::Flat)] {
            methods.push(Box::new(ours(method, &models, Job { fills: Some(fills), ..job.clone() })));
        }
    }
    if use_vtracer {
        methods.push(Box::new(Vtracer { method: Method::Vtracer }));
    }
    if use_potrace {
        methods.push(Box::new(Potrace));
    }
    if args.wants(Peer::Slic) {
        methods.push(Box::new(SlicMosaic));
    }
    let auto = Job { paths: PathBudget::Auto(AutoRule::default()), ..job.clone() };
    methods.push(Box::new(ours(Method::OursAuto, &models, auto)));
    if use_vtracer {
        methods.push(Box::new(Vtracer { method: Method::VtracerDefault }));
    }

    // Which tables each budget's drawings go in: the fixed budgets in their order, then the
    // sweep's other budgets, vtracer's settings and each method's own budget. A method is drawn
    // once per budget and recorded in every table that has it.
    let mut budgets: Vec<Budget> = Vec::new();
    for &paths in args.paths.iter().chain(&args.sweep) {
        if !budgets.contains(&Budget::Paths(paths)) {
            budgets.push(Budget::Paths(paths));
        }
    }
    if use_vtracer && !args.sweep.is_empty() {
        budgets.extend(VtracerSettings::sweep().into_iter().map(Budget::Vtracer));
    }
    budgets.push(Budget::Own);
    let tables = |budget: Budget, sweeps: bool| -> Vec<Table> {
        let compared = match budget {
            Budget::Paths(paths) => args.paths.contains(&paths),
            Budget::Own => true,
            Budget::Vtracer(_) => false,
        };
        let swept = match budget {
            Budget::Paths(paths) => sweeps && args.sweep.contains(&paths),
            Budget::Own => false,
            Budget::Vtracer(_) => true,
        };
        [(compared, Table::Compared(budget)), (swept, Table::Sweep(budget))]
            .into_iter()
            .filter_map(|(wanted, table)| wanted.then_some(table))
            .collect()
    };
    let sheet_budget = Budget::Paths(args.paths[0]);

    let mut results = Results::default();
    let mut evaluated = 0;
    let mut too_small_for_lpips = Vec::new();
    for (index, path) in images.iter().enumerate() {
        let loaded = match load(path, args.size) {
            Ok(loaded) => loaded,
            Err(err) => {
                say!("skipping {err}");
                continue;
            }
        };
        evaluated += 1;
        let (width, height) = loaded.image.dimensions();
        if lpips.as_ref().is_some_and(|net| width.min(height) < net.smallest_side()) {
            too_small_for_lpips.push(path.display().to_string());
        }
        let name = path.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        let stem = path.file_stem().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        let png = scratch.join("input.png");
        let input = Input::new(&loaded, &png, &scratch).with_context(|| png.display().to_string())?;
        results.start_sheet_row(&loaded.image);
        for &budget in &budgets {
            for method in &methods {
                let tables = tables(budget, method.sweeps());
                if tables.is_empty() {
                    continue;
                }
                let drawing = match method.draw(&input, budget) {
                    Ok(Some(drawing)) => drawing,
                    Ok(None) => continue,
                    Err(DrawError::Peer(err)) => {
                        say!("{}: {} at {}: {err}", path.display(), method.method().name(), budget.title());
                        continue;
                    }
                    Err(err) => return Err(err.into()),
                };
                if let (Some(folder), Some(svg), true) = (&args.svgs, &drawing.svg, method.method().is_ours())
                {
                    let file = folder.join(method.method().svg_name(&stem, budget));
                    // Never over an image of the folder (`--svgs` may be that folder).
                    let written = match check_output(&file, &inputs) {
                        Err(err) => Err(err.to_string()),
                        Ok(()) => write_atomic(&file, svg.as_bytes())
                            .map_err(|err| format!("{}: {err}", file.display())),
                    };
                    if let Err(message) = written {
                        say!("{message}");
                    }
                }
                for table in tables {
                    results.record((&name, &loaded.image), table, method.method(), &drawing, lpips.as_ref());
                }
                if budget == sheet_budget {
                    results.add_to_sheet(method.method(), &drawing);
                }
            }
        }
        // SuperSVG-F against time: both rows at every time and budget.
        for &paths in &args.paths {
            for &seconds in &args.time_chart {
                for (method, job, options) in f_variants(&job, Limit::Seconds(seconds)) {
                    let f = Finetuned { base: ours(method, &models, job), options };
                    if let Some(drawing) = f.draw(&input, Budget::Paths(paths))? {
                        let table = Table::Time(Budget::Paths(paths), (seconds * 1000.0).round() as u32);
                        results.record((&name, &loaded.image), table, method, &drawing, lpips.as_ref());
                    }
                }
            }
        }
        let _ = std::fs::remove_file(&png);
        say!("[{}/{}] {}", index + 1, images.len(), path.display());
    }
    let _ = std::fs::remove_dir_all(&scratch);
    if evaluated == 0 {
        bail!("{}: no readable images", args.dir.display());
    }

    if let (Some(net), false) = (&lpips, too_small_for_lpips.is_empty()) {
        notes.push(format!(
            "LPIPS is not defined under {} pixels a side, so its column is empty: {}.",
            net.smallest_side(),
            too_small_for_lpips.join(", ")
        ));
    }
    let (sheet, columns) = results.sheet(160);
    write_png_marked(&sheet_path, &sheet, MARK).with_context(|| sheet_path.display().to_string())?;
    let header = Header {
        dir: args.dir.clone(),
        images: evaluated,
        size: args.size,
        command: command_line("eval", std::env::args().skip(1)),
        notes,
        sheet: sheet_path.clone(),
        sheet_budget,
        columns,
    };
    let mut report = report(&header, &results);
    if !args.sweep.is_empty() {
        let points = sweep_points(&results, evaluated);
        let document = format!("<!-- {MARK} -->\n{}", rate_chart(&points));
        write_atomic(&chart_svg, document.as_bytes()).with_context(|| chart_svg.display().to_string())?;
        let pixels = render_chart(&document).with_context(|| chart_svg.display().to_string())?;
        write_png_marked(&chart_png, &pixels, MARK).with_context(|| chart_png.display().to_string())?;
        report.push_str(&rate_section(&points, &chart_png));
    }
    if !args.time_chart.is_empty() {
        let curves = time_points(&results);
        let document = format!("<!-- {MARK} -->\n{}", time_chart(&curves));
        write_atomic(&time_svg, document.as_bytes()).with_context(|| time_svg.display().to_string())?;
        let pixels = render_chart(&document).with_context(|| time_svg.display().to_string())?;
        write_png_marked(&time_png, &pixels, MARK).with_context(|| time_png.display().to_string())?;
        report.push_str(&time_section(&curves, &time_png));
    }
    write_atomic(&args.out, report.as_bytes()).with_context(|| args.out.display().to_string())?;
    say!("wrote {} and {}", args.out.display(), sheet_path.display());
    Ok(())
}
