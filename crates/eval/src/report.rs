//! What `eval` writes: the markdown report (a table per budget, where SuperSVG's paths came
//! from, each image's figures), the rate–distortion section and chart, and the contact sheet.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use common::chart::{self, Mark, Panel, Series};
use common::{gmsd, mse, psnr, ssim};
use image::{Rgb32FImage, RgbImage};
use infer::Origin;

use crate::lpips::Lpips;
use crate::method::{Budget, Drawing, Method, SPILL_DILATION, to_rgb8};
use crate::rate::{RatePoint, at, frontier};

/// The report a result goes in: a budget every method is drawn at, or one point of the
/// rate–distortion sweep (reported as curves, not as a table).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Table {
    /// A table of its own: a number of paths, or each method's own budget.
    Compared(Budget),
    /// One point of the sweep.
    Sweep(Budget),
    /// SuperSVG-F at a budget after a number of milliseconds (reported as curves).
    Time(Budget, u32),
}

impl Table {
    fn title(self) -> String {
        match self {
            Table::Compared(budget) | Table::Sweep(budget) | Table::Time(budget, _) => budget.title(),
        }
    }
}

/// One method's result on one image at one budget.
pub struct Row {
    /// The image's file name.
    pub image: String,
    /// Closed subpaths (regions, for the mosaic).
    pub shapes: usize,
    /// Size of the SVG file (none for the pixel-exact mosaic, which is no SVG).
    pub bytes: Option<usize>,
    /// Mean squared error against the input.
    pub mse: f64,
    /// PSNR against the input, dB.
    pub psnr: f64,
    /// SSIM against the input.
    pub ssim: f64,
    /// GMSD against the input ([`common::gmsd`]; lower is better: false and blurred edges).
    pub gmsd: f64,
    /// LPIPS against the input, when its weights are present.
    pub lpips: Option<f64>,
    /// Wall time of the method.
    pub seconds: f64,
    /// Paths per stage and spill, for SuperSVG's own drawings.
    pub anatomy: Option<crate::method::Anatomy>,
}

/// Every method's rows so far, and the contact sheet's tiles.
#[derive(Default)]
pub struct Results {
    rows: BTreeMap<(Table, Method), Vec<Row>>,
    /// Per image: the input (no method), then each method's drawing at the sheet's budget.
    sheet: Vec<Vec<(Option<Method>, Rgb32FImage)>>,
    /// Whether the image being evaluated has a row on the sheet (the first few do).
    on_sheet: bool,
}

/// Images the contact sheet shows.
const SHEET_IMAGES: usize = 8;

impl Results {
    /// Scores `drawing` of `input` (named `image`) and files it under `table` and `method`.
    pub fn record(
        &mut self,
        (image, input): (&str, &Rgb32FImage),
        table: Table,
        method: Method,
        drawing: &Drawing,
        lpips: Option<&Lpips>,
    ) {
        let drawn = &drawing.image;
        let row = Row {
            image: image.to_string(),
            shapes: drawing.shapes,
            bytes: drawing.svg.as_ref().map(String::len),
            mse: mse(drawn, input),
            psnr: psnr(drawn, input),
            ssim: ssim(drawn, input),
            gmsd: gmsd(input, drawn),
            lpips: lpips.and_then(|net| net.distance(drawn, input)),
            seconds: drawing.seconds,
            anatomy: drawing.anatomy,
        };
        self.rows.entry((table, method)).or_default().push(row);
    }

    /// Starts the contact sheet's row of an image (while it has room), with the input.
    pub fn start_sheet_row(&mut self, input: &Rgb32FImage) {
        self.on_sheet = self.sheet.len() < SHEET_IMAGES;
        if self.on_sheet {
            self.sheet.push(vec![(None, input.clone())]);
        }
    }

    /// Adds a method's drawing to the contact sheet's row of the image being evaluated.
    pub fn add_to_sheet(&mut self, method: Method, drawing: &Drawing) {
        if let Some(row) = self.sheet.last_mut().filter(|_| self.on_sheet) {
            row.push((Some(method), drawing.image.clone()));
        }
    }

    /// The contact sheet: a row per image, input first, scaled to `tile` px; and its columns'
    /// names.
    pub fn sheet(&self, tile: u32) -> (RgbImage, Vec<&'static str>) {
        let columns = self
            .sheet
            .first()
            .map(|row| row.iter().map(|(method, _)| method.map_or("input", Method::name)).collect())
            .unwrap_or_default();
        (contact_sheet(&self.sheet, tile), columns)
    }
}

/// What the report says above and below its tables.
pub struct Header {
    /// The folder evaluated.
    pub dir: PathBuf,
    /// Images evaluated.
    pub images: usize,
    /// Working size, px.
    pub size: u32,
    /// The command that made the report.
    pub command: String,
    /// Notes (peers missing, LPIPS skipped).
    pub notes: Vec<String>,
    /// The contact sheet's file, its budget and its columns.
    pub sheet: PathBuf,
    /// The budget the contact sheet shows.
    pub sheet_budget: Budget,
    /// The contact sheet's columns.
    pub columns: Vec<&'static str>,
}

/// The markdown report: one table per budget with the mean over images, then where SuperSVG's
/// paths came from.
pub fn report(header: &Header, results: &Results) -> String {
    let mut text = format!(
        "# Evaluation on `{}`\n\n{} images, working resolution {} px (long side). Every SVG rendered \
         with resvg and compared with the input at that size; means over images. \"shapes\" counts closed \
         subpaths, the same unit for every method.\n\nCommand: `{}`\n\n",
        header.dir.display(),
        header.images,
        header.size,
        header.command
    );
    let results = &results.rows;
    for table in tables(results) {
        let title = table.title();
        let title = title[..1].to_uppercase() + &title[1..];
        let _ = writeln!(
            text,
            "## {title}\n\n| method | shapes | SVG KB | PSNR (dB) | SSIM | GMSD | MSE | LPIPS | seconds / image |\n| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"
        );
        let rows_here = results.iter().filter(|((t, _), _)| *t == table);
        for ((_, method), rows) in rows_here.clone() {
            let method = method.name();
            let mean = |f: &dyn Fn(&Row) -> f64| rows.iter().map(f).sum::<f64>() / rows.len() as f64;
            let kilobytes = if rows.iter().all(|r| r.bytes.is_some()) {
                format!("{:.1}", mean(&|r| r.bytes.unwrap_or(0) as f64) / 1000.0)
            } else {
                "—".to_string()
            };
            let lpips = if rows.iter().all(|r| r.lpips.is_some()) {
                format!("{:.4}", mean(&|r| r.lpips.unwrap_or(f64::NAN)))
            } else {
                "—".to_string()
            };
            let _ = writeln!(
                text,
                "| {method} | {:.0} | {kilobytes} | {:.2} | {:.4} | {:.4} | {:.5} | {lpips} | {:.2} |",
                mean(&|r| r.shapes as f64),
                mean(&|r| r.psnr),
                mean(&|r| r.ssim),
                mean(&|r| r.gmsd),
                mean(&|r| r.mse),
                mean(&|r| r.seconds)
            );
        }
        let ours: Vec<_> = rows_here.filter(|(_, rows)| rows.iter().all(|r| r.anatomy.is_some())).collect();
        if !ours.is_empty() {
            let stages: Vec<&str> = Origin::ALL.iter().map(|o| o.name()).collect();
            let _ = writeln!(
                text,
                "\nWhere SuperSVG's paths come from (mean paths per image by stage), spill (share of \
                 region paths' area outside their region dilated by {SPILL_DILATION} px), and what E_r \
                 did (paths kept of those it proposed, summed over images; the PSNR its kept paths \
                 added, mean):\n\n| method | {} | spill | E_r kept / proposed | E_r dB |\n| --- |{} ---: | \
                 ---: | ---: |",
                stages.join(" | "),
                " ---: |".repeat(stages.len())
            );
            for ((_, method), rows) in ours {
                let anatomy = || rows.iter().filter_map(|r| r.anatomy.as_ref());
                let per_stage: Vec<String> = Origin::ALL
                    .iter()
                    .map(|&origin| {
                        let count: usize = anatomy().map(|a| a.stages.of(origin)).sum();
                        format!("{:.1}", count as f64 / rows.len() as f64)
                    })
                    .collect();
                let spill = anatomy().map(|a| a.spill).sum::<f64>() / rows.len() as f64;
                let kept: usize = anatomy().map(|a| a.refinement.kept).sum();
                let proposed: usize = anatomy().map(|a| a.refinement.proposed).sum();
                let gain = anatomy().map(|a| a.refinement.gain_db).sum::<f64>() / rows.len() as f64;
                let _ = writeln!(
                    text,
                    "| {} | {} | {spill:.3} | {kept} / {proposed} | {gain:+.2} |",
                    method.name(),
                    per_stage.join(" | ")
                );
            }
        }
        text.push('\n');
    }
    text.push_str(&per_image(results));
    for note in &header.notes {
        let _ = writeln!(text, "- {note}");
    }
    let _ = writeln!(
        text,
        "\nContact sheet at {}: `{}` (columns: {}).",
        header.sheet_budget.title(),
        header.sheet.display(),
        header.columns.join(" | ")
    );
    text
}

/// The tables the results fill, in order.
fn tables(results: &BTreeMap<(Table, Method), Vec<Row>>) -> Vec<Table> {
    let mut tables: Vec<Table> =
        results.keys().map(|(table, _)| *table).filter(|t| matches!(t, Table::Compared(_))).collect();
    tables.dedup();
    tables
}

/// One setting of the sweep, averaged over the images.
pub struct SweepPoint {
    /// The budget or setting.
    pub setting: Budget,
    /// Mean size and quality.
    pub point: RatePoint,
    /// Mean seconds an image.
    pub seconds: f64,
}

/// The sweep's means per method, settings in order. A setting that did not draw every one of
/// the `images` is left out (its error was printed), so every point averages the same images.
pub fn sweep_points(results: &Results, images: usize) -> BTreeMap<Method, Vec<SweepPoint>> {
    let results = &results.rows;
    let mut points: BTreeMap<Method, Vec<SweepPoint>> = BTreeMap::new();
    for ((table, method), rows) in results {
        let (Table::Sweep(setting), true) = (table, rows.len() == images) else { continue };
        let Some(bytes) = rows.iter().map(|r| r.bytes).sum::<Option<usize>>() else { continue };
        let mean = |f: &dyn Fn(&Row) -> f64| rows.iter().map(f).sum::<f64>() / rows.len() as f64;
        let lpips = rows.iter().map(|r| r.lpips).sum::<Option<f64>>().map(|sum| sum / rows.len() as f64);
        let point = RatePoint {
            kilobytes: bytes as f64 / rows.len() as f64 / 1000.0,
            psnr: mean(&|r| r.psnr),
            lpips,
        };
        points.entry(*method).or_default().push(SweepPoint {
            setting: *setting,
            point,
            seconds: mean(&|r| r.seconds),
        });
    }
    points
}

/// Colour of a method's series in the chart: the same in both panels.
fn colour(method: Method) -> usize {
    match method {
        Method::OursB => 0,
        Method::Fallback => 1,
        Method::Vtracer => 2,
        Method::OursLinear => 4,
        Method::OursNoMoves => 5,
        Method::OursFlat => 6,
        _ => 3,
    }
}

/// SuperSVG-F after some seconds at one budget, averaged over the images.
#[derive(Clone, Copy, Debug)]
pub struct TimePoint {
    /// Seconds of fine-tuning.
    pub seconds: f64,
    /// Mean PSNR, dB.
    pub psnr: f64,
    /// Mean LPIPS, where measured.
    pub lpips: Option<f64>,
    /// Mean GMSD.
    pub gmsd: f64,
    /// Mean SVG kilobytes.
    pub kilobytes: f64,
}

/// Every curve of `--time-chart`: per method and budget, its points in order of time.
pub fn time_points(results: &Results) -> BTreeMap<(Method, usize), Vec<TimePoint>> {
    let mut curves: BTreeMap<(Method, usize), Vec<TimePoint>> = BTreeMap::new();
    for ((table, method), rows) in &results.rows {
        let Table::Time(Budget::Paths(paths), millis) = *table else { continue };
        let mean = |f: &dyn Fn(&Row) -> f64| rows.iter().map(f).sum::<f64>() / rows.len() as f64;
        let lpips = rows.iter().map(|r| r.lpips).sum::<Option<f64>>().map(|sum| sum / rows.len() as f64);
        curves.entry((*method, paths)).or_default().push(TimePoint {
            seconds: f64::from(millis) / 1000.0,
            psnr: mean(&|r| r.psnr),
            lpips,
            gmsd: mean(&|r| r.gmsd),
            kilobytes: mean(&|r| r.bytes.unwrap_or(0) as f64) / 1000.0,
        });
    }
    for points in curves.values_mut() {
        points.sort_by(|a, b| a.seconds.total_cmp(&b.seconds));
    }
    curves
}

/// The time chart: PSNR, and LPIPS where measured, against seconds of fine-tuning, a line per
/// method and budget.
pub fn time_chart(curves: &BTreeMap<(Method, usize), Vec<TimePoint>>) -> String {
    let quality: [(&str, &str, fn(&TimePoint) -> Option<f64>); 2] = [
        ("PSNR against fine-tuning time", "PSNR (dB), higher is better", |p| Some(p.psnr)),
        ("LPIPS against fine-tuning time", "LPIPS, lower is better", |p| p.lpips),
    ];
    let panels: Vec<Panel> = quality
        .iter()
        .filter(|(_, _, value)| curves.values().flatten().all(|p| value(p).is_some()))
        .map(|&(title, y_label, value)| Panel {
            title: title.into(),
            x_label: "seconds of SuperSVG-F".into(),
            y_label: y_label.into(),
            log_x: true,
            series: curves
                .iter()
                .enumerate()
                .map(|(k, ((method, paths), points))| Series {
                    name: format!("{}, {paths} paths", method.name()),
                    colour: k,
                    mark: if *method == Method::OursF { Mark::LineAndDots } else { Mark::Dashed },
                    points: points.iter().filter_map(|p| value(p).map(|v| (p.seconds, v))).collect(),
                })
                .collect(),
        })
        .collect();
    chart::svg(&panels)
}

/// The report's section on `--time-chart`: a table per budget, a row per time, and the chart.
pub fn time_section(curves: &BTreeMap<(Method, usize), Vec<TimePoint>>, chart: &Path) -> String {
    let mut text = String::from(
        "\n## SuperSVG-F against time\n\nEach budget's drawing fine-tuned for each time, from B's drawing \
         (as `infer --finetune-secs` draws it) and as F was (from B with flat fills and no mover, \
         outlines fitted with one path where that writes less); means over images, each drawing \
         rendered with resvg. PSNR / LPIPS / GMSD / SVG KB.\n",
    );
    let budgets: std::collections::BTreeSet<usize> = curves.keys().map(|(_, paths)| *paths).collect();
    for paths in budgets {
        let methods: Vec<Method> = curves.keys().filter(|(_, p)| *p == paths).map(|(m, _)| *m).collect();
        let names: Vec<&str> = methods.iter().map(|m| m.name()).collect();
        let _ = write!(
            text,
            "\n### {paths} paths\n\n| seconds | {} |\n| ---: |{}\n",
            names.join(" | "),
            " ---: |".repeat(names.len())
        );
        let times = &curves[&(methods[0], paths)];
        for (k, point) in times.iter().enumerate() {
            let cells: Vec<String> = methods
                .iter()
                .map(|method| {
                    let p = curves[&(*method, paths)][k];
                    let lpips = p.lpips.map_or_else(|| "—".to_string(), |l| format!("{l:.4}"));
                    format!("{:.2} / {lpips} / {:.4} / {:.1}", p.psnr, p.gmsd, p.kilobytes)
                })
                .collect();
            let _ = writeln!(text, "| {} | {} |", point.seconds, cells.join(" | "));
        }
    }
    let name = chart.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let _ = writeln!(text, "\n![PSNR and LPIPS against seconds of SuperSVG-F]({name})");
    text
}

/// The rate–distortion chart: PSNR, and LPIPS where it was measured, against SVG kilobytes;
/// our budgets as lines, vtracer's settings as dots with their frontier dashed.
pub fn rate_chart(points: &BTreeMap<Method, Vec<SweepPoint>>) -> String {
    let quality: [(&str, &str, fn(&RatePoint) -> Option<f64>, fn(&RatePoint) -> Option<f64>); 2] = [
        ("PSNR against file size", "PSNR (dB), higher is better", |p| Some(p.psnr), |p| Some(p.psnr)),
        ("LPIPS against file size", "LPIPS, lower is better", |p| p.lpips, |p| p.lpips.map(|l| -l)),
    ];
    let measured =
        |pick: fn(&RatePoint) -> Option<f64>| points.values().flatten().all(|p| pick(&p.point).is_some());
    let panels: Vec<Panel> = quality
        .iter()
        .filter(|(_, _, value, _)| measured(*value))
        .map(|&(title, y_label, value, better)| {
            let mut series = Vec::new();
            // Ours last, so they are drawn over the peers.
            for (&method, sweep) in points.iter().rev() {
                let xy = |list: &[RatePoint]| {
                    list.iter().filter_map(|p| value(p).map(|v| (p.kilobytes, v))).collect()
                };
                let rates: Vec<RatePoint> = sweep.iter().map(|p| p.point).collect();
                if method == Method::Vtracer {
                    series.push(Series {
                        name: format!("{} settings", method.name()),
                        colour: colour(method),
                        mark: Mark::Dots,
                        points: xy(&rates),
                    });
                    series.push(Series {
                        name: format!("{}, best at each size", method.name()),
                        colour: colour(method),
                        mark: Mark::Dashed,
                        points: xy(&frontier(&rates, better)),
                    });
                } else {
                    series.push(Series {
                        name: format!("{}, by path budget", method.name()),
                        colour: colour(method),
                        mark: Mark::LineAndDots,
                        points: xy(&rates),
                    });
                }
            }
            Panel {
                title: title.to_string(),
                x_label: "SVG size (KB, log scale)".to_string(),
                y_label: y_label.to_string(),
                log_x: true,
                series,
            }
        })
        .collect();
    chart::svg(&panels)
}

/// The report's rate–distortion section: each method's sweep, then every vtracer setting
/// beside our methods at the same file size.
pub fn rate_section(points: &BTreeMap<Method, Vec<SweepPoint>>, chart: &Path) -> String {
    let mut text = format!(
        "## Rate and distortion\n\nMeans over the images at each setting: SuperSVG at each `--sweep` budget, \
         vtracer over speckle 0–16 at colour precision 3, 4, 6 and 8. Chart: `{}` (PSNR and LPIPS against SVG \
         KB).\n\n| method | setting | SVG KB | PSNR (dB) | LPIPS | seconds / image |\n| --- | --- | ---: | ---: | ---: | ---: |\n",
        chart.display()
    );
    let lpips = |value: Option<f64>| value.map_or_else(|| "—".to_string(), |l| format!("{l:.4}"));
    for (method, sweep) in points {
        for SweepPoint { setting, point, seconds } in sweep {
            let _ = writeln!(
                text,
                "| {} | {} | {:.1} | {:.2} | {} | {seconds:.2} |",
                method.name(),
                setting.title(),
                point.kilobytes,
                point.psnr,
                lpips(point.lpips)
            );
        }
    }
    let Some(vtracer) = points.get(&Method::Vtracer) else { return text };
    let ours: Vec<(Method, Vec<RatePoint>)> = points
        .iter()
        .filter(|(m, _)| **m != Method::Vtracer)
        .map(|(m, sweep)| (*m, sweep.iter().map(|p| p.point).collect()))
        .collect();
    let header: Vec<String> = ours.iter().map(|(m, _)| format!("{} PSNR / LPIPS", m.name())).collect();
    let _ = writeln!(
        text,
        "\n### At vtracer's file sizes\n\nEach vtracer setting beside our methods at the same SVG size, read \
         off their curves (linear in log KB between budgets). Past the largest file a method drew, its \
         largest drawing is shown, marked ≤ (a smaller file); — where the size is below what the sweep \
         covers.\n\n| vtracer setting | SVG KB | vtracer PSNR / LPIPS | {} |\n| --- | ---: | ---: |{}",
        header.join(" | "),
        " ---: |".repeat(ours.len())
    );
    // Per method: (sizes covered, PSNR above vtracer, LPIPS below vtracer, settings past its
    // largest file that its largest drawing beats on both).
    let mut wins = vec![(0, 0, 0, 0); ours.len()];
    for SweepPoint { setting, point, .. } in vtracer {
        let cells: Vec<String> = ours
            .iter()
            .zip(&mut wins)
            .map(|((_, curve), wins)| match at(curve, point.kilobytes, |p| Some(p.psnr)) {
                Some(psnr) => {
                    let ours_lpips = at(curve, point.kilobytes, |p| p.lpips);
                    wins.0 += 1;
                    wins.1 += usize::from(psnr > point.psnr);
                    wins.2 += usize::from(ours_lpips.zip(point.lpips).is_some_and(|(o, v)| o < v));
                    format!("{psnr:.2} ({:+.2}) / {}", psnr - point.psnr, lpips(ours_lpips))
                }
                None => match curve.iter().max_by(|a, b| a.kilobytes.total_cmp(&b.kilobytes)) {
                    Some(largest) if largest.kilobytes < point.kilobytes => {
                        let beats = largest.psnr > point.psnr
                            && largest.lpips.zip(point.lpips).is_some_and(|(o, v)| o < v);
                        wins.3 += usize::from(beats);
                        format!(
                            "≤ {:.2} ({:+.2}) / {}",
                            largest.psnr,
                            largest.psnr - point.psnr,
                            lpips(largest.lpips)
                        )
                    }
                    _ => "—".to_string(),
                },
            })
            .collect();
        let _ = writeln!(
            text,
            "| {} | {:.1} | {:.2} / {} | {} |",
            setting.title(),
            point.kilobytes,
            point.psnr,
            lpips(point.lpips),
            cells.join(" | ")
        );
    }
    text.push('\n');
    for ((method, _), (covered, psnr, lpips, beyond)) in ours.iter().zip(wins) {
        let _ = writeln!(
            text,
            "- {}: of the {} vtracer settings, {covered} fall within its sizes; at {psnr} of them its PSNR is \
             higher, at {lpips} its LPIPS lower. Of those larger than its largest file, {beyond} draw worse \
             than that smaller file on both measures.",
            method.name(),
            vtracer.len()
        );
    }
    text.push('\n');
    text
}

/// Each image's PSNR / LPIPS per method, one table per budget: where a mean hides one image
/// that loses.
fn per_image(results: &BTreeMap<(Table, Method), Vec<Row>>) -> String {
    let mut text = String::from("## Per image (PSNR dB / LPIPS)\n");
    for table in tables(results) {
        let methods: Vec<(Method, &Vec<Row>)> =
            results.iter().filter(|((t, _), _)| *t == table).map(|((_, m), rows)| (*m, rows)).collect();
        let mut images: Vec<&str> =
            methods.iter().flat_map(|(_, rows)| rows.iter().map(|r| r.image.as_str())).collect();
        images.sort_unstable();
        images.dedup();
        let title = table.title();
        let names: Vec<&str> = methods.iter().map(|(m, _)| m.name()).collect();
        let _ = writeln!(
            text,
            "\n{title}:\n\n| image | {} |\n| --- |{}",
            names.join(" | "),
            " ---: |".repeat(names.len())
        );
        for image in images {
            let cells: Vec<String> = methods
                .iter()
                .map(|(_, rows)| match rows.iter().find(|r| r.image == image) {
                    Some(row) => match row.lpips {
                        Some(lpips) => format!("{:.2} / {lpips:.4}", row.psnr),
                        None => format!("{:.2}", row.psnr),
                    },
                    None => "—".to_string(),
                })
                .collect();
            let _ = writeln!(text, "| {image} | {} |", cells.join(" | "));
        }
    }
    text.push('\n');
    text
}

/// Rows of tiles (input, then each method) scaled to `tile` px, with their names.
fn contact_sheet(rows: &[Vec<(Option<Method>, Rgb32FImage)>], tile: u32) -> RgbImage {
    let columns = rows.iter().map(Vec::len).max().unwrap_or(1) as u32;
    let mut sheet = RgbImage::from_pixel(
        columns * (tile + 4) + 4,
        rows.len() as u32 * (tile + 4) + 4,
        image::Rgb([255, 255, 255]),
    );
    for (r, row) in rows.iter().enumerate() {
        for (c, (_, image)) in row.iter().enumerate() {
            let scale = tile as f32 / image.width().max(image.height()) as f32;
            let (w, h) = (
                ((image.width() as f32 * scale) as u32).max(1),
                ((image.height() as f32 * scale) as u32).max(1),
            );
            let small = image::imageops::resize(&to_rgb8(image), w, h, image::imageops::FilterType::Triangle);
            let (x, y) = (4 + c as u32 * (tile + 4), 4 + r as u32 * (tile + 4));
            image::imageops::replace(&mut sheet, &small, x.into(), y.into());
        }
    }
    sheet
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::VtracerSettings;

    /// Each vtracer setting is set beside our curve at its own size, never extrapolated, and the
    /// summary counts where we draw better.
    #[test]
    fn vtracer_settings_are_read_against_our_curve_at_their_size() {
        let point = |kilobytes, psnr, lpips| RatePoint { kilobytes, psnr, lpips: Some(lpips) };
        let at_budget = |paths, point| SweepPoint { setting: Budget::Paths(paths), point, seconds: 1.0 };
        let vtracer = |filter_speckle, point| SweepPoint {
            setting: Budget::Vtracer(VtracerSettings { filter_speckle, ..VtracerSettings::default() }),
            point,
            seconds: 0.1,
        };
        let points = BTreeMap::from([
            (
                Method::OursB,
                vec![at_budget(100, point(10.0, 30.0, 0.1)), at_budget(1000, point(100.0, 40.0, 0.02))],
            ),
            (
                Method::Vtracer,
                vec![
                    vtracer(64, point(5.0, 20.0, 0.3)),
                    vtracer(8, point(10f64.powf(1.5), 34.0, 0.04)),
                    vtracer(1, point(100.0, 41.0, 0.01)),
                    vtracer(0, point(400.0, 39.0, 0.03)),
                ],
            ),
        ]);
        let text = rate_section(&points, Path::new("rate.png"));
        assert!(text.contains("| speckle 64, precision 6 | 5.0 | 20.00 / 0.3000 | — |"), "{text}");
        assert!(
            text.contains("| speckle 8, precision 6 | 31.6 | 34.00 / 0.0400 | 35.00 (+1.00) / 0.0600 |"),
            "{text}"
        );
        assert!(
            text.contains("| speckle 1, precision 6 | 100.0 | 41.00 / 0.0100 | 40.00 (-1.00) / 0.0200 |"),
            "{text}"
        );
        assert!(
            text.contains("of the 4 vtracer settings, 2 fall within its sizes; at 1 of them its PSNR is higher, at 0 its LPIPS lower. Of those larger than its largest file, 1 draw worse"),
            "{text}"
        );
        assert!(
            text.contains("| speckle 0, precision 6 | 400.0 | 39.00 / 0.0300 | ≤ 40.00 (+1.00) / 0.0200 |"),
            "{text}"
        );
        let chart = rate_chart(&points);
        assert_eq!(chart.matches("<polyline").count(), 2 * 2, "ours and vtracer's frontier, in both panels");
    }
}
