//! Line charts as SVG documents: panels side by side, each with its axes (linear, or logarithmic
//! for quantities such as file size that span decades), ticks at round values, and series drawn
//! as lines, dots or both, with one legend under all panels. The programs' plots (eval's
//! rate–distortion curves) are drawn here, so every chart reads the same.

use std::fmt::Write as _;

/// Distinct series colours (Tableau 10), used in order.
pub const COLOURS: [&str; 8] =
    ["#4e79a7", "#f28e2b", "#e15759", "#76b7b2", "#59a14f", "#edc948", "#b07aa1", "#9c755f"];

/// How a series is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mark {
    /// A solid line through the points, with a dot on each.
    LineAndDots,
    /// Dots only: settings that do not form a sequence.
    Dots,
    /// A dashed line: a derived curve (an envelope) beside the points it comes from.
    Dashed,
}

/// One named set of (x, y) points.
#[derive(Clone, Debug)]
pub struct Series {
    /// The legend's name.
    pub name: String,
    /// Index into [`COLOURS`] (taken modulo its length): series of one method share it.
    pub colour: usize,
    /// How it is drawn.
    pub mark: Mark,
    /// The points, in the order a line joins them. Points that cannot be placed (not finite, or
    /// not positive on a logarithmic axis) are left out.
    pub points: Vec<(f64, f64)>,
}

/// One plot area.
#[derive(Clone, Debug)]
pub struct Panel {
    /// Written above the panel.
    pub title: String,
    /// The horizontal axis' name.
    pub x_label: String,
    /// The vertical axis' name.
    pub y_label: String,
    /// Whether x is drawn on a logarithmic scale.
    pub log_x: bool,
    /// The series it shows; the legend lists each name once, over all panels.
    pub series: Vec<Series>,
}

/// Size of one panel's plot area and the margins around it, in SVG units.
const PLOT: (f64, f64) = (420.0, 280.0);
const LEFT: f64 = 84.0;
/// About the width of a digit of the tick labels (12 px text), to keep the axis label clear of
/// the widest one.
const DIGIT: f64 = 7.0;
const TOP: f64 = 40.0;
const GAP: f64 = 110.0;
const LEGEND_ROW: f64 = 20.0;

/// The SVG document of `panels` side by side (white background, DejaVu Sans or any sans-serif).
pub fn svg(panels: &[Panel]) -> String {
    let mut names: Vec<(&str, usize, Mark)> = Vec::new();
    for series in panels.iter().flat_map(|p| &p.series) {
        if !names.iter().any(|(name, ..)| *name == series.name) {
            names.push((&series.name, series.colour, series.mark));
        }
    }
    let width = LEFT + panels.len().max(1) as f64 * (PLOT.0 + GAP) - GAP + 30.0;
    let legend_top = TOP + PLOT.1 + 60.0;
    let height = legend_top + LEGEND_ROW * names.len() as f64 + 10.0;
    let mut svg = format!(
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" viewBox="0 0 {width} {height}" font-family="DejaVu Sans, sans-serif"><rect width="100%" height="100%" fill="white"/>"#
    );
    for (index, panel) in panels.iter().enumerate() {
        draw_panel(&mut svg, LEFT + index as f64 * (PLOT.0 + GAP), panel);
    }
    for (row, (name, colour, mark)) in names.iter().enumerate() {
        let y = legend_top + LEGEND_ROW * row as f64;
        let colour = COLOURS[colour % COLOURS.len()];
        let _ = match mark {
            Mark::Dots => write!(svg, r#"<circle cx="{}" cy="{y}" r="3.5" fill="{colour}"/>"#, LEFT + 15.0),
            Mark::LineAndDots | Mark::Dashed => write!(
                svg,
                r#"<line x1="{LEFT}" x2="{}" y1="{y}" y2="{y}" stroke="{colour}" stroke-width="2.5"{}/>"#,
                LEFT + 30.0,
                dash(*mark)
            ),
        };
        let _ = write!(
            svg,
            r#"<text x="{}" y="{}" font-size="13">{}</text>"#,
            LEFT + 38.0,
            y + 4.5,
            escape(name)
        );
    }
    svg.push_str("</svg>\n");
    svg
}

fn dash(mark: Mark) -> &'static str {
    if mark == Mark::Dashed { r#" stroke-dasharray="6 4""# } else { "" }
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

/// An axis: the data range it shows and how values map onto it.
struct Axis {
    low: f64,
    high: f64,
    log: bool,
}

impl Axis {
    /// The axis over `values` (a flat range is widened so that it has a length), with a margin
    /// of 5 % on the linear scale.
    fn over(values: impl Iterator<Item = f64>, log: bool) -> Self {
        let (low, high) =
            values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
        if !low.is_finite() {
            return Self { low: if log { 1.0 } else { 0.0 }, high: if log { 10.0 } else { 1.0 }, log };
        }
        if log {
            let (low, high) = (low.log10(), high.log10());
            let margin = ((high - low) * 0.05).max(0.05);
            Self { low: low - margin, high: high + margin, log }
        } else {
            let margin = ((high - low) * 0.05).max(high.abs().max(1e-3) * 0.01);
            Self { low: low - margin, high: high + margin, log }
        }
    }

    /// Where `value` falls, from 0 (low end) to 1 (high end).
    fn fraction(&self, value: f64) -> f64 {
        let v = if self.log { value.log10() } else { value };
        (v - self.low) / (self.high - self.low)
    }

    /// Round values to mark, with their labels: 1, 2, 5 × 10ᵏ on a logarithmic axis (fewer when
    /// it spans many decades); on a linear one a step of 1, 2 or 5 × 10ᵏ that gives four to ten
    /// ticks, labelled with the step's decimals.
    fn ticks(&self) -> Vec<(f64, String)> {
        if self.log {
            let decades = self.high - self.low;
            let mantissas: &[f64] = if decades > 3.0 { &[1.0] } else { &[1.0, 2.0, 5.0] };
            let mut ticks = Vec::new();
            for exponent in self.low.floor() as i32..=self.high.ceil() as i32 {
                for m in mantissas {
                    let value = m * 10f64.powi(exponent);
                    if (self.low..=self.high).contains(&value.log10()) {
                        ticks.push((value, label(value, 10f64.powi(exponent))));
                    }
                }
            }
            ticks
        } else {
            let span = self.high - self.low;
            let base = 10f64.powf((span / 10.0).log10().floor());
            let step = [1.0, 2.0, 5.0, 10.0]
                .iter()
                .map(|m| m * base)
                .find(|s| span / s <= 10.0)
                .unwrap_or(base * 10.0);
            let first = (self.low / step).ceil() as i64;
            let last = (self.high / step).floor() as i64;
            (first..=last).map(|k| (k as f64 * step, label(k as f64 * step, step))).collect()
        }
    }
}

/// A tick's label: `value` with the decimals that `resolution` (the step between ticks, or the
/// tick's power of ten) needs.
fn label(value: f64, resolution: f64) -> String {
    let decimals = (-resolution.log10().floor()).max(0.0) as usize;
    format!("{value:.decimals$}")
}

fn draw_panel(svg: &mut String, left: f64, panel: &Panel) {
    let (width, height) = PLOT;
    let placeable = |&(x, y): &(f64, f64)| x.is_finite() && y.is_finite() && (!panel.log_x || x > 0.0);
    let points = || panel.series.iter().flat_map(|s| s.points.iter().filter(|p| placeable(p)));
    let x_axis = Axis::over(points().map(|p| p.0), panel.log_x);
    let y_axis = Axis::over(points().map(|p| p.1), false);
    let x = |v: f64| left + x_axis.fraction(v) * width;
    let y = |v: f64| TOP + (1.0 - y_axis.fraction(v)) * height;
    let (right, bottom) = (left + width, TOP + height);
    let _ = write!(
        svg,
        r##"<text x="{}" y="{}" text-anchor="middle" font-size="15">{}</text>"##,
        left + width / 2.0,
        TOP - 14.0,
        escape(&panel.title)
    );
    let y_ticks = y_axis.ticks();
    let widest = y_ticks.iter().map(|(_, text)| text.chars().count()).max().unwrap_or(0) as f64;
    for (value, text) in y_ticks {
        let level = y(value);
        let _ = write!(
            svg,
            r##"<line x1="{left}" x2="{right}" y1="{level:.1}" y2="{level:.1}" stroke="#e4e4e4"/><text x="{}" y="{:.1}" text-anchor="end" font-size="12">{text}</text>"##,
            left - 6.0,
            level + 4.0,
        );
    }
    for (value, text) in x_axis.ticks() {
        let at = x(value);
        let _ = write!(
            svg,
            r##"<line x1="{at:.1}" x2="{at:.1}" y1="{TOP}" y2="{bottom}" stroke="#e4e4e4"/><text x="{at:.1}" y="{}" text-anchor="middle" font-size="12">{text}</text>"##,
            bottom + 16.0,
        );
    }
    let _ = write!(
        svg,
        r##"<rect x="{left}" y="{TOP}" width="{width}" height="{height}" fill="none" stroke="#888"/><text x="{}" y="{}" text-anchor="middle" font-size="13">{}</text><text transform="translate({} {}) rotate(-90)" text-anchor="middle" font-size="13">{}</text>"##,
        left + width / 2.0,
        bottom + 36.0,
        escape(&panel.x_label),
        left - 14.0 - widest * DIGIT,
        TOP + height / 2.0,
        escape(&panel.y_label)
    );
    for series in &panel.series {
        let colour = COLOURS[series.colour % COLOURS.len()];
        let placed: Vec<(f64, f64)> =
            series.points.iter().filter(|p| placeable(p)).map(|&(px, py)| (x(px), y(py))).collect();
        if series.mark != Mark::Dots && placed.len() > 1 {
            let line: Vec<String> = placed.iter().map(|(px, py)| format!("{px:.1},{py:.1}")).collect();
            let _ = write!(
                svg,
                r#"<polyline points="{}" fill="none" stroke="{colour}" stroke-width="2"{}/>"#,
                line.join(" "),
                dash(series.mark)
            );
        }
        if series.mark != Mark::Dashed {
            for (px, py) in placed {
                let _ = write!(svg, r#"<circle cx="{px:.1}" cy="{py:.1}" r="3.5" fill="{colour}"/>"#);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn panel(log_x: bool, points: Vec<(f64, f64)>) -> Panel {
        Panel {
            title: "PSNR & size".into(),
            x_label: "KB".into(),
            y_label: "dB".into(),
            log_x,
            series: vec![Series { name: "ours <B>".into(), colour: 0, mark: Mark::LineAndDots, points }],
        }
    }

    #[test]
    fn log_ticks_are_round_and_inside_the_data() {
        let labels = |axis: Axis| axis.ticks().into_iter().map(|(_, text)| text).collect::<Vec<_>>();
        assert_eq!(
            labels(Axis::over([12.0, 480.0].into_iter(), true)),
            ["10", "20", "50", "100", "200", "500"]
        );
        let wide = Axis::over([0.5, 30000.0].into_iter(), true);
        assert_eq!(labels(wide), ["1", "10", "100", "1000", "10000"]);
        assert_eq!(labels(Axis::over([0.03, 0.4].into_iter(), true)), ["0.05", "0.1", "0.2"]);
    }

    #[test]
    fn linear_ticks_step_by_one_two_or_five() {
        let labels = |low: f64, high: f64| {
            Axis::over([low, high].into_iter(), false).ticks().into_iter().map(|(_, t)| t).collect::<Vec<_>>()
        };
        assert_eq!(labels(22.3, 31.8), ["22", "24", "26", "28", "30", "32"]);
        assert_eq!(labels(0.012, 0.081), ["0.01", "0.02", "0.03", "0.04", "0.05", "0.06", "0.07", "0.08"]);
        assert_eq!(labels(22.1, 24.9), ["22.0", "22.5", "23.0", "23.5", "24.0", "24.5", "25.0"]);
    }

    #[test]
    fn points_land_inside_the_plot_and_in_order() {
        let document = svg(&[panel(true, vec![(10.0, 20.0), (100.0, 25.0), (1000.0, 30.0)])]);
        let line = document.split("<polyline points=\"").nth(1).unwrap().split('"').next().unwrap();
        let placed: Vec<(f64, f64)> = line
            .split(' ')
            .map(|p| {
                let (x, y) = p.split_once(',').unwrap();
                (x.parse().unwrap(), y.parse().unwrap())
            })
            .collect();
        assert_eq!(placed.len(), 3);
        for &(x, y) in &placed {
            assert!((LEFT..=LEFT + PLOT.0).contains(&x) && (TOP..=TOP + PLOT.1).contains(&y), "{placed:?}");
        }
        // Equal steps in log x are equal steps on the page; higher values are higher up.
        assert!(((placed[1].0 - placed[0].0) - (placed[2].0 - placed[1].0)).abs() < 0.2, "{placed:?}");
        assert!(placed[0].1 > placed[1].1 && placed[1].1 > placed[2].1, "{placed:?}");
        assert!(document.contains("ours &lt;B&gt;") && document.contains("PSNR &amp; size"));
    }

    #[test]
    fn points_that_cannot_be_placed_are_left_out() {
        let document = svg(&[panel(true, vec![(0.0, 1.0), (10.0, f64::NAN), (10.0, 2.0), (20.0, 3.0)])]);
        let line = document.split("<polyline points=\"").nth(1).unwrap().split('"').next().unwrap();
        assert_eq!(line.split(' ').count(), 2, "{line}");
        assert_eq!(document.matches("<circle").count(), 2, "{document}");
    }
}
