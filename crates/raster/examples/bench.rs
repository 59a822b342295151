//! Times forward + backward of `render_soft` followed by an L2 loss against a random target.
//!
//! `cargo run --release -p raster --example bench -- --backend flex --batch 16 --paths 32 --size 64 --samples 4`
//!
//! Prints one line per timed run, then, last, one JSON object with the median and the peak
//! resident memory of the process.

use std::time::Instant;

use burn::tensor::{Distribution, Tensor};
use rand::SeedableRng;
use raster::{Backend, PathBatch, SoftRasterOptions, random_scene, render_soft};

struct Args {
    backend: Backend,
    batch: usize,
    paths: usize,
    size: usize,
    samples: usize,
    runs: usize,
}

fn parse_args() -> Result<Args, String> {
    let mut args = Args { backend: Backend::Flex, batch: 16, paths: 32, size: 64, samples: 4, runs: 7 };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let value = it.next().ok_or_else(|| format!("{flag} needs a value"))?;
        let number = || value.parse::<usize>().map_err(|_| format!("{flag}: `{value}` is not a count"));
        match flag.as_str() {
            "--backend" => args.backend = value.parse().map_err(|e| format!("{e}"))?,
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

    let mut times = Vec::new();
    for run in 0..args.runs + 2 {
        let start = Instant::now();
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
        "{{\"backend\":\"{}\",\"batch\":{},\"paths\":{},\"size\":{},\"samples\":{},\"median_ms\":{median:.1},\"peak_rss_mb\":{:.0}}}",
        args.backend,
        args.batch,
        args.paths,
        args.size,
        args.samples,
        peak_rss_mb()
    );
}
