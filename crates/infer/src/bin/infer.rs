//! `infer`: turns images into SVG with the trained SuperSVG networks.
//!
//! `infer photo.jpg -o photo.svg [--paths 500] [--preview photo.png] [--metrics photo.json]`
//! `infer a.png b.jpg … -o out/` (a folder for several inputs)

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use clap::Parser;
use image::{Rgb32FImage, RgbImage};
use indicatif::ProgressBar;
use infer::decode::load;
use infer::finetune::{Budget, FinetuneOptions, finetune};
use infer::metrics::{mse, psnr, ssim};
use infer::models::{Models, bundled};
use infer::pipeline::{Options, vectorize};
use infer::write::{write_atomic, write_png};
use raster::{Backend, render_exact, to_svg};

/// Vectorize images into SVG with SuperSVG.
#[derive(Parser, Debug)]
#[command(name = "infer", version)]
struct Args {
    /// Input images (png, jpeg, webp, gif, bmp, tiff).
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// Output SVG file for one input, or a folder for several.
    #[arg(short, long)]
    output: PathBuf,
    /// The most paths in the result (at least 2); fewer only when no further path lowers the
    /// error.
    #[arg(long, default_value_t = 500)]
    paths: usize,
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
    /// Long side of the working resolution (the SVG keeps the input's size).
    #[arg(long, default_value_t = 512)]
    size: u32,
    /// Number of superpixels (default: the operating point stored with the coarse model, for
    /// the budget).
    #[arg(long)]
    regions: Option<usize>,
    /// Write a PNG rendering of the result (a folder for several inputs).
    #[arg(long)]
    preview: Option<PathBuf>,
    /// Write input and rendering side by side as PNG (a folder for several inputs).
    #[arg(long)]
    compare: Option<PathBuf>,
    /// Write MSE, PSNR, SSIM, path count and seconds per stage as JSON (a folder for several).
    #[arg(long)]
    metrics: Option<PathBuf>,
    /// Seed of the device's random generator (results are deterministic per seed and backend).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// SuperSVG-F: fine-tune every path against the image, this many steps per region.
    #[arg(long, conflicts_with = "finetune_secs")]
    finetune_steps: Option<usize>,
    /// SuperSVG-F: fine-tune every path against the image for this many seconds.
    #[arg(long)]
    finetune_secs: Option<f64>,
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
            eprintln!("error: {err}");
            ExitCode::FAILURE
        }
    }
}

/// Loads the models, then vectorizes every input; returns how many inputs failed.
fn run(args: &Args) -> Result<usize, String> {
    let many = args.inputs.len() > 1;
    if many {
        for folder in
            [Some(&args.output), args.preview.as_ref(), args.compare.as_ref(), args.metrics.as_ref()]
                .into_iter()
                .flatten()
        {
            std::fs::create_dir_all(folder).map_err(|err| format!("{}: {err}", folder.display()))?;
        }
    }
    let device = args.backend.device().map_err(|err| err.to_string())?;
    device.seed(args.seed);
    let coarse = match &args.coarse {
        Some(path) => path.clone(),
        None => PathBuf::from(bundled("coarse.ckpt")?),
    };
    let refine = match (&args.refine, args.no_refine) {
        (_, true) => None,
        (Some(path), false) => Some(path.clone()),
        (None, false) => Some(bundled("refine.ckpt")?),
    };
    let models = Models::load(&coarse, refine.as_deref(), &device).map_err(|err| err.to_string())?;
    let options = Options { paths: args.paths, regions: args.regions, ..Options::default() };

    let bar = (many && std::io::stderr().is_terminal()).then(|| ProgressBar::new(args.inputs.len() as u64));
    let mut failed = 0;
    for input in &args.inputs {
        let destination = |folder: &Path, extension: &str| -> PathBuf {
            if many {
                let stem = input.file_stem().unwrap_or_default();
                folder.join(Path::new(stem).with_extension(extension))
            } else {
                folder.to_path_buf()
            }
        };
        let result = process(input, &models, &options, args, &device, &destination);
        if let Err(message) = result {
            let line = format!("error: {}: {message}", input.display());
            match &bar {
                Some(bar) => bar.println(line),
                None => eprintln!("{line}"),
            }
            failed += 1;
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

/// One input: vectorize, write the SVG and whatever extra output was asked for.
fn process(
    input: &Path,
    models: &Models,
    options: &Options,
    args: &Args,
    device: &burn::tensor::Device,
    destination: &dyn Fn(&Path, &str) -> PathBuf,
) -> Result<(), String> {
    let started = Instant::now();
    let loaded = load(input, args.size).map_err(|err| err.message)?;
    let decoded = started.elapsed().as_secs_f64();
    let mut result = vectorize(models, &loaded.image, options, device).map_err(|err| err.to_string())?;
    let budget = match (args.finetune_steps, args.finetune_secs) {
        (Some(steps), _) => Some(Budget::StepsPerRegion(steps)),
        (None, Some(seconds)) => Some(Budget::Seconds(seconds)),
        (None, None) => None,
    };
    if let Some(budget) = budget {
        let tuning = Instant::now();
        let options = FinetuneOptions { budget, ..FinetuneOptions::default() };
        finetune(&mut result.scene, &options, &device.clone().autodiff());
        result.timings.push(("finetune", tuning.elapsed().as_secs_f64()));
    }
    let scene = result.scene.scene();

    let export = Instant::now();
    let (width, height) = loaded.original;
    let svg = to_svg(&scene, width, height, None).map_err(|err| err.to_string())?;
    let svg_path = destination(&args.output, "svg");
    write_atomic(&svg_path, svg.as_bytes()).map_err(|err| format!("{}: {err}", svg_path.display()))?;

    let (w, h) = loaded.image.dimensions();
    let needs_render = args.preview.is_some() || args.compare.is_some() || args.metrics.is_some();
    let rendering = needs_render.then(|| render_exact(&scene, w, h, [1.0; 3]));
    if let (Some(folder), Some(rendering)) = (&args.preview, &rendering) {
        let path = destination(folder, "png");
        write_png(&path, rendering).map_err(|err| format!("{}: {err}", path.display()))?;
    }
    if let (Some(folder), Some(rendering)) = (&args.compare, &rendering) {
        let path = destination(folder, "png");
        write_png(&path, &side_by_side(&loaded.image, rendering))
            .map_err(|err| format!("{}: {err}", path.display()))?;
    }
    let export_seconds = export.elapsed().as_secs_f64();
    if let (Some(folder), Some(rendering)) = (&args.metrics, &rendering) {
        let drawn = image::DynamicImage::ImageRgb8(rendering.clone()).to_rgb32f();
        let mut seconds = serde_json::Map::new();
        seconds.insert("decode".into(), decoded.into());
        for (stage, value) in &result.timings {
            seconds.insert((*stage).into(), (*value).into());
        }
        seconds.insert("export".into(), export_seconds.into());
        seconds.insert("total".into(), started.elapsed().as_secs_f64().into());
        let report = serde_json::json!({
            "input": input.display().to_string(),
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
                "coarse_paths": result.operating_point.coarse_paths,
                "refine_share": result.operating_point.refine_share,
            },
            "mse": mse(&drawn, &loaded.image),
            "psnr": psnr(&drawn, &loaded.image),
            "ssim": ssim(&drawn, &loaded.image),
            "seconds": seconds,
        });
        let path = destination(folder, "json");
        let text = serde_json::to_string_pretty(&report).expect("metrics serialize");
        write_atomic(&path, text.as_bytes()).map_err(|err| format!("{}: {err}", path.display()))?;
    }
    Ok(())
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
