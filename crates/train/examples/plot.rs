//! Validation curves of training runs as one SVG: PSNR over the flat fill (paths kept where
//! they help, and every path drawn) and spill, against the step; for E_r runs also what E_r
//! adds at inference against the same paths spent on regions (`val_refine_*`).
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

/// One run's validation points: (step, kept − flat dB, drawn − flat dB, spill), and E_r's at
/// inference: (step, dB it added, dB as many regions add).
struct Curve {
    label: String,
    points: Vec<Point>,
    at_inference: Vec<InferencePoint>,
}

/// (step, kept − flat dB, drawn − flat dB, spill).
type Point = (f64, f64, f64, f64);

/// (step, dB E_r added, dB as many regions add).
type InferencePoint = (f64, f64, f64);

fn read(run: &PathBuf) -> Result<Curve, String> {
    let path = run.join("metrics.jsonl");
    let text = std::fs::read_to_string(&path).map_err(|err| format!("{}: {err}", path.display()))?;
    let (mut points, mut at_inference) = (Vec::new(), Vec::new());
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
        if let (Some(step), Some(gain), Some(regions)) =
            (field("step"), field("val_refine_gain_db"), field("val_refine_regions_db"))
        {
            at_inference.push((step, gain, regions));
        }
    }
    if points.is_empty() {
        return Err(format!("{}: no validation lines (val_*)", path.display()));
    }
    let label =
        run.file_name().map_or_else(|| run.display().to_string(), |n| n.to_string_lossy().into_owned());
    Ok(Curve { label, points, at_inference })
}

fn main() {
    let args = Args::parse();
    let inputs: Vec<PathBuf> = args.runs.iter().map(|run| run.join("metrics.jsonl")).collect();
    if let Err(err) = common::outputs::check_output(&args.output, &inputs) {
        common::say!("plot: {err}");
        std::process::exit(1);
    }
    let curves: Vec<Curve> = match args.runs.iter().map(read).collect() {
        Ok(curves) => curves,
        Err(message) => {
            common::say!("plot: {message}");
            std::process::exit(1);
        }
    };
    let gains = paired(
        "PSNR over the flat fill: kept paths solid, all paths dashed",
        "dB",
        &curves,
        |curve| &curve.points,
        |p: &Point| (p.0, p.1),
        (", every path drawn", |p: &Point| (p.0, p.2)),
    );
    let spill = Panel {
        title: "spill".into(),
        x_label: "step".into(),
        y_label: "area outside the dilated mask / path area".into(),
        log_x: false,
        series: curves
            .iter()
            .enumerate()
            .map(|(i, c)| series(&c.label, i, "", Mark::LineAndDots, &c.points, |p| (p.0, p.3)))
            .collect(),
    };
    let mut panels = vec![gains, spill];
    if curves.iter().any(|curve| !curve.at_inference.is_empty()) {
        panels.push(paired(
            "E_r at inference: its paths solid, as many regions dashed",
            "dB added",
            &curves,
            |curve| &curve.at_inference,
            |p: &InferencePoint| (p.0, p.1),
            (", regions", |p: &InferencePoint| (p.0, p.2)),
        ));
    }
    if let Err(err) = common::write::write_atomic(&args.output, chart::svg(&panels).as_bytes()) {
        common::say!("plot: {}: {err}", args.output.display());
        std::process::exit(1);
    }
}

/// The series `label` + `suffix` in colour `index`: `pick` (x, y) of every point.
fn series<P>(
    label: &str,
    index: usize,
    suffix: &str,
    mark: Mark,
    points: &[P],
    pick: impl Fn(&P) -> (f64, f64),
) -> Series {
    Series {
        name: format!("{label}{suffix}"),
        colour: index,
        mark,
        points: points.iter().map(pick).collect(),
    }
}

/// A panel against the step with two series per run: `solid` of its `points`, and the dashed
/// `(suffix, pick)`.
fn paired<P>(
    title: &str,
    y_label: &str,
    curves: &[Curve],
    points: impl Fn(&Curve) -> &[P],
    solid: fn(&P) -> (f64, f64),
    (suffix, dashed): (&str, fn(&P) -> (f64, f64)),
) -> Panel {
    Panel {
        title: title.into(),
        x_label: "step".into(),
        y_label: y_label.into(),
        log_x: false,
        series: curves
            .iter()
            .enumerate()
            .flat_map(|(index, curve)| {
                [
                    series(&curve.label, index, "", Mark::LineAndDots, points(curve), solid),
                    series(&curve.label, index, suffix, Mark::Dashed, points(curve), dashed),
                ]
            })
            .collect(),
    }
}
