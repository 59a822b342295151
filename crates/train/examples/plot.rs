//! Validation curves of training runs as one SVG: PSNR over the flat fill (paths kept where
//! they help, and every path drawn) and spill, against the step.
//!
//! `cargo run --release -p train --example plot -- RUN_DIR... -o curves.svg`, then e.g.
//! `rsvg-convert curves.svg -o curves.png`. Each run is labelled with its folder's name.

use std::path::PathBuf;

use clap::Parser;
use common::chart::{self, Mark, Panel, Series};

/// Plot the `val_*` lines of runs' metrics.jsonl.
#[derive(Parser, Debug)]
struct Args {
    /// Run folders (each holding a metrics.jsonl).
    #[arg(required = true)]
    runs: Vec<PathBuf>,
    /// The SVG to write.
    #[arg(short, long)]
    output: PathBuf,
}

/// One run's validation points: (step, kept − flat dB, drawn − flat dB, spill).
struct Curve {
    label: String,
    points: Vec<(f64, f64, f64, f64)>,
}

fn read(run: &PathBuf) -> Result<Curve, String> {
    let path = run.join("metrics.jsonl");
    let text = std::fs::read_to_string(&path).map_err(|err| format!("{}: {err}", path.display()))?;
    let mut points = Vec::new();
    for (number, line) in text.lines().enumerate() {
        let value: serde_json::Value =
            serde_json::from_str(line).map_err(|err| format!("{}:{}: {err}", path.display(), number + 1))?;
        let field = |key: &str| value.get(key).and_then(serde_json::Value::as_f64);
        if let (Some(step), Some(flat), Some(kept), Some(drawn), Some(spill)) = (
            field("step"),
            field("val_psnr_flat"),
            field("val_psnr_kept"),
            field("val_psnr_drawn"),
            field("val_spill"),
        ) {
            points.push((step, kept - flat, drawn - flat, spill));
        }
    }
    if points.is_empty() {
        return Err(format!("{}: no validation lines (val_*)", path.display()));
    }
    let label =
        run.file_name().map_or_else(|| run.display().to_string(), |n| n.to_string_lossy().into_owned());
    Ok(Curve { label, points })
}

fn main() {
    let args = Args::parse();
    let curves: Vec<Curve> = match args.runs.iter().map(read).collect() {
        Ok(curves) => curves,
        Err(message) => {
            eprintln!("plot: {message}");
            std::process::exit(1);
        }
    };
    let series =
        |curve: &Curve, index: usize, suffix: &str, mark: Mark, pick: fn(&(f64, f64, f64, f64)) -> f64| {
            Series {
                name: format!("{}{suffix}", curve.label),
                colour: index,
                mark,
                points: curve.points.iter().map(|p| (p.0, pick(p))).collect(),
            }
        };
    let gains = Panel {
        title: "PSNR over the flat fill: kept paths solid, all paths dashed".into(),
        x_label: "step".into(),
        y_label: "dB".into(),
        log_x: false,
        series: curves
            .iter()
            .enumerate()
            .flat_map(|(index, curve)| {
                [
                    series(curve, index, "", Mark::LineAndDots, |p| p.1),
                    series(curve, index, ", every path drawn", Mark::Dashed, |p| p.2),
                ]
            })
            .collect(),
    };
    let spill = Panel {
        title: "spill".into(),
        x_label: "step".into(),
        y_label: "area outside the dilated mask / path area".into(),
        log_x: false,
        series: curves
            .iter()
            .enumerate()
            .map(|(i, c)| series(c, i, "", Mark::LineAndDots, |p| p.3))
            .collect(),
    };
    if let Err(err) = std::fs::write(&args.output, chart::svg(&[gains, spill])) {
        eprintln!("plot: {}: {err}", args.output.display());
        std::process::exit(1);
    }
}
