//! Times SLIC on an image file.
//!
//! `cargo run --release -p superpixel --example bench -- IMAGE --segments 256 --compactness 30`
//!
//! Prints one line per timed run, then, last, one JSON object with the median.

use std::time::Instant;

use common::decode::{LoadOptions, open};
use superpixel::{SlicOptions, slic};

fn main() {
    let mut args = std::env::args().skip(1);
    let mut image_path = None;
    let mut options = SlicOptions { n_segments: 256, ..Default::default() };
    let mut runs = 7usize;
    while let Some(arg) = args.next() {
        let mut value = || args.next().unwrap_or_else(|| fail(&format!("{arg} needs a value")));
        match arg.as_str() {
            "--segments" => {
                options.n_segments = value().parse().unwrap_or_else(|_| fail("--segments: not a count"))
            }
            "--compactness" => {
                options.compactness = value().parse().unwrap_or_else(|_| fail("--compactness: not a number"))
            }
            "--runs" => runs = value().parse().unwrap_or_else(|_| fail("--runs: not a count")),
            flag if flag.starts_with("--") => fail(&format!("unknown flag {flag}")),
            _ => image_path = Some(arg),
        }
    }
    let path =
        image_path.unwrap_or_else(|| fail("usage: bench IMAGE [--segments N] [--compactness C] [--runs R]"));
    // At the file's own size: SLIC is timed on the pixels it is given.
    let options_full = LoadOptions { long_side: u32::MAX, ..LoadOptions::default() };
    let image =
        open(std::path::Path::new(&path), &options_full).unwrap_or_else(|err| fail(&err.to_string())).image;
    let mut times = Vec::new();
    let mut segments = 0;
    for run in 0..runs + 1 {
        let start = Instant::now();
        let segmentation = slic(&image, &options).unwrap_or_else(|err| fail(&format!("{path}: {err}")));
        let ms = start.elapsed().as_secs_f64() * 1e3;
        segments = segmentation.regions.len();
        if run > 0 {
            println!("run {run}: {ms:.1} ms, {segments} regions");
            times.push(ms);
        }
    }
    times.sort_by(f64::total_cmp);
    println!(
        "{{\"median_ms\":{:.1},\"segments\":{segments},\"width\":{},\"height\":{}}}",
        times[times.len() / 2],
        image.width(),
        image.height()
    );
}

fn fail(message: &str) -> ! {
    eprintln!("error: {message}");
    std::process::exit(2);
}
