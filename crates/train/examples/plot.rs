//! Validation curves of training runs as one SVG: PSNR over the flat fill (paths kept where
//! they help, and every path drawn) and spill, against the step.
//!
//! `cargo run --release -p train --example plot -- RUN_DIR... -o curves.svg`, then e.g.
//! `rsvg-convert curves.svg -o curves.png`. Each run is labelled with its folder's name.

use std::fmt::Write as _;
use std::path::PathBuf;

use clap::Parser;

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

/// Panel geometry: left, top, width, height in SVG units.
const PANEL: (f64, f64, f64, f64) = (70.0, 40.0, 420.0, 260.0);
/// Distinct line colours (Tableau 10).
const COLOURS: [&str; 8] =
    ["#4e79a7", "#f28e2b", "#e15759", "#76b7b2", "#59a14f", "#edc948", "#b07aa1", "#9c755f"];

/// One panel at horizontal offset `dx`: `series(curve)` gives (step, value) lines, solid and
/// dashed; y from `low` to `high`.
fn panel(
    svg: &mut String,
    dx: f64,
    title: &str,
    curves: &[Curve],
    max_step: f64,
    (low, high): (f64, f64),
    series: &dyn Fn(&(f64, f64, f64, f64)) -> (f64, Option<f64>),
) {
    let (left, top, width, height) = PANEL;
    let left = left + dx;
    let x = |step: f64| left + step / max_step * width;
    let y = |v: f64| top + (high - v.clamp(low, high)) / (high - low) * height;
    let _ = write!(
        svg,
        r##"<rect x="{left}" y="{top}" width="{width}" height="{height}" fill="none" stroke="#888"/><text x="{}" y="{}" text-anchor="middle" font-size="15">{title}</text>"##,
        left + width / 2.0,
        top - 12.0
    );
    for i in 0..=4 {
        let v = low + (high - low) * i as f64 / 4.0;
        let (right, level, label_x) = (left + width, y(v), left - 6.0);
        let _ = write!(
            svg,
            r##"<line x1="{left}" x2="{right}" y1="{level}" y2="{level}" stroke="#ddd"/><text x="{label_x}" y="{}" text-anchor="end" font-size="12">{v:.2}</text>"##,
            level + 4.0
        );
        let s = max_step * i as f64 / 4.0;
        let _ = write!(
            svg,
            r#"<text x="{}" y="{}" text-anchor="middle" font-size="12">{s:.0}</text>"#,
            x(s),
            top + height + 16.0
        );
    }
    let _ = write!(
        svg,
        r#"<text x="{}" y="{}" text-anchor="middle" font-size="12">step</text>"#,
        left + width / 2.0,
        top + height + 32.0
    );
    for (index, curve) in curves.iter().enumerate() {
        let colour = COLOURS[index % COLOURS.len()];
        let line = |pick: &dyn Fn(&(f64, f64, f64, f64)) -> Option<f64>| -> String {
            curve
                .points
                .iter()
                .filter_map(|p| pick(p).map(|v| format!("{:.1},{:.1}", x(p.0), y(v))))
                .collect::<Vec<_>>()
                .join(" ")
        };
        let solid = line(&|p| Some(series(p).0));
        let dashed = line(&|p| series(p).1);
        let _ = write!(svg, r#"<polyline points="{solid}" fill="none" stroke="{colour}" stroke-width="2"/>"#);
        for p in &curve.points {
            let _ = write!(
                svg,
                r#"<circle cx="{:.1}" cy="{:.1}" r="3" fill="{colour}"/>"#,
                x(p.0),
                y(series(p).0)
            );
        }
        if !dashed.is_empty() {
            let _ = write!(
                svg,
                r#"<polyline points="{dashed}" fill="none" stroke="{colour}" stroke-width="1.5" stroke-dasharray="5 4"/>"#
            );
        }
    }
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
    let max_step = curves.iter().flat_map(|c| c.points.iter().map(|p| p.0)).fold(1.0, f64::max);
    let gains = curves.iter().flat_map(|c| c.points.iter().flat_map(|p| [p.1, p.2]));
    let (low, high) = gains.fold((0.0f64, 0.5f64), |(lo, hi), v| (lo.min(v), hi.max(v)));
    let spill_high = curves.iter().flat_map(|c| c.points.iter().map(|p| p.3)).fold(0.01, f64::max);
    let (width, height) = (1100.0, 380.0 + 20.0 * curves.len() as f64);
    let mut svg = format!(
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" viewBox="0 0 {width} {height}" font-family="DejaVu Sans, sans-serif"><rect width="100%" height="100%" fill="white"/>"#
    );
    panel(
        &mut svg,
        0.0,
        "PSNR over the flat fill (dB): kept paths solid, all paths dashed",
        &curves,
        max_step,
        (low.floor(), high.ceil()),
        &|p| (p.1, Some(p.2)),
    );
    panel(
        &mut svg,
        540.0,
        "spill (area outside the dilated mask / path area)",
        &curves,
        max_step,
        (0.0, spill_high * 1.1),
        &|p| (p.3, None),
    );
    for (index, curve) in curves.iter().enumerate() {
        let y = 350.0 + 20.0 * index as f64;
        let colour = COLOURS[index % COLOURS.len()];
        let _ = write!(
            svg,
            r#"<line x1="70" x2="100" y1="{0}" y2="{0}" stroke="{colour}" stroke-width="3"/><text x="108" y="{1}" font-size="13">{2}</text>"#,
            y,
            y + 4.0,
            curve.label
        );
    }
    svg.push_str("</svg>\n");
    if let Err(err) = std::fs::write(&args.output, svg) {
        eprintln!("plot: {}: {err}", args.output.display());
        std::process::exit(1);
    }
}
