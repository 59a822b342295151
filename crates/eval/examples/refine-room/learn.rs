//! A small network that predicts each outline point's optimum move along its normal from the
//! image and the drawing around it: how much of the one-pass room a learned model takes.
//! Plain Rust (a two-layer perceptron, its gradient and Adam written out), so that the
//! question is answered in a minute; a network meant to ship would be a burn module trained by
//! crates/train.

use std::path::Path;

use burn::tensor::Device;
use common::decode::load;
use image::Rgb32FImage;
use infer::{FinetuneOptions, Job, Models, PathBudget, Scene, run};
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use raster::{Outline, Segment, Shape};
use rayon::prelude::*;

use crate::{Args, Room};

/// Where the profile is sampled along a point's normal, in pixels.
const OFFSETS: [f32; 17] =
    [-4.0, -3.5, -3.0, -2.5, -2.0, -1.5, -1.0, -0.5, 0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0];
/// The target's and the canvas's RGB at each offset.
const FEATURES: usize = 6 * OFFSETS.len();
/// Hidden units of each of the two hidden layers.
const HIDDEN: usize = 32;
/// The largest move learned or applied, in pixels.
const MAX_MOVE: f32 = 4.0;

/// Two hidden ReLU layers and one output: the move along the normal, in pixels.
pub struct Mlp {
    w1: Vec<f32>,
    b1: Vec<f32>,
    w2: Vec<f32>,
    b2: Vec<f32>,
    w3: Vec<f32>,
    b3: f32,
}

impl Mlp {
    fn new(rng: &mut ChaCha8Rng) -> Self {
        use rand::Rng;
        let mut init = |n: usize, fan_in: usize| -> Vec<f32> {
            let scale = (2.0 / fan_in as f32).sqrt();
            (0..n).map(|_| (rng.random::<f32>() * 2.0 - 1.0) * scale * 3f32.sqrt() / 2.0).collect()
        };
        Self {
            w1: init(HIDDEN * FEATURES, FEATURES),
            b1: vec![0.0; HIDDEN],
            w2: init(HIDDEN * HIDDEN, HIDDEN),
            b2: vec![0.0; HIDDEN],
            w3: init(HIDDEN, HIDDEN),
            b3: 0.0,
        }
    }

    fn forward(&self, x: &[f32]) -> ([f32; HIDDEN], [f32; HIDDEN], f32) {
        let mut h1 = [0.0; HIDDEN];
        for (j, h) in h1.iter_mut().enumerate() {
            let row = &self.w1[j * FEATURES..(j + 1) * FEATURES];
            *h = (dot(row, x) + self.b1[j]).max(0.0);
        }
        let mut h2 = [0.0; HIDDEN];
        for (j, h) in h2.iter_mut().enumerate() {
            let row = &self.w2[j * HIDDEN..(j + 1) * HIDDEN];
            *h = (dot(row, &h1) + self.b2[j]).max(0.0);
        }
        let y = dot(&self.w3, &h2) + self.b3;
        (h1, h2, y)
    }

    fn predict(&self, x: &[f32]) -> f32 {
        self.forward(x).2.clamp(-MAX_MOVE, MAX_MOVE)
    }

    fn params(&mut self) -> [&mut [f32]; 6] {
        [
            &mut self.w1,
            &mut self.b1,
            &mut self.w2,
            &mut self.b2,
            &mut self.w3,
            std::slice::from_mut(&mut self.b3),
        ]
    }
}

/// `a · b` summed in eight lanes, which the compiler keeps in vector registers.
fn dot(a: &[f32], b: &[f32]) -> f32 {
    let mut lanes = [0.0f32; 8];
    let (a8, b8) = (a.chunks_exact(8), b.chunks_exact(8));
    let tail: f32 = a8.remainder().iter().zip(b8.remainder()).map(|(x, y)| x * y).sum();
    for (x, y) in a8.zip(b8) {
        for k in 0..8 {
            lanes[k] += x[k] * y[k];
        }
    }
    lanes.iter().sum::<f32>() + tail
}

/// One sample: a point's profile and its optimum move along the normal.
struct Sample {
    x: [f32; FEATURES],
    y: f32,
}

/// Each point of `outline` (in [`Outline::points`]' order) in pixels, with its unit normal (zero
/// where its neighbours coincide).
fn frames(outline: &Outline, (w, h): (f32, f32)) -> Vec<([f32; 2], [f32; 2])> {
    let points: Vec<[f32; 2]> = outline.points().iter().map(|p| [p[0] * w, p[1] * h]).collect();
    let mut frames = Vec::with_capacity(points.len());
    let mut at = 0;
    for contour in outline.contours() {
        let count: usize = (contour.segments.iter())
            .map(|segment| match segment {
                Segment::Line(_) => 1,
                Segment::Cubic(..) => 3,
            })
            .sum();
        let slice = &points[at..at + count];
        for (j, &p) in slice.iter().enumerate() {
            let (prev, next) = (slice[(j + count - 1) % count], slice[(j + 1) % count]);
            let (tx, ty) = (next[0] - prev[0], next[1] - prev[1]);
            let length = tx.hypot(ty);
            let normal = if length > 1e-6 { [-ty / length, tx / length] } else { [0.0; 2] };
            frames.push((p, normal));
        }
        at += count;
    }
    frames
}

/// `image` at pixel position (x, y), bilinear between pixel centres, clamped at the edges.
fn sample(image: &Rgb32FImage, x: f32, y: f32) -> [f32; 3] {
    let (w, h) = image.dimensions();
    let (u, v) = ((x - 0.5).clamp(0.0, w as f32 - 1.0), (y - 0.5).clamp(0.0, h as f32 - 1.0));
    let (x0, y0) = (u.floor() as u32, v.floor() as u32);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (fx, fy) = (u - x0 as f32, v - y0 as f32);
    let p = |x, y| image.get_pixel(x, y).0;
    let (a, b, c, d) = (p(x0, y0), p(x1, y0), p(x0, y1), p(x1, y1));
    std::array::from_fn(|k| {
        (a[k] * (1.0 - fx) + b[k] * fx) * (1.0 - fy) + (c[k] * (1.0 - fx) + d[k] * fx) * fy
    })
}

/// A point's profile: the target's and the canvas's RGB along its normal, less the canvas's
/// colour at the point.
fn features(target: &Rgb32FImage, canvas: &Rgb32FImage, p: [f32; 2], n: [f32; 2]) -> [f32; FEATURES] {
    let centre = sample(canvas, p[0], p[1]);
    let mut x = [0.0; FEATURES];
    for (k, s) in OFFSETS.iter().enumerate() {
        let (qx, qy) = (p[0] + s * n[0], p[1] + s * n[1]);
        let (t, c) = (sample(target, qx, qy), sample(canvas, qx, qy));
        for ch in 0..3 {
            x[6 * k + ch] = t[ch] - centre[ch];
            x[6 * k + 3 + ch] = c[ch] - centre[ch];
        }
    }
    x
}

/// The optimum moves of every point of B's drawings of the images in `folder`, learned: the
/// drawings as `before` leaves them (one pass of each network in turn), so that the network
/// learned is the next pass.
pub fn train(
    folder: &Path,
    before: &[Mlp],
    args: &Args,
    models: &Models,
    device: &Device,
    rates: &FinetuneOptions,
) -> Result<Mlp, Box<dyn std::error::Error>> {
    let mut files: Vec<_> =
        std::fs::read_dir(folder)?.map(|e| e.map(|e| e.path())).collect::<Result<_, _>>()?;
    files.sort();
    let mut samples = Vec::new();
    for file in &files {
        let loaded = load(file, 512)?;
        let job = Job { paths: PathBudget::Count(args.paths), fills: args.fills, ..Job::default() };
        let drawn = run(models, &loaded, &job, device)?;
        let room = Room::of(&drawn.scene);
        let (mut drawing, mut start) = (drawn.scene.clone(), room.start(&drawn.scene));
        for mlp in before {
            start = pass(mlp, &drawing, &start);
            drawing.set_shapes(&start.iter().cloned().map(Shape::from).collect::<Vec<_>>());
        }
        let moved = room.pass(&start, args, rates);
        let count = samples.len();
        collect(&drawing, &start, &moved, &mut samples);
        eprintln!("{}: {} points", file.display(), samples.len() - count);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(54);
    samples.shuffle(&mut rng);
    let held = samples.len() / 10;
    let (held, learn) = samples.split_at(held);
    let mut mlp = Mlp::new(&mut rng);
    let mut adam = Adam::new(&mut mlp);
    let mut order: Vec<usize> = (0..learn.len()).collect();
    for epoch in 0..args.epochs {
        order.shuffle(&mut rng);
        for batch in order.chunks(256) {
            let grads = gradients(&mlp, batch.iter().map(|&i| &learn[i]));
            adam.step(&mut mlp, &grads, 1e-3);
        }
        let mse = |set: &[Sample], f: &dyn Fn(&Sample) -> f32| {
            set.iter().map(|s| f64::from((f(s) - s.y).powi(2))).sum::<f64>() / set.len() as f64
        };
        eprintln!(
            "epoch {epoch}: held-out mse {:.4} (moving nothing: {:.4})",
            mse(held, &|s| mlp.predict(&s.x)),
            mse(held, &|_| 0.0)
        );
    }
    Ok(mlp)
}

/// The samples of one drawing: each point of each outline, and how far the optimum moved it
/// along its normal.
fn collect(scene: &Scene, start: &[Outline], moved: &[Outline], samples: &mut Vec<Sample>) {
    let target = scene.target();
    let canvas = scene.canvas_image();
    let size = (target.width() as f32, target.height() as f32);
    for (before, after) in start.iter().zip(moved) {
        let after: Vec<[f32; 2]> = after.points().iter().map(|p| [p[0] * size.0, p[1] * size.1]).collect();
        for ((p, n), q) in frames(before, size).into_iter().zip(after) {
            if n == [0.0; 2] {
                continue;
            }
            let y = ((q[0] - p[0]) * n[0] + (q[1] - p[1]) * n[1]).clamp(-MAX_MOVE, MAX_MOVE);
            samples.push(Sample { x: features(target, &canvas, p, n), y });
        }
    }
}

/// The network's one pass over a drawing: every point moved along its normal at once.
pub fn pass(mlp: &Mlp, scene: &Scene, outlines: &[Outline]) -> Vec<Outline> {
    let target = scene.target();
    let canvas = scene.canvas_image();
    let size = (target.width() as f32, target.height() as f32);
    outlines
        .par_iter()
        .map(|outline| {
            let points: Vec<[f32; 2]> = frames(outline, size)
                .into_iter()
                .map(|(p, n)| {
                    let d = if n == [0.0; 2] { 0.0 } else { mlp.predict(&features(target, &canvas, p, n)) };
                    [(p[0] + d * n[0]) / size.0, (p[1] + d * n[1]) / size.1]
                })
                .collect();
            outline.with_points(&points)
        })
        .collect()
}

/// The mean gradient of the squared error over `batch`, laid out as [`Mlp::params`].
fn gradients<'a>(mlp: &Mlp, batch: impl Iterator<Item = &'a Sample>) -> Vec<Vec<f32>> {
    let mut g = vec![
        vec![0.0; HIDDEN * FEATURES],
        vec![0.0; HIDDEN],
        vec![0.0; HIDDEN * HIDDEN],
        vec![0.0; HIDDEN],
        vec![0.0; HIDDEN],
        vec![0.0; 1],
    ];
    let mut n = 0;
    for sample in batch {
        n += 1;
        let (h1, h2, y) = mlp.forward(&sample.x);
        let dy = 2.0 * (y - sample.y);
        g[5][0] += dy;
        let mut d2 = [0.0; HIDDEN];
        for j in 0..HIDDEN {
            g[4][j] += dy * h2[j];
            d2[j] = if h2[j] > 0.0 { dy * mlp.w3[j] } else { 0.0 };
        }
        let mut d1 = [0.0; HIDDEN];
        for j in 0..HIDDEN {
            if d2[j] == 0.0 {
                continue;
            }
            g[3][j] += d2[j];
            for k in 0..HIDDEN {
                g[2][j * HIDDEN + k] += d2[j] * h1[k];
                d1[k] += d2[j] * mlp.w2[j * HIDDEN + k];
            }
        }
        for k in 0..HIDDEN {
            if h1[k] <= 0.0 || d1[k] == 0.0 {
                continue;
            }
            g[1][k] += d1[k];
            for (f, x) in sample.x.iter().enumerate() {
                g[0][k * FEATURES + f] += d1[k] * x;
            }
        }
    }
    for values in &mut g {
        values.iter_mut().for_each(|v| *v /= n.max(1) as f32);
    }
    g
}

/// Adam's moments of every parameter: raster's `FlatAdam` keeps values in [0, 1], which
/// weights are not.
struct Adam {
    moments: Vec<Vec<(f32, f32)>>,
    steps: i32,
}

impl Adam {
    fn new(mlp: &mut Mlp) -> Self {
        Self { moments: mlp.params().iter().map(|p| vec![(0.0, 0.0); p.len()]).collect(), steps: 0 }
    }

    fn step(&mut self, mlp: &mut Mlp, grads: &[Vec<f32>], rate: f32) {
        self.steps += 1;
        let (b1, b2) = (0.9f32, 0.999f32);
        let (c1, c2) = (1.0 - b1.powi(self.steps), 1.0 - b2.powi(self.steps));
        for ((params, moments), grads) in mlp.params().into_iter().zip(&mut self.moments).zip(grads) {
            for ((p, (m, v)), g) in params.iter_mut().zip(moments.iter_mut()).zip(grads) {
                *m = b1 * *m + (1.0 - b1) * g;
                *v = b2 * *v + (1.0 - b2) * g * g;
                *p -= rate * (*m / c1) / ((*v / c2).sqrt() + 1e-8);
            }
        }
    }
}

/// `outline` with each all-straight contour simplified (Douglas–Peucker, `tolerance` pixels of
/// a `size` canvas); contours with cubics are kept.
pub fn simplified(outline: &Outline, tolerance: f32, (w, h): (f32, f32)) -> Outline {
    use raster::Contour;
    let contours: Vec<Contour> = (outline.contours().iter())
        .map(|contour| {
            if contour.segments.iter().any(|s| matches!(s, Segment::Cubic(..))) || contour.segments.len() < 4
            {
                return contour.clone();
            }
            let ring: Vec<[f32; 2]> = std::iter::once(contour.start)
                .chain(contour.segments.iter().map(Segment::end))
                .take(contour.segments.len())
                .map(|p| [p[0] * w, p[1] * h])
                .collect();
            let far = (1..ring.len())
                .max_by(|&a, &b| dist2(ring[0], ring[a]).total_cmp(&dist2(ring[0], ring[b])))
                .unwrap_or(1);
            let mut keep = vec![false; ring.len()];
            keep[0] = true;
            keep[far] = true;
            let closed: Vec<[f32; 2]> = ring.iter().copied().chain(std::iter::once(ring[0])).collect();
            mark(&closed, 0, far, tolerance, &mut keep);
            let mut tail = vec![false; closed.len()];
            mark(&closed, far, closed.len() - 1, tolerance, &mut tail);
            for (k, t) in tail.iter().enumerate().take(ring.len()) {
                keep[k] |= t;
            }
            let kept: Vec<[f32; 2]> =
                ring.iter().zip(&keep).filter(|(_, k)| **k).map(|(p, _)| [p[0] / w, p[1] / h]).collect();
            if kept.len() < 3 {
                return contour.clone();
            }
            Contour {
                start: kept[0],
                segments: kept[1..]
                    .iter()
                    .chain(std::iter::once(&kept[0]))
                    .map(|&p| Segment::Line(p))
                    .collect(),
            }
        })
        .collect();
    Outline::new(contours, outline.fill, outline.alpha).unwrap_or_else(|| outline.clone())
}

fn dist2(a: [f32; 2], b: [f32; 2]) -> f32 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)
}

/// Douglas–Peucker between `points[from]` and `points[to]` (kept), marking what else is kept.
fn mark(points: &[[f32; 2]], from: usize, to: usize, tolerance: f32, keep: &mut [bool]) {
    if to <= from + 1 {
        return;
    }
    let (a, b) = (points[from], points[to]);
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let length = dx.hypot(dy);
    let distance = |p: [f32; 2]| {
        if length < 1e-6 {
            dist2(a, p).sqrt()
        } else {
            ((p[0] - a[0]) * dy - (p[1] - a[1]) * dx).abs() / length
        }
    };
    let (worst, d) = (from + 1..to)
        .map(|k| (k, distance(points[k])))
        .fold((from, -1.0), |m, x| if x.1 > m.1 { x } else { m });
    if d > tolerance {
        keep[worst] = true;
        mark(points, from, worst, tolerance, keep);
        mark(points, worst, to, tolerance, keep);
    }
}

impl Mlp {
    /// Its parameters, little-endian f32 in [`Mlp::params`]' order.
    pub fn save(&mut self, file: &Path) -> std::io::Result<()> {
        let bytes: Vec<u8> =
            self.params().iter().flat_map(|p| p.iter().flat_map(|v| v.to_le_bytes())).collect();
        std::fs::write(file, bytes)
    }

    /// The network [`Mlp::save`] wrote to `file`.
    pub fn open(file: &Path) -> std::io::Result<Self> {
        let bytes = std::fs::read(file)?;
        let mut mlp = Self::new(&mut ChaCha8Rng::seed_from_u64(0));
        let count: usize = mlp.params().iter().map(|p| p.len()).sum();
        if bytes.len() != 4 * count {
            let problem =
                format!("{}: {} bytes, not the {} of this network", file.display(), bytes.len(), 4 * count);
            return Err(std::io::Error::other(problem));
        }
        let mut values = bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]));
        for params in mlp.params() {
            params.iter_mut().zip(&mut values).for_each(|(p, v)| *p = v);
        }
        Ok(mlp)
    }
}
