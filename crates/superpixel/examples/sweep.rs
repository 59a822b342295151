//! How a region recipe draws a folder of images with flat fills, and what it costs: for each
//! region count and recipe, the mean PSNR of every region filled with its mean colour (what the
//! regions alone can draw) and the mean seconds to segment, over every image that decodes.
//!
//! `cargo run --release -p superpixel --example sweep -- DIR [--regions 500,2000] [--size 512]
//!  [--recipe OVERSEGMENT,ITERATIONS,COMPACTNESS,SIGMA,KEEP ...]`
//!
//! A recipe is SLIC for OVERSEGMENT × the regions, at most ITERATIONS rounds, at COMPACTNESS,
//! smoothed by SIGMA, its fragments kept (KEEP 1) or joined to their left neighbours (0), then
//! merged by colour to the count. Without `--recipe`, `SegmentOptions::ward(30)` and the recipe
//! it replaced (64, 10, 10, 1, 0). One line per (count, recipe), then, last, one JSON line.

use std::path::PathBuf;
use std::time::Instant;

use common::decode::load;
use common::folder::files_in;
use superpixel::{SegmentOptions, segment};

fn main() {
    let mut args = std::env::args().skip(1);
    let (mut dir, mut regions, mut size, mut recipes) = (None, vec![500, 2000], 512u32, Vec::new());
    while let Some(arg) = args.next() {
        let mut value = || args.next().unwrap_or_else(|| fail(&format!("{arg} needs a value")));
        match arg.as_str() {
            "--regions" => regions = numbers(&value(), "--regions"),
            "--size" => size = value().parse().unwrap_or_else(|_| fail("--size: not a number")),
            "--recipe" => recipes.push(recipe(&value())),
            flag if flag.starts_with("--") => fail(&format!("unknown flag {flag}")),
            _ => dir = Some(PathBuf::from(arg)),
        }
    }
    let dir =
        dir.unwrap_or_else(|| fail("usage: sweep DIR [--regions N,…] [--size PX] [--recipe O,I,C,S,K …]"));
    if recipes.is_empty() {
        let replaced = SegmentOptions { compactness: 10.0, oversegment: 64.0, ..SegmentOptions::default() };
        recipes = vec![SegmentOptions::ward(30.0), replaced];
    }
    let files = files_in(&dir).unwrap_or_else(|err| fail(&err.to_string()));
    let images: Vec<_> = files.iter().filter_map(|path| load(path, size).ok()).map(|l| l.image).collect();
    if images.is_empty() {
        fail(&format!("{}: no image decodes", dir.display()));
    }
    let mut rows = Vec::new();
    for &count in &regions {
        for options in &recipes {
            let (mut psnr, mut seconds) = (0.0, 0.0);
            for image in &images {
                let started = Instant::now();
                let segmentation =
                    segment(image, count, options).unwrap_or_else(|err| fail(&err.to_string()));
                seconds += started.elapsed().as_secs_f64();
                let values = 3.0 * image.width() as f64 * image.height() as f64;
                psnr += common::psnr_of_mse(segmentation.flat_error(image) / values);
            }
            let n = images.len() as f64;
            let SegmentOptions {
                oversegment,
                iterations,
                compactness,
                sigma,
                keep_fragments,
                flat_areas,
                ..
            } = options;
            let areas = if *flat_areas { " from flat areas" } else { "" };
            let name = format!(
                "{oversegment},{iterations},{compactness},{sigma},{}{areas}",
                u8::from(*keep_fragments)
            );
            println!("{count} regions, recipe {name}: {:.3} dB, {:.1} ms", psnr / n, seconds / n * 1e3);
            rows.push(format!(
                "{{\"regions\":{count},\"recipe\":\"{name}\",\"psnr\":{:.4},\"seconds\":{:.4}}}",
                psnr / n,
                seconds / n
            ));
        }
    }
    println!("{{\"images\":{},\"rows\":[{}]}}", images.len(), rows.join(","));
}

/// `O,I,C,S,K` as a recipe (no compactness floor: merged freely, as `ward` merges; always from
/// SLIC, never from flat areas).
fn recipe(text: &str) -> SegmentOptions {
    let values: Vec<f32> = numbers(text, "--recipe");
    let [oversegment, iterations, compactness, sigma, keep] = values[..] else {
        fail("--recipe: five numbers, OVERSEGMENT,ITERATIONS,COMPACTNESS,SIGMA,KEEP")
    };
    SegmentOptions {
        compactness,
        oversegment,
        min_compactness: 0.0,
        sigma,
        iterations: iterations as usize,
        keep_fragments: keep != 0.0,
        flat_areas: false,
    }
}

fn numbers<T: std::str::FromStr>(text: &str, flag: &str) -> Vec<T> {
    text.split(',')
        .map(|v| v.parse().unwrap_or_else(|_| fail(&format!("{flag}: {v:?} is not a number"))))
        .collect()
}

fn fail(message: &str) -> ! {
    eprintln!("error: {message}");
    std::process::exit(2);
}
