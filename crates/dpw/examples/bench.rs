//! Times forward + backward of the batched DPW between random predictions and targets.
//!
//! `cargo run --release -p dpw --example bench -- --backend flex --batch 64 --targets 120 --preds 8 --dim 27`
//!
//! Prints one line per timed run, then, last, one JSON object with the median.

use std::time::Instant;

use burn::tensor::{Distribution, Tensor};
use dpw::{dpw, pairwise_sq_distance};
use raster::Backend;

fn main() {
    let mut values =
        [("--batch", 64usize), ("--targets", 120), ("--preds", 8), ("--dim", 27), ("--runs", 11)];
    let mut backend = Backend::Flex;
    let mut args = std::env::args().skip(1);
    while let Some(flag) = args.next() {
        let value = args.next().unwrap_or_else(|| fail(&format!("{flag} needs a value")));
        if flag == "--backend" {
            backend = value.parse().unwrap_or_else(|err| fail(&format!("{err}")));
            continue;
        }
        let slot = values
            .iter_mut()
            .find(|(name, _)| *name == flag)
            .unwrap_or_else(|| fail(&format!("unknown flag {flag}")));
        slot.1 = value.parse().unwrap_or_else(|_| fail(&format!("{flag}: `{value}` is not a count")));
    }
    let [batch, targets, preds, dim, runs] = values.map(|(_, v)| v);
    let device = backend.autodiff_device().unwrap_or_else(|err| fail(&err.to_string()));
    let target = Tensor::<3>::random([batch, targets, dim], Distribution::Default, &device);
    let prediction = Tensor::<3>::random([batch, preds, dim], Distribution::Default, &device);

    let mut times = Vec::new();
    for run in 0..runs + 2 {
        let start = Instant::now();
        let p = prediction.clone().detach().require_grad();
        let value = dpw(pairwise_sq_distance(p.clone(), target.clone()), 0.01).mean();
        let grad = p.grad(&value.backward()).expect("predictions receive a gradient");
        let _: f32 = grad.sum().into_scalar();
        let ms = start.elapsed().as_secs_f64() * 1e3;
        if run >= 2 {
            println!("run {}: {ms:.2} ms", run - 1);
            times.push(ms);
        }
    }
    times.sort_by(f64::total_cmp);
    println!(
        "{{\"backend\":\"{backend}\",\"batch\":{batch},\"targets\":{targets},\"preds\":{preds},\"dim\":{dim},\"median_ms\":{:.2}}}",
        times[times.len() / 2]
    );
}

fn fail(message: &str) -> ! {
    eprintln!("error: {message}");
    std::process::exit(2);
}
