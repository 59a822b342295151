//! How much a network that moves what is drawn could gain in one pass (issue 54's question),
//! and how much a small learned one takes of it: measured in docs/eval/refine-room.md.
//!
//! A network that reads one region's box (target, canvas, the region's outline) and is trained
//! on that box's error can at best predict the outline's own optimum with the rest of the
//! drawing held as it is. This finds that optimum by optimization (Adam on the exact renderer,
//! `--steps` steps, the region's points and flat colour, or its points only) for every region
//! of a SuperSVG-B drawing, its outlines as drawn, and applies the moves as a batched network
//! would — all from the same drawing, each scaled by `--damping` — or one region after another
//! (`--one-by-one`: what a single pass cannot do, since each region then sees its neighbours'
//! moves).
//!
//! With `--learn FOLDER` it also learns each point's move along its normal from the optimum's
//! moves on the images in FOLDER ([`learn`]) and scores that network's one pass; `--save` and
//! `--net` keep and reuse it; `--simplify` simplifies what moved before it is scored.
//!
//! `cargo run --release -p eval --example refine-room -- IMAGE... [--paths 500] [--steps 30]
//!  [--damping 1] [--passes 1] [--one-by-one | --shared] [--points-only] [--fills F] [--decimals 1]
//!  [--net FILE]... [--learn FOLDER [--epochs 20] [--save FILE]] [--learned-passes 1] [--finetune-secs S] [--simplify PX] [--lpips]`
//!
//! Prints, per image, B's PSNR and bytes as `infer` writes it, then B re-written and each
//! pass's drawing: PSNR (exact renderer, points rounded to `--decimals` of a pixel as the SVG
//! writes them) and the SVG's bytes (region groups, `--decimals`), the seconds the passes took,
//! and the learned pass's; last, the means.

use std::path::PathBuf;
use std::time::Instant;

use burn::tensor::Device;
use clap::Parser;
use common::PixelBox;
use common::decode::load;
use common::psnr_of_mse;
use eval::{Lpips, render_svg};
use infer::{Fills, FinetuneOptions, Job, Limit, Models, PathBudget, Scene, finetune, run};
use raster::{Fill, Filled, FlatAdam, Outline, Shape, SvgOptions, Window, to_svg_with};

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
    /// Learn each point's move along its normal from the optimum moves of the images in this
    /// folder (a small network over the point's profile), and score its pass too.
    #[arg(long)]
    learn: Option<PathBuf>,
    /// Simplify every moved straight contour within this many pixels (Douglas–Peucker).
    #[arg(long)]
    simplify: Option<f32>,
    /// Passes of the learned network, each over the drawing the last one left.
    #[arg(long, default_value_t = 1)]
    learned_passes: usize,
    /// Also fine-tune (SuperSVG-F) for this many seconds from the learned passes' drawing, and
    /// from B for as long and for twice as long.
    #[arg(long)]
    finetune_secs: Option<f64>,
    /// Write the learned network here.
    #[arg(long)]
    save: Option<PathBuf>,
    /// The networks (written by `--save`) of the learned passes, in order (the last repeats);
    /// `--learn` learns the pass after them.
    #[arg(long)]
    net: Vec<PathBuf>,
    /// Also score LPIPS (eval's, of resvg's rendering of the SVG; weights from `$SUPERSVG_LPIPS`
    /// or models/lpips).
    #[arg(long)]
    lpips: bool,
    /// Epochs of that learning.
    #[arg(long, default_value_t = 20)]
    epochs: usize,
}

mod learn;

/// Pixels around what an outline can change that its box also scores.
const PAD: u32 = 5;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = Args::parse();
    let device = Device::flex();
    let models = Models::bundled(true, &device)?;
    let rates = FinetuneOptions::default();
    let lpips = if args.lpips { Some(Lpips::load(&Lpips::default_folder(), &device)?) } else { None };
    let mut sums = vec![(0.0, 0.0, 0.0); args.passes + 1];
    let mut finetuned = [0.0; 3];
    let mut learned = (args.net.iter()).map(|file| learn::Mlp::open(file)).collect::<Result<Vec<_>, _>>()?;
    if let Some(folder) = &args.learn {
        let mut mlp = learn::train(folder, &learned, &args, &models, &device, &rates)?;
        if let Some(file) = &args.save {
            mlp.save(file)?;
        }
        learned.push(mlp);
    }
    if !learned.is_empty() {
        sums.extend(std::iter::repeat_n((0.0, 0.0, 0.0), args.learned_passes));
    }
    for image in &args.images {
        let loaded = load(image, 512)?;
        let job = Job { paths: PathBudget::Count(args.paths), fills: args.fills, ..Job::default() };
        let drawn = run(&models, &loaded, &job, &device)?;
        let room = Room::of(&drawn.scene);
        let mut outlines = room.start(&drawn.scene);
        let mut line =
            format!("{}: B {:.3} dB {:.1} KB |", image.display(), drawn.report.psnr, kb(drawn.svg.len()));
        let mut score = |outlines: &[Outline],
                         pass: usize,
                         line: &mut String|
         -> Result<(), Box<dyn std::error::Error>> {
            let size = (room.width as f32, room.height as f32);
            let simple: Vec<Outline> = match (args.simplify, pass) {
                (Some(tolerance), 1..) => {
                    outlines.iter().map(|o| learn::simplified(o, tolerance, size)).collect()
                }
                _ => outlines.to_vec(),
            };
            let (psnr, svg) = room.score(&drawn.scene, &simple, loaded.original, args.decimals)?;
            sums[pass].0 += psnr;
            sums[pass].1 += kb(svg.len());
            *line += &format!(" {psnr:.3} dB {:.1} KB", kb(svg.len()));
            if let Some(net) = &lpips {
                let (width, height) = loaded.image.dimensions();
                let distance = net.distance(&render_svg(&svg, width, height)?, &loaded.image);
                sums[pass].2 += distance;
                *line += &format!(" LPIPS {distance:.4}");
            }
            Ok(())
        };
        score(&outlines, 0, &mut line)?;
        let mut seconds = 0.0;
        for pass in 1..=args.passes {
            let started = Instant::now();
            outlines = room.pass(&outlines, &args, &rates);
            seconds += started.elapsed().as_secs_f64();
            score(&outlines, pass, &mut line)?;
        }
        line += &format!(" ({seconds:.2} s)");
        if let Some(last) = learned.last() {
            line += " | learned";
            let (mut drawing, mut moved) = (drawn.scene.clone(), room.start(&drawn.scene));
            for pass in 1..=args.learned_passes {
                let started = Instant::now();
                moved = learn::pass(learned.get(pass - 1).unwrap_or(last), &drawing, &moved);
                let seconds = started.elapsed().as_secs_f64();
                score(&moved, args.passes + pass, &mut line)?;
                line += &format!(" ({seconds:.3} s)");
                drawing.set_shapes(&moved.iter().cloned().map(Shape::from).collect::<Vec<_>>());
            }
            if let Some(seconds) = args.finetune_secs {
                let psnr_after = |scene: &Scene, seconds: f64| {
                    let mut scene = scene.clone();
                    finetune(
                        &mut scene,
                        &FinetuneOptions { limit: Limit::Seconds(seconds), ..rates.clone() },
                    );
                    let values = 3.0 * f64::from(room.width) * f64::from(room.height);
                    psnr_of_mse(scene.total_error() / values)
                };
                let f = [
                    psnr_after(&drawn.scene, seconds),
                    psnr_after(&drawn.scene, 2.0 * seconds),
                    psnr_after(&drawing, seconds),
                ];
                line += &format!(
                    " | F from B {seconds} s {:.3}, {} s {:.3}; F from the learned pass {seconds} s {:.3}",
                    f[0],
                    2.0 * seconds,
                    f[1],
                    f[2]
                );
                finetuned.iter_mut().zip(f).for_each(|(sum, psnr)| *sum += psnr);
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
    if args.finetune_secs.is_some() {
        let [a, b, c] = finetuned.map(|sum| sum / n);
        println!("mean F: from B {a:.3}, twice as long {b:.3}; from the learned pass {c:.3}");
    }
    Ok(())
}

fn kb(bytes: usize) -> f64 {
    bytes as f64 / 1000.0
}

/// The image as the exact renderer scores it.
struct Room {
    width: u32,
    height: u32,
    /// Planar RGB, `[3][height][width]`.
    target: Vec<f32>,
}

impl Room {
    fn of(scene: &Scene) -> Self {
        let image = scene.target();
        let (width, height) = image.dimensions();
        let target = (0..3).flat_map(|c| image.pixels().map(move |p| p.0[c])).collect();
        Self { width, height, target }
    }

    /// B's shapes as outlines, as drawn.
    fn start(&self, scene: &Scene) -> Vec<Outline> {
        (scene.scene().iter())
            .map(|shape| match shape {
                Shape::Outline(outline) => (**outline).clone(),
                Shape::Path(path) => Outline::from_path(path, path.color).expect("a drawn path"),
            })
            .collect()
    }

    /// The PSNR of `outlines` as the SVG writes them (points rounded to `decimals` of a pixel)
    /// and the SVG's bytes at the image's own size.
    fn score(
        &self,
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
        let values = 3.0 * f64::from(self.width) * f64::from(self.height);
        let layers: Vec<Option<u32>> = scene.paths().iter().map(|placed| placed.region).collect();
        let svg =
            to_svg_with(&rounded, &layers, width, height, &SvgOptions { decimals, ..SvgOptions::default() })?;
        Ok((psnr_of_mse(drawing.total_error() / values), svg))
    }

    /// The pixels `outline` can change, grown by [`PAD`] within the image: the box its move is
    /// scored over. `None` when it has no finite point.
    fn pixel_box(&self, outline: &Outline) -> Option<PixelBox> {
        Some(outline.pixel_box(self.width, self.height)?.padded(PAD, self.width, self.height))
    }

    /// One pass: every region moved to its optimum over its box.
    fn pass(&self, outlines: &[Outline], args: &Args, rates: &FinetuneOptions) -> Vec<Outline> {
        let mut moved = outlines.to_vec();
        let mut boxes: Vec<Option<PixelBox>> = outlines.iter().map(|o| self.pixel_box(o)).collect();
        for i in 0..outlines.len() {
            let over = if args.one_by_one { &moved } else { outlines };
            moved[i] = self.optimum(over, &boxes, i, args, rates);
            if args.one_by_one {
                boxes[i] = self.pixel_box(&moved[i]);
            }
        }
        if args.shared {
            shared_moves(outlines, &mut moved);
        }
        moved
    }

    /// Outline `i` of `outlines` moved (its points, and a flat colour unless `--points-only`;
    /// `args.steps` Adam steps, the best state kept) against its box with every other outline
    /// held, the move scaled by `args.damping`; `boxes` are the outlines' [`Room::pixel_box`]es.
    /// A ramp keeps its stops and ends; an outline without a box stays as it is.
    fn optimum(
        &self,
        outlines: &[Outline],
        boxes: &[Option<PixelBox>],
        i: usize,
        args: &Args,
        rates: &FinetuneOptions,
    ) -> Outline {
        let Some(bbox) = boxes[i] else { return outlines[i].clone() };
        let (cw, ch) = (bbox.width() as usize, bbox.height() as usize);
        let (w, h) = (self.width as f32, self.height as f32);
        let (sx, sy) = (w / cw as f32, h / ch as f32);
        let (ox, oy) = (bbox.x0() as f32 / cw as f32, bbox.y0() as f32 / ch as f32);
        let to_box = |o: &Outline| mapped(o, |p| [p[0] * sx - ox, p[1] * sy - oy]);
        let meeting = |range: std::ops::Range<usize>| -> Vec<Outline> {
            (range.filter(|&k| boxes[k].is_some_and(|other| other.intersection(&bbox).is_some())))
                .map(|k| to_box(&outlines[k]))
                .collect()
        };
        let below = meeting(0..i);
        let mut scene: Vec<Outline> = vec![to_box(&outlines[i])];
        scene.extend(meeting(i + 1..outlines.len()));
        let mut target = Vec::with_capacity(3 * cw * ch);
        let (width, height) = (self.width as usize, self.height as usize);
        for c in 0..3 {
            for y in bbox.rows() {
                let row = (c * height + y as usize) * width;
                target.extend_from_slice(&self.target[row + bbox.x0() as usize..row + bbox.x1() as usize]);
            }
        }
        let white =
            Window::new(cw as u32, ch as u32, vec![1.0; target.len()], target.clone()).expect("a box");
        let window = Window::new(cw as u32, ch as u32, white.render_outlines(&below), target).expect("a box");
        // Parameters: the points (x, y), then RGB, then opacity; a pixel's step as F's.
        let solid = match scene[0].fill {
            Fill::Solid(color) => Some(color),
            Fill::Linear(_) => None,
        };
        let points = scene[0].points();
        let mut params: Vec<f32> = points.iter().flatten().copied().collect();
        params.extend(solid.unwrap_or_default());
        params.push(scene[0].alpha);
        let start = params.clone();
        let n = 2 * points.len();
        let mut steps: Vec<f32> =
            (0..n).map(|k| rates.lr_outline_points * if k % 2 == 0 { sx } else { sy }).collect();
        let paint = if args.points_only || solid.is_none() { 0.0 } else { rates.lr_colors };
        steps.extend([paint; 4]);
        let set = |scene: &mut Vec<Outline>, params: &[f32]| {
            let points: Vec<[f32; 2]> = params[..n].chunks_exact(2).map(|p| [p[0], p[1]]).collect();
            let mut outline = scene[0].with_points(&points);
            if solid.is_some() {
                outline.fill = Fill::Solid([params[n], params[n + 1], params[n + 2]]);
            }
            outline.alpha = params[n + 3];
            scene[0] = outline;
        };
        // Adam keeps every value in [0, 1]: the points within the box, colour and opacity.
        let mut adam = FlatAdam::new(params.len());
        let mut best = (f64::INFINITY, params.clone());
        for _ in 0..args.steps {
            set(&mut scene, &params);
            let (loss, gradients) = window.l2_gradient_outlines(&scene);
            if loss < best.0 {
                best = (loss, params.clone());
            }
            let g = &gradients[0];
            let mut flat: Vec<f32> = g.points.iter().flatten().copied().collect();
            flat.extend(g.color);
            flat.push(g.alpha);
            adam.step(&steps, &mut params, &flat);
        }
        set(&mut scene, &params);
        if window.l2_outlines(&scene) < best.0 {
            best.1 = params.clone();
        }
        let chosen: Vec<f32> = start.iter().zip(&best.1).map(|(s, b)| s + args.damping * (b - s)).collect();
        set(&mut scene, &chosen);
        mapped(&scene[0], |p| [(p[0] + ox) / sx, (p[1] + oy) / sy])
    }
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

/// `outline` with its points and a ramp's ends mapped by `f` (its fill and opacity kept).
fn mapped(outline: &Outline, f: impl Fn([f32; 2]) -> [f32; 2]) -> Outline {
    let points: Vec<[f32; 2]> = outline.points().into_iter().map(&f).collect();
    let mut moved = outline.with_points(&points);
    if let Fill::Linear(mut ramp) = outline.fill {
        (ramp.start, ramp.end) = (f(ramp.start), f(ramp.end));
        moved.fill = Fill::Linear(ramp);
    }
    moved
}
