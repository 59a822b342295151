//! The error of B's drawings along E_o's steps: `optimizer-probe CONFIG [CHECKPOINT]`.
use std::path::PathBuf;

use burn::tensor::Device;
use infer::learned::LearnedSteps;
use model::{LearnedOptimizer, OptimizerCheckpoint};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let config = train::OptimizerConfig::load(&PathBuf::from(&args[1]))?;
    let device = Device::flex();
    let network = match args.get(2) {
        Some(path) => {
            OptimizerCheckpoint::load(&PathBuf::from(path))?.build(&device, std::path::Path::new(path))?
        }
        None => LearnedOptimizer::new(&device).silenced(),
    };
    let models = infer::Models::bundled(true, &device)?;
    for case in train::Case::all_of(&config.validation, &models, &device)? {
        {
            let mut runner = LearnedSteps::new(case.movable.clone(), 8);
            let input = runner.features(&case.outlines, &case.window, case.scene.target());
            let mut relative: Vec<f32> = input.along.iter().map(|g| (g / input.loss as f32).abs()).collect();
            relative.sort_by(f32::total_cmp);
            let q = |f: f32| relative[((relative.len() - 1) as f32 * f) as usize];
            println!(
                "{}: {} points, |d log E / du| quantiles 50% {:.2e} 90% {:.2e} 99% {:.2e} max {:.2e}",
                case.name,
                relative.len(),
                q(0.5),
                q(0.9),
                q(0.99),
                q(1.0)
            );
        }
        for refit in [true, false] {
            let mut runner = LearnedSteps::new(case.movable.clone(), 8);
            runner.refit = refit;
            let mut outlines = case.outlines.clone();
            let mut errors = vec![case.window.l2_outlines(&outlines)];
            for _ in 0..8 {
                let input = runner.features(&outlines, &case.window, case.scene.target());
                let moves = network.moves(input.features.clone(), &device);
                let largest = moves.iter().fold(0.0f32, |m, v| m.max(v.abs()));
                let nan = moves.iter().filter(|v| !v.is_finite()).count();
                let next = runner.apply(&outlines, &input, &moves, case.scene.target());
                if std::env::var_os("PROBE_VERBOSE").is_some() {
                    println!(
                        "  move max {largest:.3} px, {nan} non-finite, error {:.3e}",
                        case.window.l2_outlines(&next)
                    );
                }
                outlines = next;
                errors.push(case.window.l2_outlines(&outlines));
            }
            let ratios: Vec<String> = errors.iter().map(|e| format!("{:.3}", e / errors[0])).collect();
            println!("{} refit {refit}: {}", case.name, ratios.join(" "));
        }
    }
    Ok(())
}
