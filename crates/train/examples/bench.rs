//! Training-step throughput of a coarse config: the real loop (data workers, objective, backward,
//! AdamW) timed per phase.
//!
//! `cargo run --release -p train --example bench -- --config configs/coarse.toml [--steps 20]
//!  [--warmup 3] [--backend flex]`
//!
//! Prints one line per phase, then, last, one JSON line: `samples_per_s`, `seconds_per_step`
//! (medians over the timed steps) and `split`, the median seconds of each phase (`data` is the
//! time spent waiting for the next batch).

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use burn::optim::GradientsParams;
use clap::Parser;
use model::CoarseModel;
use raster::Backend;
use train::adamw;
use train::config::{self, CoarseConfig};
use train::{CoarseObjective, Objective};
use train::{DataSource, Loader};

/// Time training steps of a coarse config.
#[derive(Parser, Debug)]
struct Args {
    /// The TOML config file.
    #[arg(long)]
    config: PathBuf,
    /// Timed steps.
    #[arg(long, default_value_t = 20)]
    steps: usize,
    /// Steps run first and not timed.
    #[arg(long, default_value_t = 3)]
    warmup: usize,
    /// Compute backend: flex, ndarray or wgpu.
    #[arg(long, default_value = "flex")]
    backend: Backend,
}

fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = Args::parse();
    let config: CoarseConfig = config::load(&args.config)?;
    let device = args.backend.autodiff_device()?;
    device.seed(config.train.seed);
    let model_config = config.model.0.clone();
    let mut model = CoarseModel::new(&model_config, &device);
    let objective = CoarseObjective::new(&config);
    let mut optimizer = adamw(&config.train);
    let source =
        Arc::new(DataSource::new(&config.data, &model_config, config.train.batch_size, config.train.seed)?);
    let mut loader = Loader::start(source, 0, config.data.workers, config.data.prefetch);

    let mut phases: BTreeMap<&'static str, Vec<f64>> = BTreeMap::new();
    let mut totals = Vec::new();
    for step in 0..args.warmup + args.steps {
        let started = Instant::now();
        let batch = loader.next_batch()?;
        let data = started.elapsed().as_secs_f64();
        let output = objective.step(&model, &batch.tensors(&device), step);
        let backward_started = Instant::now();
        let grads = GradientsParams::from_grads(output.total.backward(), &model);
        let backward = backward_started.elapsed().as_secs_f64();
        let optimizer_started = Instant::now();
        model = optimizer.step(config.train.lr, model, grads);
        let optimizer_seconds = optimizer_started.elapsed().as_secs_f64();
        if step < args.warmup {
            continue;
        }
        totals.push(started.elapsed().as_secs_f64());
        let step_phases = output.phases.into_iter().chain([
            ("data", data),
            ("backward", backward),
            ("optimizer", optimizer_seconds),
        ]);
        for (name, seconds) in step_phases {
            phases.entry(name).or_default().push(seconds);
        }
    }
    let per_step = median(&mut totals);
    let split: BTreeMap<&str, f64> =
        phases.iter_mut().map(|(name, values)| (*name, median(values))).collect();
    for (name, seconds) in &split {
        println!("{name:>10}: {:7.1} ms ({:4.1} %)", seconds * 1e3, 100.0 * seconds / per_step);
    }
    let report = serde_json::json!({
        "config": args.config.display().to_string(),
        "backend": args.backend.to_string(),
        "batch_size": config.train.batch_size,
        "steps": args.steps,
        "seconds_per_step": per_step,
        "samples_per_s": config.train.batch_size as f64 / per_step,
        "split": split,
    });
    println!("{report}");
    Ok(())
}
