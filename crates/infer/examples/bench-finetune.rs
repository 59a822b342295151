//! Throughput and payoff of SuperSVG-F on one image: the bundled models draw it (SuperSVG-B),
//! then fine-tuning runs from that same drawing for 2, 5 and 10 seconds.
//!
//! `cargo run --release -p infer --example bench-finetune -- IMAGE [--paths 500] [--size 512]
//!  [--lr-points X] [--lr-outline-points Z] [--lr-colors Y]`
//!
//! Prints one line per budget, then, last, one JSON line: `steps_per_s` and `ms_per_step` (of
//! the 10 s run; a step is one Adam step of every path), `psnr_b`, `psnr_start` (the drawing F
//! starts from, before any step: B's outlines as drawn or fitted with one path each, whichever
//! writes less) and `psnr_after`
//! (seconds → PSNR of the exact rendering; B's when F's best is worse).

use std::ops::ControlFlow;
use std::path::PathBuf;
use std::time::Instant;

use burn::tensor::Device;
use clap::Parser;
use common::decode::load;
use common::psnr;
use infer::{FinetuneOptions, Job, Limit, Models, PathBudget, finetune, finetune_with_progress, run};

/// Time SuperSVG-F on one image.
#[derive(Parser, Debug)]
struct Args {
    /// The image.
    image: PathBuf,
    /// Path budget of the SuperSVG-B drawing it starts from.
    #[arg(long, default_value_t = 500)]
    paths: usize,
    /// Long side of the working resolution.
    #[arg(long, default_value_t = 512)]
    size: u32,
    /// Adam learning rate of the control points (default: [`FinetuneOptions::default`]'s).
    #[arg(long)]
    lr_points: Option<f32>,
    /// Adam learning rate of the points of outlines moved as drawn (default:
    /// [`FinetuneOptions::default`]'s).
    #[arg(long)]
    lr_outline_points: Option<f32>,
    /// Adam learning rate of colours and opacity (default: [`FinetuneOptions::default`]'s).
    #[arg(long)]
    lr_colors: Option<f32>,
}

/// The fine-tuning budgets measured, in seconds.
const SECONDS: [f64; 3] = [2.0, 5.0, 10.0];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = Args::parse();
    let device = Device::flex();
    let loaded = load(&args.image, args.size)?;
    let image = &loaded.image;
    let models = Models::bundled(true, &device)?;
    let drawn =
        run(&models, &loaded, &Job { paths: PathBudget::Count(args.paths), ..Job::default() }, &device)?;
    let psnr_b = drawn.report.psnr;
    println!("SuperSVG-B: {} paths, {psnr_b:.2} dB", drawn.scene.len());
    // The first step's report holds the error of the state before it, F's start (the
    // last report, after the stop, is of the scene kept).
    let mut psnr_start = f64::NAN;
    finetune_with_progress(
        &mut drawn.scene.clone(),
        &FinetuneOptions { limit: Limit::Steps(1), ..FinetuneOptions::default() },
        &mut |progress| {
            if psnr_start.is_nan() {
                psnr_start = progress.psnr;
            }
            ControlFlow::Break(())
        },
    );
    println!("F starts from {psnr_start:.2} dB");
    let mut after = serde_json::Map::new();
    let mut rate = (0.0, 0.0);
    for seconds in SECONDS {
        let mut scene = drawn.scene.clone();
        let defaults = FinetuneOptions::default();
        let options = FinetuneOptions {
            limit: Limit::Seconds(seconds),
            lr_points: args.lr_points.unwrap_or(defaults.lr_points),
            lr_outline_points: args.lr_outline_points.unwrap_or(defaults.lr_outline_points),
            lr_colors: args.lr_colors.unwrap_or(defaults.lr_colors),
            ..defaults
        };
        let started = Instant::now();
        let steps = finetune(&mut scene, &options);
        let spent = started.elapsed().as_secs_f64();
        let tuned = psnr(&scene.canvas_image(), image);
        println!("{seconds} s: {steps} steps in {spent:.2} s, {tuned:.2} dB ({:+.2})", tuned - psnr_b);
        after.insert(format!("{seconds}"), tuned.into());
        rate = (steps as f64 / spent, 1000.0 * spent / steps.max(1) as f64);
    }
    let line = serde_json::json!({
        "image": args.image.display().to_string(),
        "paths": args.paths,
        "steps_per_s": rate.0,
        "ms_per_step": rate.1,
        "psnr_b": psnr_b,
        "psnr_start": psnr_start,
        "psnr_after": after,
    });
    println!("{line}");
    Ok(())
}
