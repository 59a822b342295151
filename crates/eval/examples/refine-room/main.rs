//! How much a network that moves what is drawn could gain in one pass (issue 54's question):
//! measured in docs/eval/refine-room.md.
//!
//! A network that reads one region's box (target, canvas, the region's outline) and is trained
//! on that box's error can at best predict the outline's own optimum with the rest of the
//! drawing held as it is. This finds that optimum by optimization ([`train::Room`], the mover's
//! teacher: Adam on the exact renderer, `--steps` steps, the region's points and flat colour,
//! or its points only) for every region of a SuperSVG-B drawing (the mover off), its outlines
//! as drawn, and applies the moves as a batched network would — all from the same drawing, each
//! scaled by `--damping` — or one region after another (`--one-by-one`: what a single pass
//! cannot do, since each region then sees its neighbours' moves). `--simplify` simplifies what
//! moved before it is scored, as the mover's stage does.
//!
//! `cargo run --release -p eval --example refine-room -- IMAGE... [--paths 500] [--steps 30]
//!  [--damping 1] [--passes 1] [--one-by-one | --shared] [--points-only] [--fills F] [--decimals 1]
//!  [--simplify PX] [--lpips]`
//!
//! Prints, per image, B's PSNR and bytes as `infer` writes it, then B re-written and each
//! pass's drawing: PSNR (exact renderer, points rounded to `--decimals` of a pixel as the SVG
//! writes them) and the SVG's bytes (region groups, `--decimals`), and the seconds the passes
//! took; last, the means.

use std::path::PathBuf;
use std::time::Instant;

use burn::tensor::Device;
use clap::Parser;
use common::PixelBox;
use common::decode::load;
use common::psnr_of_mse;
use eval::{Lpips, render_svg};
use infer::{Fills, FinetuneOptions, Job, Models, Moves, PathBudget, Scene, run};
use raster::{Fill, Outline, Shape, SvgOptions, to_svg_with};
use train::Room;

/// Measure the best one-pass move of every region of B's drawing.
#[derive(Parser, Debug)]
struct Args {
    /// The images.
    #[arg(required = true)]
    images: Vec<PathBuf>,
    /// Path budget of the SuperSVG-B drawing.
    #[arg(long, default_value_t = 500)]
    paths: usize,
    /// Adam steps that find each region's optimum.
    #[arg(long, default_value_t = 30)]
    steps: usize,
    /// The share of each region's move applied (a network may learn to damp what neighbours
    /// will also move).
    #[arg(long, default_value_t = 1.0)]
    damping: f32,
    /// Passes, each from the drawing the last one left.
    #[arg(long, default_value_t = 1)]
    passes: usize,
    /// Move each point that several outlines share by the mean of their moves.
    #[arg(long)]
    shared: bool,
    /// Move the regions one after another, each over its neighbours' moves.
    #[arg(long)]
    one_by_one: bool,
    /// Decimals of a pixel the SVG writes (points are rounded to them before scoring).
    #[arg(long, default_value_t = 1)]
    decimals: usize,
    /// B's fills (default: B's own).
    #[arg(long)]
    fills: Option<Fills>,
    /// Move the points only, each region keeping its colour.
    #[arg(long)]
    points_only: bool,
    /// Simplify every moved straight contour within this many pixels (Douglas–Peucker).
    #[arg(long)]
    simplify: Option<f32>,
    /// Also score LPIPS (eval's, of resvg's rendering of the SVG; weights from `$SUPERSVG_LPIPS`
    /// or models/lpips).
    #[arg(long)]
    lpips: bool,
}

/// Pixels around what an outline can change that its box also scores.
const PAD: u32 = 5;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = Args::parse();
    let device = Device::flex();
    let models = Models::bundled(true, &device)?;
    let rates = FinetuneOptions::default();
    let lpips = if args.lpips { Some(Lpips::load(&Lpips::default_folder(), &device)?) } else { None };
    let mut sums = vec![(0.0, 0.0, 0.0); args.passes + 1];
    for image in &args.images {
        let loaded = load(image, 512)?;
        let job = Job {
            paths: PathBudget::Count(args.paths),
            fills: args.fills,
            moves: Moves::Off,
            ..Job::default()
        };
        let drawn = run(&models, &loaded, &job, &device)?;
        let room = Room::of(drawn.scene.target(), PAD);
        let mut outlines = drawn_outlines(&drawn.scene);
        let mut line =
            format!("{}: B {:.3} dB {:.1} KB |", image.display(), drawn.report.psnr, kb(drawn.svg.len()));
        let size = drawn.scene.target().dimensions();
        for pass in 0..=args.passes {
            let started = Instant::now();
            if pass > 0 {
                outlines = moved(&room, &outlines, &args, &rates);
            }
            let seconds = started.elapsed().as_secs_f64();
            let scored: Vec<Outline> = match (args.simplify, pass) {
                (Some(tolerance), 1..) => outlines.iter().map(|o| o.simplified(tolerance, size)).collect(),
                _ => outlines.clone(),
            };
            let (psnr, svg) = score(&drawn.scene, &scored, loaded.original, args.decimals)?;
            sums[pass].0 += psnr;
            sums[pass].1 += kb(svg.len());
            line += &format!(" {psnr:.3} dB {:.1} KB", kb(svg.len()));
            if let Some(net) = &lpips {
                let (width, height) = loaded.image.dimensions();
                if let Some(distance) = net.distance(&render_svg(&svg, width, height)?, &loaded.image) {
                    sums[pass].2 += distance;
                    line += &format!(" LPIPS {distance:.4}");
                }
            }
            if pass > 0 {
                line += &format!(" ({seconds:.2} s)");
            }
        }
        println!("{line}");
    }
    let n = args.images.len() as f64;
    let means: Vec<String> = (sums.iter())
        .map(|(p, b, l)| match lpips {
            Some(_) => format!("{:.3} dB {:.1} KB LPIPS {:.4}", p / n, b / n, l / n),
            None => format!("{:.3} dB {:.1} KB", p / n, b / n),
        })
        .collect();
    println!("mean: {}", means.join(" | "));
    Ok(())
}

fn kb(bytes: usize) -> f64 {
    bytes as f64 / 1000.0
}

/// B's shapes as outlines, as drawn.
fn drawn_outlines(scene: &Scene) -> Vec<Outline> {
    scene.scene().iter().map(|shape| shape.to_outline().expect("a drawn path is finite")).collect()
}

/// The PSNR of `outlines` as the SVG writes them (points rounded to `decimals` of a pixel)
/// and the SVG's bytes at the image's own size.
fn score(
    scene: &Scene,
    outlines: &[Outline],
    (width, height): (u32, u32),
    decimals: usize,
) -> Result<(f64, String), raster::SvgError> {
    let scale = 10f32.powi(decimals as i32);
    let (w, h) = (width as f32, height as f32);
    let rounded: Vec<Outline> = (outlines.iter())
        .map(|o| {
            let points: Vec<[f32; 2]> = (o.points().iter())
                .map(|p| [(p[0] * w * scale).round() / scale / w, (p[1] * h * scale).round() / scale / h])
                .collect();
            o.with_points(&points)
        })
        .collect();
    let mut drawing = scene.clone();
    drawing.set_shapes(&rounded.iter().cloned().map(Shape::from).collect::<Vec<_>>());
    let (tw, th) = scene.target().dimensions();
    let values = 3.0 * f64::from(tw) * f64::from(th);
    let layers: Vec<Option<u32>> = scene.paths().iter().map(|placed| placed.region).collect();
    let svg =
        to_svg_with(&rounded, &layers, width, height, &SvgOptions { decimals, ..SvgOptions::default() })?;
    Ok((psnr_of_mse(drawing.total_error() / values), svg))
}

/// One pass: every region moved to its optimum over its box, all from the same drawing or
/// one by one, each move scaled by `--damping`.
fn moved(room: &Room, outlines: &[Outline], args: &Args, rates: &FinetuneOptions) -> Vec<Outline> {
    let mut moved = outlines.to_vec();
    let mut boxes: Vec<Option<PixelBox>> = outlines.iter().map(|o| room.pixel_box(o)).collect();
    for i in 0..outlines.len() {
        let over = if args.one_by_one { &moved } else { outlines };
        let best = room.optimum(over, &boxes, i, args.steps, !args.points_only, rates);
        moved[i] = damped(&outlines[i], &best, args.damping);
        if args.one_by_one {
            boxes[i] = room.pixel_box(&moved[i]);
        }
    }
    if args.shared {
        shared_moves(outlines, &mut moved);
    }
    moved
}

/// `start` moved the share `damping` of the way to `best`: its points, and a flat colour and
/// opacity.
fn damped(start: &Outline, best: &Outline, damping: f32) -> Outline {
    let lerp = |a: f32, b: f32| a + damping * (b - a);
    let points: Vec<[f32; 2]> =
        start.points().iter().zip(best.points()).map(|(a, b)| [lerp(a[0], b[0]), lerp(a[1], b[1])]).collect();
    let mut outline = start.with_points(&points);
    if let (Fill::Solid(a), Fill::Solid(b)) = (start.fill, best.fill) {
        outline.fill = Fill::Solid(std::array::from_fn(|k| lerp(a[k], b[k])));
    }
    outline.alpha = lerp(start.alpha, best.alpha);
    outline
}

/// Every point that several outlines share where they start (a boundary point drawn once for
/// each region it bounds) moved by the mean of their moves, so that neighbours agree on their
/// common edge.
fn shared_moves(start: &[Outline], moved: &mut [Outline]) {
    use std::collections::HashMap;
    let key = |p: [f32; 2]| (p[0].to_bits(), p[1].to_bits());
    let mut sums: HashMap<(u32, u32), ([f64; 2], usize)> = HashMap::new();
    // Each outline's points before and after its move.
    type Moves = (Vec<[f32; 2]>, Vec<[f32; 2]>);
    let points: Vec<Moves> = start.iter().zip(moved.iter()).map(|(a, b)| (a.points(), b.points())).collect();
    for (before, after) in &points {
        for (p, q) in before.iter().zip(after) {
            let entry = sums.entry(key(*p)).or_insert(([0.0; 2], 0));
            entry.0[0] += f64::from(q[0] - p[0]);
            entry.0[1] += f64::from(q[1] - p[1]);
            entry.1 += 1;
        }
    }
    for ((before, _), outline) in points.iter().zip(moved.iter_mut()) {
        let agreed: Vec<[f32; 2]> = (before.iter())
            .map(|p| {
                let (sum, count) = sums[&key(*p)];
                [p[0] + (sum[0] / count as f64) as f32, p[1] + (sum[1] / count as f64) as f32]
            })
            .collect();
        *outline = outline.with_points(&agreed);
    }
}
