//! Times forward + backward of `render_soft` followed by an L2 loss against a random target, or
//! (`--rasterizer exact`) the same loss and gradient from [`raster::Window`] on the CPU, one
//! window per batch entry.
//!
//! `cargo run --release -p raster --example bench -- --backend flex --batch 16 --paths 32 --size 64 --samples 4`
//! `cargo run --release -p raster --example bench -- --rasterizer exact --batch 16 --paths 32 --size 64`
//!
//! Prints one line per timed run, then, last, one JSON object with the median and the peak
//! resident memory of the process.

use std::time::Instant;

use burn::tensor::{Distribution, Tensor};
use rand::Rng;
use rand::SeedableRng;
use raster::{Backend, PathBatch, SoftRasterOptions, Window, random_scene, render_soft};

struct Args {
    backend: Backend,
    exact: bool,
    batch: usize,
    paths: usize,
    size: usize,
    samples: usize,
    runs: usize,
}

fn parse_args() -> Result<Args, String> {
    let mut args =
        Args { backend: Backend::Flex, exact: false, batch: 16, paths: 32, size: 64, samples: 4, runs: 7 };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let value = it.next().ok_or_else(|| format!("{flag} needs a value"))?;
        let number = || value.parse::<usize>().map_err(|_| format!("{flag}: `{value}` is not a count"));
        match flag.as_str() {
            "--backend" => args.backend = value.parse().map_err(|e| format!("{e}"))?,
            "--rasterizer" => {
                args.exact = match value.as_str() {
                    "soft" => false,
                    "exact" => true,
                    _ => return Err(format!("--rasterizer: `{value}` is not soft or exact")),
                }
            }
            "--batch" => args.batch = number()?,
            "--paths" => args.paths = number()?,
            "--size" => args.size = number()?,
            "--samples" => args.samples = number()?,
            "--runs" => args.runs = number()?,
            _ => return Err(format!("unknown flag {flag}")),
        }
    }
    Ok(args)
}

/// Peak resident set size of this process in MiB (Linux), 0 where unknown.
fn peak_rss_mb() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|status| {
            let line = status.lines().find(|line| line.starts_with("VmHWM:"))?;
            line.split_whitespace().nth(1)?.parse::<f64>().ok()
        })
        .map_or(0.0, |kib| kib / 1024.0)
}

fn main() {
    let args = parse_args().unwrap_or_else(|err| {
        eprintln!("error: {err}");
        std::process::exit(2);
    });
    let device = args.backend.autodiff_device().unwrap_or_else(|err| {
        eprintln!("error: {err}");
        std::process::exit(1);
    });
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    let scenes: Vec<_> = (0..args.batch).map(|_| random_scene(&mut rng, args.paths)).collect();
    let params = PathBatch::from_scenes(&scenes, &device).into_params();
    let target = Tensor::<4>::random([args.batch, 3, args.size, args.size], Distribution::Default, &device);
    let options = SoftRasterOptions { segments_per_curve: args.samples, ..Default::default() };

    let pixels = 3 * args.size * args.size;
    let windows: Vec<Window> = (0..args.batch)
        .map(|_| {
            let target = (0..pixels).map(|_| rng.random()).collect();
            Window::new(args.size as u32, args.size as u32, vec![1.0; pixels], target)
                .expect("a non-empty window")
        })
        .collect();

    let mut times = Vec::new();
    for run in 0..args.runs + 2 {
        let start = Instant::now();
        if args.exact {
            let _: f64 = windows.iter().zip(&scenes).map(|(window, scene)| window.l2_gradient(scene).0).sum();
            let ms = start.elapsed().as_secs_f64() * 1e3;
            if run >= 2 {
                println!("run {}: {ms:.1} ms", run - 1);
                times.push(ms);
            }
            continue;
        }
        let params = params.clone().detach().require_grad();
        let image = render_soft(&PathBatch::new(params.clone()), args.size, args.size, &options);
        let loss = (image - target.clone()).square().mean();
        let grads = loss.backward();
        let grad = params.grad(&grads).expect("parameters receive a gradient");
        let _: f32 = grad.sum().into_scalar();
        let ms = start.elapsed().as_secs_f64() * 1e3;
        if run >= 2 {
            println!("run {}: {ms:.1} ms", run - 1);
            times.push(ms);
        }
    }
    times.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    println!(
        "{{\"rasterizer\":\"{}\",\"backend\":\"{}\",\"batch\":{},\"paths\":{},\"size\":{},\"samples\":{},\"median_ms\":{median:.1},\"peak_rss_mb\":{:.0}}}",
        if args.exact { "exact" } else { "soft" },
        args.backend,
        args.batch,
        args.paths,
        args.size,
        args.samples,
        peak_rss_mb()
    );
}
