//! SuperSVG-B's time, quality and size on a folder of images, per budget: what a user who tries
//! it beside vtracer sees, stage by stage.
//!
//! `cargo run --release -p infer --example bench -- DIR [--paths 500,2000,auto] [--size 512]
//!  [--no-refine | --regions-only] [--tolerance 0.5]`
//!
//! Each image is read and drawn once per budget with the bundled models on the CPU (flex), as
//! `infer IMAGE --paths N` draws it. Prints a line per budget, then, last, one JSON line:
//! `{"images": N, "budgets": [{"paths": "500", "median_seconds": …, "median_stage_seconds":
//! {"decode": …, "superpixels": …, "coarse": …, "refine": …, "export": …},
//! "median_network_seconds": …, "mean_psnr": …, "mean_svg_bytes": …, "mean_paths": …}, …]}`.
//! Seconds are wall time of reading the file and the library call; the stage split is the job's
//! report, and of its coarse and refinement stages the networks' forward passes are
//! `median_network_seconds` (the rest of B's time is the median total less them).

use std::path::PathBuf;
use std::time::Instant;

use burn::tensor::Device;
use clap::Parser;
use common::decode::load;
use common::folder::files_in;
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

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = Args::parse();
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
            ("export", stage(|r| r.seconds.export)),
        ];
        let psnr = mean(runs.iter().map(|(_, r)| r.psnr));
        let bytes = mean(runs.iter().map(|(_, r)| r.svg_bytes as f64));
        let drawn = mean(runs.iter().map(|(_, r)| r.paths as f64));
        let networks = stage(|r| r.seconds.networks);
        let split: Vec<String> = stages.iter().map(|(name, s)| format!("{name} {s:.3}")).collect();
        println!(
            "--paths {paths}: {seconds:.3} s median per image ({}; of coarse and refine, the networks \
             {networks:.3}), {psnr:.2} dB, {:.1} KB, {drawn:.0} paths (means over {} images)",
            split.join(", "),
            bytes / 1000.0,
            images.len(),
        );
        let entry = json!({
            "paths": paths.to_string(),
            "median_seconds": seconds,
            "median_stage_seconds": stages.iter().map(|(name, s)| (name.to_string(), json!(s))).collect::<serde_json::Map<_, _>>(),
            "median_network_seconds": networks,
            "mean_psnr": psnr,
            "mean_svg_bytes": bytes,
            "mean_paths": drawn,
        });
        budgets.push(entry);
    }
    println!("{}", json!({ "images": images.len(), "budgets": budgets }));
    Ok(())
}
