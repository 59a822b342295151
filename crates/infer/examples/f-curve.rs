//! SuperSVG-F's quality against time on a folder: each image drawn by SuperSVG-B, then F run
//! from it for `--seconds`, the PSNR of its best state so far read at every mark.
//!
//! `cargo run --release -p infer --example f-curve -- DIR [--paths 500|auto] [--seconds 10]
//!  [--lr-scale 1] [--as-drawn false] [--fixed-alpha false]`
//!
//! Prints one line per image (its B, then the PSNR at each mark) and the means.

use std::ops::ControlFlow;
use std::path::PathBuf;

use burn::tensor::Device;
use clap::Parser;
use common::decode::load;
use infer::{
    FinetuneOptions, Job, Learned, Limit, ModelSource, Models, PathBudget, finetune_with_progress, run,
};

/// Time SuperSVG-F on a folder.
#[derive(Parser, Debug)]
struct Args {
    /// The folder.
    dir: PathBuf,
    /// Path budget of the SuperSVG-B drawing F starts from.
    #[arg(long, default_value = "500", value_parser = str::parse::<PathBudget>)]
    paths: PathBudget,
    /// Long side of the working resolution.
    #[arg(long, default_value_t = 512)]
    size: u32,
    /// Seconds of F.
    #[arg(long, default_value_t = 10.0)]
    seconds: f64,
    /// Every learning rate times this.
    #[arg(long, default_value_t = 1.0)]
    lr_scale: f32,
    /// [`FinetuneOptions::as_drawn`].
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    as_drawn: bool,
    /// [`FinetuneOptions::fixed_alpha`].
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    fixed_alpha: bool,
    /// E_o's file (`train-optimizer`'s): its steps first, then Adam.
    #[arg(long)]
    optimizer: Option<PathBuf>,
    /// Only the first N images.
    #[arg(long)]
    limit: Option<usize>,
}

const MARKS: [f64; 7] = [0.25, 0.5, 1.0, 2.0, 3.0, 5.0, 10.0];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = Args::parse();
    let device = Device::flex();
    let mut models = Models::bundled(true, &device)?;
    if let Some(file) = &args.optimizer {
        models = models.with_optimizer(&ModelSource::File(file.clone()), &device)?;
    }
    let learned = models.optimizer.as_ref().map(|optimizer| Learned {
        network: optimizer.network.clone(),
        steps: optimizer.steps(),
        device: device.clone(),
    });
    let defaults = FinetuneOptions::default();
    let options = FinetuneOptions {
        limit: Limit::Seconds(args.seconds),
        lr_points: defaults.lr_points * args.lr_scale,
        lr_outline_points: defaults.lr_outline_points * args.lr_scale,
        lr_colors: defaults.lr_colors * args.lr_scale,
        as_drawn: args.as_drawn,
        fixed_alpha: args.fixed_alpha,
        learned,
    };
    let marks: Vec<f64> = MARKS.iter().copied().filter(|&m| m <= args.seconds).collect();
    let mut sums = vec![0.0; marks.len() + 2];
    let mut count = 0;
    let files = common::folder::files_in(&args.dir)?;
    for path in files.iter().take(args.limit.unwrap_or(usize::MAX)) {
        let Ok(loaded) = load(path, args.size) else { continue };
        let job = Job { paths: args.paths, ..Job::default() };
        let drawn = run(&models, &loaded, &job, &device)?;
        let mut at = vec![f64::NAN; marks.len()];
        let mut last = drawn.report.psnr;
        let mut scene = drawn.scene.clone();
        finetune_with_progress(&mut scene, &options, &mut |progress| {
            for (k, &mark) in marks.iter().enumerate() {
                if progress.seconds <= mark {
                    at[k] = progress.psnr;
                }
            }
            last = progress.psnr;
            ControlFlow::Continue(())
        });
        for value in at.iter_mut() {
            if value.is_nan() {
                *value = last;
            }
        }
        let kept = common::psnr(&scene.canvas_image(), &loaded.image);
        let row: Vec<f64> = std::iter::once(drawn.report.psnr).chain(at).chain([kept]).collect();
        let name = path.file_name().unwrap_or_default().to_string_lossy();
        println!("{name}\t{}", row.iter().map(|v| format!("{v:.2}")).collect::<Vec<_>>().join("\t"));
        sums.iter_mut().zip(&row).for_each(|(sum, v)| *sum += v);
        count += 1;
    }
    let header: Vec<String> = std::iter::once("B".to_string())
        .chain(marks.iter().map(|m| format!("{m}s")))
        .chain(["kept".into()])
        .collect();
    println!("mean of {count}\t{}", header.join("\t"));
    println!(
        "mean\t{}",
        sums.iter().map(|s| format!("{:.3}", s / count.max(1) as f64)).collect::<Vec<_>>().join("\t")
    );
    Ok(())
}
