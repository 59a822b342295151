//! The size of both networks for a preset, to compare with the reference (ViT-S/16 E_c).
//!
//! `cargo run --release -p model --example summary -- --preset paper` prints, last, one JSON
//! line: `{"preset":"paper","coarse_params":N,"refine_params":M,...}`.

use burn::module::Module;
use burn::tensor::Device;
use model::{CoarseModel, ModelConfig, Preset, RefineModel};

fn main() {
    if let Err(message) = run() {
        eprintln!("summary: {message}");
        std::process::exit(2);
    }
}

fn run() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let name = match args.as_slice() {
        [] => "cpu".to_string(),
        [flag, value] if flag == "--preset" => value.clone(),
        _ => return Err("usage: summary [--preset paper|cpu]".into()),
    };
    let preset: Preset = serde_json::from_value(serde_json::Value::String(name.clone()))
        .map_err(|_| format!("unknown preset {name:?} (paper or cpu)"))?;
    let config = ModelConfig::preset(preset);
    let device = Device::flex();
    let coarse = CoarseModel::new(&config, &device).num_params();
    let refine = RefineModel::new(&config, &device).num_params();
    let line = serde_json::json!({
        "preset": name,
        "coarse_params": coarse,
        "refine_params": refine,
        "input_size": config.input_size,
        "embed_dim": config.embed_dim,
        "depth": config.depth,
        "paths": config.paths,
        "refine_paths": config.refine_paths,
    });
    println!("{line}");
    Ok(())
}
