//! Our curve fitting ([`raster::fit_curve`], what `infer --tolerance` draws boundaries with)
//! beside linebender's `kurbo` (`simplify_bezpath`, its fitter for polylines) on what tracing
//! hands the fitter: staircase outlines along pixel edges, of rotated ellipses of 4 to 60 pixels.
//! For each tolerance it prints, per fitter, the median time an outline, the pieces (lines and
//! cubics) it draws the outlines with, and how far the curve strays from the staircase's
//! midpoints (the smooth shape a tracer should follow; mean and worst, in pixels).
//!
//! `cargo run --release -p raster --example kurbo -- --outlines 400 --runs 5`

use std::time::Instant;

use kurbo::simplify::{SimplifyOptions, simplify_bezpath};
use kurbo::{BezPath, ParamCurve, PathSeg, Point};
use rand::{Rng, SeedableRng};
use raster::{Segment, fit_curve};

fn main() {
    let mut outlines = 400;
    let mut runs = 5;
    let mut args = std::env::args().skip(1);
    while let Some(flag) = args.next() {
        let value = args.next().and_then(|v| v.parse::<usize>().ok());
        match (flag.as_str(), value) {
            ("--outlines", Some(n)) if n > 0 => outlines = n,
            ("--runs", Some(n)) if n > 0 => runs = n,
            _ => {
                eprintln!("usage: kurbo [--outlines N] [--runs N] (counts above 0)");
                std::process::exit(2);
            }
        }
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let shapes: Vec<Vec<[f32; 2]>> = (0..outlines).map(|_| staircase_ellipse(&mut rng)).collect();
    println!("{outlines} staircase outlines, {runs} runs; time is the median a run, per outline");
    println!("| tolerance | fitter | µs an outline | pieces | strays, mean / worst (px) |");
    println!("| ---: | --- | ---: | ---: | ---: |");
    for tolerance in [0.5f32, 1.0, 2.0] {
        let ours = |points: &[[f32; 2]]| -> Vec<[[f64; 2]; 4]> {
            let (start, segments) = fit_curve(points, true, tolerance);
            cubics(start, &segments)
        };
        let theirs = |points: &[[f32; 2]]| -> Vec<[[f64; 2]; 4]> {
            let mut path = BezPath::new();
            path.move_to(point(points[0]));
            for &p in &points[1..] {
                path.line_to(point(p));
            }
            path.close_path();
            let fitted = simplify_bezpath(path, f64::from(tolerance), &SimplifyOptions::default());
            fitted.segments().map(as_cubic).collect()
        };
        report(tolerance, "supersvg fit_curve", &shapes, runs, ours);
        report(tolerance, "kurbo simplify_bezpath", &shapes, runs, theirs);
    }
}

/// Times `fit` over every outline `runs` times and prints its row.
fn report(
    tolerance: f32,
    name: &str,
    shapes: &[Vec<[f32; 2]>],
    runs: usize,
    fit: impl Fn(&[[f32; 2]]) -> Vec<[[f64; 2]; 4]>,
) {
    let mut times: Vec<f64> = (0..runs)
        .map(|_| {
            let start = Instant::now();
            for shape in shapes {
                std::hint::black_box(fit(shape));
            }
            start.elapsed().as_secs_f64()
        })
        .collect();
    times.sort_by(f64::total_cmp);
    let mut pieces = 0;
    let (mut sum, mut count, mut worst) = (0.0, 0usize, 0.0f64);
    for shape in shapes {
        let curve = fit(shape);
        pieces += curve.len();
        let dense: Vec<[f64; 2]> =
            curve.iter().flat_map(|c| (0..32).map(move |i| cubic_at(c, i as f64 / 32.0))).collect();
        for mid in midpoints(shape) {
            let d = dense.iter().map(|q| (q[0] - mid[0]).hypot(q[1] - mid[1])).fold(f64::INFINITY, f64::min);
            (sum, count, worst) = (sum + d, count + 1, worst.max(d));
        }
    }
    let micros = times[runs / 2] / shapes.len() as f64 * 1e6;
    println!("| {tolerance} | {name} | {micros:.1} | {pieces} | {:.2} / {:.2} |", sum / count as f64, worst);
}

/// The outline a pixel tracer draws around a rotated ellipse: its pixel centres inside, walked
/// as horizontal and vertical unit steps (a closed polyline, first point not repeated).
fn staircase_ellipse(rng: &mut impl Rng) -> Vec<[f32; 2]> {
    let (a, b) = (rng.random_range(4.0..60.0f32), rng.random_range(4.0..60.0f32));
    let angle = rng.random_range(0.0..std::f32::consts::PI);
    let (sin, cos) = angle.sin_cos();
    // Around the ellipse in small angle steps, each point rounded to the pixel grid, then every
    // diagonal move split into a horizontal and a vertical one.
    let steps = (8.0 * (a + b)) as usize;
    let mut corners: Vec<[i32; 2]> = Vec::new();
    for i in 0..steps {
        let t = i as f32 / steps as f32 * std::f32::consts::TAU;
        let (x, y) = (a * t.cos(), b * t.sin());
        let p = [(x * cos - y * sin + 100.0).round() as i32, (x * sin + y * cos + 100.0).round() as i32];
        let Some(&last) = corners.last() else {
            corners.push(p);
            continue;
        };
        let mut q = last;
        while q != p {
            if q[0] != p[0] {
                q[0] += (p[0] - q[0]).signum();
            } else {
                q[1] += (p[1] - q[1]).signum();
            }
            corners.push(q);
        }
    }
    corners.dedup();
    while corners.len() > 1 && corners.first() == corners.last() {
        corners.pop();
    }
    corners.iter().map(|&[x, y]| [x as f32, y as f32]).collect()
}

/// The midpoints of a closed polyline's edges: a staircase's smooth centre line.
fn midpoints(points: &[[f32; 2]]) -> Vec<[f64; 2]> {
    (0..points.len())
        .map(|i| {
            let (p, q) = (points[i], points[(i + 1) % points.len()]);
            [f64::from(p[0] + q[0]) / 2.0, f64::from(p[1] + q[1]) / 2.0]
        })
        .collect()
}

/// Our fitted pieces as cubics (a line as a straight cubic).
fn cubics(start: [f32; 2], segments: &[Segment]) -> Vec<[[f64; 2]; 4]> {
    let f = |p: [f32; 2]| [f64::from(p[0]), f64::from(p[1])];
    let mut from = f(start);
    segments
        .iter()
        .map(|segment| {
            let cubic = match *segment {
                Segment::Line(to) => {
                    let to = f(to);
                    [from, lerp(from, to, 1.0 / 3.0), lerp(from, to, 2.0 / 3.0), to]
                }
                Segment::Cubic(c1, c2, to) => [from, f(c1), f(c2), f(to)],
            };
            from = cubic[3];
            cubic
        })
        .collect()
}

fn as_cubic(segment: PathSeg) -> [[f64; 2]; 4] {
    let c = segment.to_cubic();
    let p = |p: Point| [p.x, p.y];
    [p(c.p0), p(c.p1), p(c.p2), p(c.p3)]
}

fn point(p: [f32; 2]) -> Point {
    Point::new(f64::from(p[0]), f64::from(p[1]))
}

fn lerp(a: [f64; 2], b: [f64; 2], t: f64) -> [f64; 2] {
    [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t]
}

fn cubic_at(c: &[[f64; 2]; 4], t: f64) -> [f64; 2] {
    let cubic = kurbo::CubicBez::new(
        Point::new(c[0][0], c[0][1]),
        Point::new(c[1][0], c[1][1]),
        Point::new(c[2][0], c[2][1]),
        Point::new(c[3][0], c[3][1]),
    );
    let p = cubic.eval(t);
    [p.x, p.y]
}
