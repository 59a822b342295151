//! SuperSVG-B's time, quality and size on a folder of images, per budget: what a user who tries
//! it beside vtracer sees, stage by stage and as whole processes.
//!
//! `cargo build --release -p infer && cargo run --release -p infer --example bench -- DIR
//!  [--paths 500,2000,auto] [--size 512] [--no-refine | --regions-only] [--tolerance 0.5]
//!  [--rounds 3] [--infer PATH]`
//!
//! Each image is read and drawn once per budget with the bundled models on the CPU (flex), as
//! `infer IMAGE --paths N` draws it; seconds are wall time of reading the file and the library
//! call, the stage split is the job's report, and of its coarse and refinement stages the
//! networks' forward passes are `median_network_seconds`. Then the `infer` program (by default
//! the one cargo built beside this example) is timed as a user times it, whole processes: its
//! start-up (a 64×64 flat image, where no stage has work), and each image at each budget
//! `--rounds` times — when `vtracer` is on the PATH, in alternating pairs with vtracer's
//! defaults, the ratio taken pair by pair.
//!
//! Prints a line per measurement, then, last, one JSON line: `{"images": N, "startup_seconds":
//! …, "budgets": [{"paths": "500", "median_seconds": …, "median_stage_seconds": {"decode": …,
//! "superpixels": …, "coarse": …, "refine": …, "export": …}, "median_network_seconds": …,
//! "mean_psnr": …, "mean_svg_bytes": …, "mean_paths": …, "process_median_seconds": …,
//! "vtracer_median_seconds": …, "median_ratio_to_vtracer": …}, …]}` (the vtracer keys are null
//! without vtracer).

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

use burn::tensor::Device;
use clap::Parser;
use common::decode::load;
use common::folder::files_in;
use common::write::create_temporary_folder;
use infer::{Job, Models, PathBudget, Report, run};
use serde_json::json;

/// Time SuperSVG-B on every image of a folder.
#[derive(Parser, Debug)]
struct Args {
    /// The folder of images (every file in it that decodes).
    dir: PathBuf,
    /// Budgets, comma-separated: numbers of paths or `auto`.
    #[arg(long, value_delimiter = ',', default_value = "500,2000", value_parser = str::parse::<PathBudget>)]
    paths: Vec<PathBudget>,
    /// Long side of the working resolution.
    #[arg(long, default_value_t = 512)]
    size: u32,
    /// Without E_r (the coarse stage and the fallback only).
    #[arg(long)]
    no_refine: bool,
    /// The fallback alone: every budget N spent on N − 1 regions, without E_c or E_r (`infer
    /// --paths N --regions N-1 --no-refine`), the bar the networks must clear.
    #[arg(long, conflicts_with = "no_refine")]
    regions_only: bool,
    /// Regions as shared boundaries fitted with curves within this many pixels (`infer
    /// --tolerance`); by default traced polygons.
    #[arg(long)]
    tolerance: Option<f32>,
    /// Whole-process runs of `infer` per image and budget (and of vtracer, paired with them).
    #[arg(long, default_value_t = 3)]
    rounds: usize,
    /// The `infer` program to time as whole processes; by default the one in the folder above
    /// this example's (`cargo build --release -p infer` builds it).
    #[arg(long)]
    infer: Option<PathBuf>,
}

/// The median of `values` (the mean of the middle two for an even count).
fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    if n == 0 { f64::NAN } else { (values[(n - 1) / 2] + values[n / 2]) / 2.0 }
}

fn mean(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    sum / n as f64
}

/// Wall seconds of `program args…`, its output discarded; an error names the program and what
/// it printed when it fails.
fn time_process(program: &Path, args: &[&std::ffi::OsStr]) -> Result<f64, String> {
    let started = Instant::now();
    let output = Command::new(program)
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .output()
        .map_err(|err| format!("{}: {err}", program.display()))?;
    let seconds = started.elapsed().as_secs_f64();
    if !output.status.success() {
        let said = String::from_utf8_lossy(&output.stderr);
        return Err(format!("{} failed ({}): {}", program.display(), output.status, said.trim()));
    }
    Ok(seconds)
}

/// Whether `vtracer` runs from the PATH.
fn vtracer_installed() -> bool {
    Command::new("vtracer").arg("--version").stdout(Stdio::null()).stderr(Stdio::null()).status().is_ok()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = Args::parse();
    let infer = match &args.infer {
        Some(path) => path.clone(),
        None => std::env::current_exe()?
            .parent()
            .and_then(Path::parent)
            .map(|dir| dir.join(format!("infer{}", std::env::consts::EXE_SUFFIX)))
            .ok_or("no folder above this example's")?,
    };
    if !infer.is_file() {
        return Err(format!(
            "{}: no infer program there (build it with `cargo build --release -p infer`, or name it with --infer)",
            infer.display()
        )
        .into());
    }
    if args.rounds == 0 {
        return Err("--rounds: at least 1".into());
    }
    let vtracer = vtracer_installed();
    let scratch = create_temporary_folder(&std::env::temp_dir(), "supersvg-bench")?;
    let result = bench(&args, &infer, vtracer, &scratch);
    std::fs::remove_dir_all(&scratch)?;
    result
}

fn bench(args: &Args, infer: &Path, vtracer: bool, scratch: &Path) -> Result<(), Box<dyn std::error::Error>> {
    let device = Device::flex();
    let models = Models::bundled(!(args.no_refine || args.regions_only), &device)?;
    let images: Vec<PathBuf> =
        files_in(&args.dir)?.into_iter().filter(|path| load(path, args.size).is_ok()).collect();
    if images.is_empty() {
        return Err(format!("{}: no image decodes", args.dir.display()).into());
    }
    let mut budgets = Vec::new();
    for &paths in &args.paths {
        let regions = match paths {
            PathBudget::Count(count) if args.regions_only => Some(count - 1),
            PathBudget::Auto(_) if args.regions_only => {
                return Err("--regions-only needs numbers of paths, not auto".into());
            }
            _ => None,
        };
        let job = Job { paths, regions, tolerance: args.tolerance, ..Job::default() };
        let mut runs: Vec<(f64, Report)> = Vec::new();
        for path in &images {
            let started = Instant::now();
            let loaded = load(path, args.size)?;
            let outcome =
                run(&models, &loaded, &job, &device).map_err(|err| format!("{}: {err}", path.display()))?;
            runs.push((started.elapsed().as_secs_f64(), outcome.report));
        }
        let stage = |of: fn(&Report) -> f64| median(runs.iter().map(|(_, r)| of(r)).collect());
        let seconds = median(runs.iter().map(|(s, _)| *s).collect());
        let stages = [
            ("decode", stage(|r| r.seconds.decode)),
            ("superpixels", stage(|r| r.seconds.superpixels)),
            ("coarse", stage(|r| r.seconds.coarse)),
            ("refine", stage(|r| r.seconds.refine)),
            ("moves", stage(|r| r.seconds.moves)),
            ("export", stage(|r| r.seconds.export)),
        ];
        let psnr = mean(runs.iter().map(|(_, r)| r.psnr));
        let bytes = mean(runs.iter().map(|(_, r)| r.svg_bytes as f64));
        let drawn = mean(runs.iter().map(|(_, r)| r.paths as f64));
        let networks = stage(|r| r.seconds.networks);
        let split: Vec<String> = stages.iter().map(|(name, s)| format!("{name} {s:.3}")).collect();
        println!(
            "--paths {paths}: {seconds:.3} s median per image ({}; of coarse, refine and moves, the networks \
             {networks:.3}), {psnr:.2} dB, {:.1} KB, {drawn:.0} paths (means over {} images)",
            split.join(", "),
            bytes / 1000.0,
            images.len(),
        );
        let (process, versus) = processes(args, infer, vtracer, scratch, &images, paths, regions)?;
        match versus {
            Some(Versus { vtracer, ratio }) => println!(
                "--paths {paths}, whole processes: infer {process:.3} s, vtracer {vtracer:.3} s median per \
                 image (ratio {ratio:.2}, the median of {} pairs)",
                images.len() * args.rounds
            ),
            None => println!(
                "--paths {paths}, whole processes: infer {process:.3} s median per image (no vtracer)"
            ),
        }
        let entry = json!({
            "paths": paths.to_string(),
            "median_seconds": seconds,
            "median_stage_seconds": stages.iter().map(|(name, s)| (name.to_string(), json!(s))).collect::<serde_json::Map<_, _>>(),
            "median_network_seconds": networks,
            "mean_psnr": psnr,
            "mean_svg_bytes": bytes,
            "mean_paths": drawn,
            "process_median_seconds": process,
            "vtracer_median_seconds": versus.map(|v| v.vtracer),
            "median_ratio_to_vtracer": versus.map(|v| v.ratio),
        });
        budgets.push(entry);
    }
    let startup = startup(args, infer, scratch)?;
    println!("start-up: infer {startup:.3} s median of {} runs on a 64×64 flat image", STARTUP_RUNS);
    println!("{}", json!({ "images": images.len(), "startup_seconds": startup, "budgets": budgets }));
    Ok(())
}

/// Runs of `infer` on the flat image that measure its start-up.
const STARTUP_RUNS: usize = 21;

/// The median wall time of `infer` on a 64×64 flat image: everything but the stages' work.
fn startup(args: &Args, infer: &Path, scratch: &Path) -> Result<f64, Box<dyn std::error::Error>> {
    let image = scratch.join("flat.png");
    image::RgbImage::from_pixel(64, 64, image::Rgb([51, 102, 204])).save(&image)?;
    let svg = scratch.join("flat.svg");
    let mut extra: Vec<&std::ffi::OsStr> = Vec::new();
    if args.no_refine || args.regions_only {
        extra.push("--no-refine".as_ref());
    }
    let mut seconds = Vec::new();
    for _ in 0..STARTUP_RUNS {
        let mut argv: Vec<&std::ffi::OsStr> =
            vec![image.as_os_str(), "-o".as_ref(), svg.as_os_str(), "-q".as_ref()];
        argv.extend(&extra);
        seconds.push(time_process(infer, &argv)?);
    }
    Ok(median(seconds))
}

/// vtracer's whole-process time beside ours.
#[derive(Clone, Copy)]
struct Versus {
    /// Its median seconds per image.
    vtracer: f64,
    /// The median over pairs of ours over its.
    ratio: f64,
}

/// Every image at `paths`, `--rounds` times, as whole processes: the median seconds of `infer`,
/// and vtracer's beside them when it is installed (run right after ours, pair by pair).
fn processes(
    args: &Args,
    infer: &Path,
    vtracer: bool,
    scratch: &Path,
    images: &[PathBuf],
    paths: PathBudget,
    regions: Option<usize>,
) -> Result<(f64, Option<Versus>), Box<dyn std::error::Error>> {
    let svg = scratch.join("out.svg");
    let (budget, size) = (paths.to_string(), args.size.to_string());
    let mut options: Vec<String> = vec!["--paths".into(), budget, "--size".into(), size, "-q".into()];
    if let Some(regions) = regions {
        options.extend(["--regions".into(), regions.to_string()]);
    }
    if args.no_refine || args.regions_only {
        options.push("--no-refine".into());
    }
    if let Some(tolerance) = args.tolerance {
        options.extend(["--tolerance".into(), tolerance.to_string()]);
    }
    let (mut ours, mut theirs, mut ratios) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..args.rounds {
        for image in images {
            let mut argv: Vec<&std::ffi::OsStr> = vec![image.as_os_str(), "-o".as_ref(), svg.as_os_str()];
            argv.extend(options.iter().map(std::ffi::OsStr::new));
            let seconds = time_process(infer, &argv)?;
            ours.push(seconds);
            if vtracer {
                let argv = ["--input".as_ref(), image.as_os_str(), "--output".as_ref(), svg.as_os_str()];
                let other = time_process(Path::new("vtracer"), &argv)?;
                theirs.push(other);
                ratios.push(seconds / other);
            }
        }
    }
    let versus = vtracer.then(|| Versus { vtracer: median(theirs), ratio: median(ratios) });
    Ok((median(ours), versus))
}
