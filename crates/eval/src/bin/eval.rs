//! `eval`: SuperSVG (B, and F when asked) against other vectorizers on a folder of images.
//!
//! `eval DIR --paths 500,2000,4000 [--finetune-secs 10] --out report.md`
//!
//! Every SVG is rendered with resvg, independently of the project's renderers, at the working
//! resolution, and compared with the input scaled to it (MSE, PSNR, SSIM, and LPIPS when
//! `scripts/fetch-lpips.sh` has provided its weights). Writes a markdown report and a contact
//! sheet (input | each method) next to it.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, bail};
use clap::Parser;
use eval::cli::{files_in, finish, load_models};
use eval::lpips::Lpips;
use eval::peers::{
    PeerError, available, count_shapes, fallback_mosaic, mean_color_superpixels, potrace_colors, render_svg,
    vtracer,
};
use eval::spill::spill;
use image::{Rgb32FImage, RgbImage};
use infer::decode::load;
use infer::finetune::{Budget, FinetuneOptions, finetune};
use infer::metrics::{mse, psnr, ssim};
use infer::pipeline::{AutoBudget, MAX_PATHS, Options, auto_budget, operating_point, vectorize};
use infer::scene::{Origin, Scene};
use infer::write::{write_atomic, write_png};
use raster::{Backend, to_svg};

/// Peers `--peers` accepts.
const PEERS: [&str; 4] = ["vtracer", "potrace", "slic", "fallback"];
/// Dilation (pixels) of a region's mask before its paths' spill is measured: the margin the
/// training's boundary loss allows.
const SPILL_DILATION: u32 = 2;

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
    /// Peers: vtracer and potrace (when installed), slic (pixel-exact superpixels in their mean
    /// colour), fallback (SuperSVG's fallback drawing alone); comma separated, empty for none.
    #[arg(long, value_delimiter = ',', default_value = "vtracer,potrace,slic,fallback")]
    peers: Vec<String>,
    /// Evaluate only the first N images.
    #[arg(long)]
    limit: Option<usize>,
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
struct Anatomy {
    stages: Vec<(Origin, usize)>,
    spill: f64,
}

fn main() -> ExitCode {
    finish(run(Args::parse()))
}

fn run(args: Args) -> anyhow::Result<()> {
    if let Some(bad) = args.peers.iter().find(|p| !p.is_empty() && !PEERS.contains(&p.as_str())) {
        bail!("--peers: unknown peer `{bad}` (known: {})", PEERS.join(", "));
    }
    if let Some(bad) = args.paths.iter().find(|&&p| !(2..=MAX_PATHS).contains(&p)) {
        bail!("--paths: {bad} is out of range (2, the background and one region, to {MAX_PATHS})");
    }
    if !(16..=8192).contains(&args.size) {
        bail!("--size: {} is out of range (16 to 8192 pixels)", args.size);
    }
    if let Some(seconds) = args.finetune_secs.filter(|s| !(s.is_finite() && *s >= 0.0)) {
        bail!("--finetune-secs: {seconds} is not a number of seconds");
    }
    let mut images = files_in(&args.dir)?;
    images.truncate(args.limit.unwrap_or(usize::MAX));
    if images.is_empty() {
        bail!("{}: no images", args.dir.display());
    }
    let device = args.backend.device()?;
    let (models, _, _) = load_models(args.coarse.as_deref(), args.refine.as_deref(), &device)?;
    let scratch = std::env::temp_dir().join(format!("supersvg-eval-{}", std::process::id()));
    std::fs::create_dir_all(&scratch)?;

    let wanted = |peer: &str| args.peers.iter().any(|p| p == peer);
    let use_vtracer = wanted("vtracer") && available("vtracer");
    let use_potrace = wanted("potrace") && available("potrace");
    let mut notes = Vec::new();
    for (peer, used) in [("vtracer", use_vtracer), ("potrace", use_potrace)] {
        if wanted(peer) && !used {
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

    // results[(budget, method)] = one row per image
    let mut results: BTreeMap<(usize, String), Vec<Row>> = BTreeMap::new();
    let mut sheet_rows: Vec<Vec<(String, Rgb32FImage)>> = Vec::new();
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
        let png = scratch.join("input.png");
        write_png(&png, &to_rgb8(image))?;
        let mut tiles = vec![("input".to_string(), image.clone())];
        let mut record = |budget: usize,
                          method: &str,
                          drawn: Result<Drawn, PeerError>,
                          seconds: f64,
                          anatomy: Option<Anatomy>,
                          tiles: &mut Vec<(String, Rgb32FImage)>| {
            match drawn {
                Ok(Drawn { image: drawn, shapes, bytes }) => {
                    let row = Row {
                        image: name.clone(),
                        shapes,
                        bytes,
                        mse: mse(&drawn, image),
                        psnr: psnr(&drawn, image),
                        ssim: ssim(&drawn, image).unwrap_or(f64::NAN),
                        lpips: lpips.as_ref().map(|net| net.distance(&drawn, image)),
                        seconds,
                        anatomy,
                    };
                    if budget == args.paths[0] {
                        tiles.push((method.to_string(), drawn));
                    }
                    results.entry((budget, method.to_string())).or_default().push(row);
                }
                Err(err) => eprintln!("{}: {method} at {budget}: {err}", path.display()),
            }
        };
        let rendered = |svg: &str| {
            render_svg(svg, width, height).map(|drawn| Drawn {
                image: drawn,
                shapes: count_shapes(svg),
                bytes: Some(svg.len()),
            })
        };
        let drawing = |scene: &Scene| -> Result<Drawn, PeerError> {
            let svg = to_svg(&scene.scene(), width, height, None)?;
            rendered(&svg)
        };
        let anatomy = |scene: &Scene| Anatomy {
            stages: scene.counts(),
            spill: spill(scene.paths(), scene.segmentation(), SPILL_DILATION),
        };
        for &budget in &args.paths {
            let started = Instant::now();
            let options = Options { paths: budget, ..Options::default() };
            let mut result = vectorize(&models, image, &options, &device)?;
            let seconds = started.elapsed().as_secs_f64();
            let parts = Some(anatomy(&result.scene));
            record(budget, "SuperSVG-B (ours)", drawing(&result.scene), seconds, parts, &mut tiles);
            if let Some(limit) = args.finetune_secs {
                let tuning = Instant::now();
                let options_f =
                    FinetuneOptions { budget: Budget::Seconds(limit), ..FinetuneOptions::default() };
                finetune(&mut result.scene, &options_f);
                let total = seconds + tuning.elapsed().as_secs_f64();
                let parts = Some(anatomy(&result.scene));
                record(budget, "SuperSVG-F (ours)", drawing(&result.scene), total, parts, &mut tiles);
            }
            if wanted("fallback") {
                let drawn = fallback_mosaic(image, budget).and_then(|(paths, seconds)| {
                    let svg = to_svg(&paths, width, height, None)?;
                    Ok((rendered(&svg)?, seconds))
                });
                let seconds = drawn.as_ref().map_or(0.0, |(_, s)| *s);
                let name = "fallback alone (traced regions, mean colour)";
                record(budget, name, drawn.map(|(d, _)| d), seconds, None, &mut tiles);
            }
            if use_vtracer {
                let traced = vtracer(&png, Some(budget), &scratch);
                let seconds = traced.as_ref().map_or(0.0, |t| t.seconds);
                record(budget, "vtracer", traced.and_then(|t| rendered(&t.svg)), seconds, None, &mut tiles);
            }
            if use_potrace {
                let traced = potrace_colors(image, 16, Some(budget), &scratch);
                let seconds = traced.as_ref().map_or(0.0, |t| t.seconds);
                let drawn = traced.and_then(|t| rendered(&t.svg));
                record(budget, "potrace, 16 colour layers", drawn, seconds, None, &mut tiles);
            }
            if wanted("slic") {
                let (filled, regions, seconds) = mean_color_superpixels(image, budget);
                let drawn = Drawn { image: filled, shapes: regions, bytes: None };
                record(budget, "SLIC regions, mean colour", Ok(drawn), seconds, None, &mut tiles);
            }
        }
        // Each method's own budget: `--paths auto` for SuperSVG-B, vtracer's defaults.
        let started = Instant::now();
        let defaults = Options::default();
        let point = operating_point(&models, &defaults);
        let paths = auto_budget(image, &point, defaults.compactness, &AutoBudget::default())?;
        let result = vectorize(&models, image, &Options { paths, ..defaults }, &device)?;
        let seconds = started.elapsed().as_secs_f64();
        let parts = Some(anatomy(&result.scene));
        record(0, "SuperSVG-B (ours), --paths auto", drawing(&result.scene), seconds, parts, &mut tiles);
        if use_vtracer {
            let traced = vtracer(&png, None, &scratch);
            let seconds = traced.as_ref().map_or(0.0, |t| t.seconds);
            let drawn = traced.and_then(|t| rendered(&t.svg));
            record(0, "vtracer (default settings)", drawn, seconds, None, &mut tiles);
        }
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
    let columns: Vec<String> =
        sheet_rows.first().map(|row| row.iter().map(|(name, _)| name.clone()).collect()).unwrap_or_default();
    let report = report(&args, evaluated, &results, &notes, (&sheet_path, &columns));
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
    results: &BTreeMap<(usize, String), Vec<Row>>,
    notes: &[String],
    (sheet, columns): (&Path, &[String]),
) -> String {
    let mut text = format!(
        "# Evaluation on `{}`\n\n{images} images, working resolution {} px (long side). Every SVG rendered \
         with resvg and compared with the input at that size; means over images. \"shapes\" counts closed \
         subpaths, the same unit for every method.\n\nCommand: `{}`\n\n",
        args.dir.display(),
        args.size,
        std::env::args().collect::<Vec<_>>().join(" ")
    );
    let budgets: Vec<usize> = {
        let mut b: Vec<usize> = results.keys().map(|(budget, _)| *budget).collect();
        b.dedup();
        b
    };
    for budget in budgets {
        let title =
            if budget == 0 { "Each method's own budget".to_string() } else { format!("{budget} paths") };
        let _ = writeln!(
            text,
            "## {title}\n\n| method | shapes | SVG KB | PSNR (dB) | SSIM | MSE | LPIPS | seconds / image |\n| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"
        );
        let rows_here = results.iter().filter(|((b, _), _)| *b == budget);
        for ((_, method), rows) in rows_here.clone() {
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
                "\nWhere SuperSVG's paths come from (mean paths per image by stage) and spill (share of \
                 region paths' area outside their region dilated by {SPILL_DILATION} px):\n\n| method | {} | \
                 spill |\n| --- |{} ---: |",
                stages.join(" | "),
                " ---: |".repeat(stages.len())
            );
            for ((_, method), rows) in ours {
                let anatomy = || rows.iter().filter_map(|r| r.anatomy.as_ref());
                let per_stage: Vec<String> = Origin::ALL
                    .iter()
                    .map(|origin| {
                        let count: usize = anatomy()
                            .map(|a| a.stages.iter().find(|(o, _)| o == origin).map_or(0, |(_, n)| *n))
                            .sum();
                        format!("{:.1}", count as f64 / rows.len() as f64)
                    })
                    .collect();
                let spill = anatomy().map(|a| a.spill).sum::<f64>() / rows.len() as f64;
                let _ = writeln!(text, "| {method} | {} | {spill:.3} |", per_stage.join(" | "));
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

/// Each image's PSNR / LPIPS per method, one table per budget: where a mean hides one image
/// that loses.
fn per_image(results: &BTreeMap<(usize, String), Vec<Row>>) -> String {
    let mut text = String::from("## Per image (PSNR dB / LPIPS)\n");
    let mut budgets: Vec<usize> = results.keys().map(|(budget, _)| *budget).collect();
    budgets.dedup();
    for budget in budgets {
        let methods: Vec<(&String, &Vec<Row>)> =
            results.iter().filter(|((b, _), _)| *b == budget).map(|((_, m), rows)| (m, rows)).collect();
        let mut images: Vec<&str> =
            methods.iter().flat_map(|(_, rows)| rows.iter().map(|r| r.image.as_str())).collect();
        images.sort_unstable();
        images.dedup();
        let title =
            if budget == 0 { "each method's own budget".to_string() } else { format!("{budget} paths") };
        let names: Vec<&str> = methods.iter().map(|(m, _)| m.as_str()).collect();
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
fn contact_sheet(rows: &[Vec<(String, Rgb32FImage)>], tile: u32) -> RgbImage {
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
