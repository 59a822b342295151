//! `tune`: measures SuperSVG-B over a grid of operating points (how a path budget is split
//! between regions, E_c and E_r) and stores the best with the model.
//!
//! `tune DIR --paths 500,2000 --coarse-share 0,0.1 --refine-share 0,0.25
//!       --out docs/operating-point.md [--write models/coarse.ckpt]`
//!
//! Each point draws every image through `infer::run`, as `infer` would with that point. Scores are
//! the PSNR of the drawing at the working resolution (the job's report), averaged over images and
//! then over budgets; the best point is the one with the highest average.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, anyhow, bail};
use clap::Parser;
use common::decode::load;
use common::folder::files_in;
use common::outputs::check_output;
use common::write::write_atomic;
use eval::{command_line, finish, load_models};
use infer::{Job, PathBudget, Split, run};
use infer::{Origin, StageCounts};
use model::{Checkpoint, OperatingPoint, Stage};
use raster::Backend;

/// Measure operating points of SuperSVG-B on a folder of images.
#[derive(Parser, Debug)]
#[command(name = "tune", version)]
struct Args {
    /// Folder of images.
    dir: PathBuf,
    /// Path budgets, comma separated.
    #[arg(long, value_delimiter = ',', default_value = "500,2000")]
    paths: Vec<usize>,
    /// Values of the budget share for E_c.
    #[arg(long, value_delimiter = ',', default_value = "0,0.05,0.1,0.2")]
    coarse_share: Vec<f32>,
    /// Values of the budget share kept for E_r.
    #[arg(long, value_delimiter = ',', default_value = "0,0.1,0.25")]
    refine_share: Vec<f32>,
    /// The markdown table to write.
    #[arg(long)]
    out: PathBuf,
    /// Store the best point in this coarse checkpoint (rewritten in place; checked before any
    /// measuring: a missing, damaged or refinement checkpoint is refused first).
    #[arg(long)]
    write: Option<PathBuf>,
    /// Coarse-model checkpoint (default: the bundled one).
    #[arg(long)]
    coarse: Option<PathBuf>,
    /// Refinement-model checkpoint (default: the bundled one).
    #[arg(long)]
    refine: Option<PathBuf>,
    /// Long side of the working resolution.
    #[arg(long, default_value_t = 512)]
    size: u32,
    /// Compute backend: flex, ndarray or wgpu.
    #[arg(long, default_value = "flex")]
    backend: Backend,
}

/// Mean paths per stage over images.
#[derive(Clone, Copy, Default)]
struct MeanStages {
    background: f64,
    fallback: f64,
    coarse: f64,
    refine: f64,
}

impl MeanStages {
    /// Adds one image's counts, weighted `weight` (one over the number of images).
    fn add(&mut self, counts: StageCounts, weight: f64) {
        self.background += counts.background as f64 * weight;
        self.fallback += counts.fallback as f64 * weight;
        self.coarse += counts.coarse as f64 * weight;
        self.refine += counts.refine as f64 * weight;
    }

    /// `background / fallback / coarse / refine`, rounded.
    fn cell(&self) -> String {
        let order = Origin::ALL.map(|origin| match origin {
            Origin::Background => self.background,
            Origin::Fallback => self.fallback,
            Origin::Coarse => self.coarse,
            Origin::Refine => self.refine,
        });
        order.map(|v| format!("{v:.0}")).join(" / ")
    }
}

/// One grid point's results: mean PSNR, mean seconds and mean paths per stage, per budget.
struct Measured {
    point: OperatingPoint,
    psnr: Vec<f64>,
    seconds: Vec<f64>,
    stages: Vec<MeanStages>,
}

fn main() -> ExitCode {
    finish(run_tune(Args::parse()))
}

fn run_tune(args: Args) -> anyhow::Result<()> {
    if !common::WORKING_SIZES.contains(&args.size) {
        let sizes = common::WORKING_SIZES;
        bail!("--size: {} is out of range ({} to {} pixels)", args.size, sizes.start(), sizes.end());
    }
    let files = files_in(&args.dir)?;
    // What is written at the end is checked now, before any measuring: the table is no image
    // of the folder and no model file read or rewritten, and the checkpoint that takes the
    // best point is a coarse one, whole, and no image either.
    let models = [&args.coarse, &args.refine, &args.write].into_iter().flatten();
    check_output(&args.out, &files.iter().chain(models).collect::<Vec<_>>())?;
    let target = match &args.write {
        Some(path) => {
            let checkpoint = Checkpoint::load(path)?;
            checkpoint.expect_stage(Stage::Coarse, path)?;
            let read = [&args.refine].into_iter().flatten();
            check_output(path, &files.iter().chain(read).collect::<Vec<_>>())?;
            Some(checkpoint)
        }
        None => None,
    };
    let device = args.backend.device()?;
    let models = load_models(args.coarse.as_deref(), args.refine.as_deref(), None, &device)?;
    let mut points = Vec::new();
    for &coarse_share in &args.coarse_share {
        for &refine_share in &args.refine_share {
            let point = OperatingPoint { coarse_share, refine_share };
            for &paths in &args.paths {
                let job = Job {
                    paths: PathBudget::Count(paths),
                    operating_point: Split::Point(point),
                    ..Job::default()
                };
                job.validate().map_err(|err| anyhow!("--paths {paths}, grid point {point:?}: {err}"))?;
            }
            points.push(point);
        }
    }
    let images: Vec<_> = files.iter().filter_map(|path| load(path, args.size).ok()).collect();
    if images.is_empty() {
        bail!("{}: no readable images", args.dir.display());
    }

    let mut measured = Vec::new();
    for (index, &point) in points.iter().enumerate() {
        let budgets = args.paths.len();
        let mut result = Measured {
            point,
            psnr: vec![0.0; budgets],
            seconds: vec![0.0; budgets],
            stages: vec![MeanStages::default(); budgets],
        };
        let weight = 1.0 / images.len() as f64;
        for (b, &paths) in args.paths.iter().enumerate() {
            for image in &images {
                let job = Job {
                    paths: PathBudget::Count(paths),
                    operating_point: Split::Point(point),
                    ..Job::default()
                };
                let report = run(&models, image, &job, &device)?.report;
                result.seconds[b] += report.seconds.total * weight;
                result.psnr[b] += report.psnr * weight;
                result.stages[b].add(report.paths_by_stage, weight);
            }
        }
        common::say!("[{}/{}] {point:?}: {:?}", index + 1, points.len(), result.psnr);
        measured.push(result);
    }
    let mean = |m: &Measured| m.psnr.iter().sum::<f64>() / m.psnr.len() as f64;
    let best = measured.iter().max_by(|a, b| mean(a).total_cmp(&mean(b))).expect("a grid point");

    let mut text = format!(
        "# Operating point\n\nSuperSVG-B on `{}` ({} images, {} px), models `{}` and `{}`. PSNR of the exact \
         rendering, mean over images; paths per stage (background / fallback / coarse / refine), mean over \
         images.\n\nCommand: `{}`\n\n| coarse share | refine share |",
        args.dir.display(),
        images.len(),
        args.size,
        models.coarse.identity,
        models.refine.as_ref().map_or("none".to_string(), |refine| refine.identity.to_string()),
        command_line("tune", std::env::args().skip(1))
    );
    for paths in &args.paths {
        let _ = write!(text, " PSNR @{paths} | stages @{paths} | s @{paths} |");
    }
    let _ = write!(
        text,
        " mean PSNR |\n| ---: | ---: |{} ---: |\n",
        " ---: | ---: | ---: |".repeat(args.paths.len())
    );
    for m in &measured {
        let p = m.point;
        let _ = write!(text, "| {} | {} |", p.coarse_share, p.refine_share);
        for b in 0..args.paths.len() {
            let _ = write!(text, " {:.2} | {} | {:.2} |", m.psnr[b], m.stages[b].cell(), m.seconds[b]);
        }
        let marker = if std::ptr::eq(m, best) { " **best**" } else { "" };
        let _ = writeln!(text, " {:.2}{marker} |", mean(m));
    }
    write_atomic(&args.out, text.as_bytes()).with_context(|| args.out.display().to_string())?;
    common::say!("best: {:?} ({:.2} dB); wrote {}", best.point, mean(best), args.out.display());

    if let (Some(path), Some(checkpoint)) = (&args.write, target) {
        let tuned = Checkpoint { inference: Some(best.point), ..checkpoint };
        tuned.save(path)?;
        common::say!("stored the best point in {}", path.display());
    }
    Ok(())
}
