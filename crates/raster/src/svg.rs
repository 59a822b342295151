//! SVG export: one `<path>` per visible shape, in painter's order; the ramps they are filled
//! with as `<linearGradient>`s in `<defs>`, in user space (the viewBox's pixels).

use std::fmt::Write;

use crate::decimals::{Decimals, MAX_DECIMALS};
use crate::fill::{Fill, to_8_bits};
use crate::shape::Filled;

/// Why a set of paths cannot be written as SVG.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SvgError {
    /// A canvas side is zero.
    #[error("the canvas is empty ({width}×{height})")]
    EmptyCanvas {
        /// Canvas width in pixels.
        width: u32,
        /// Canvas height in pixels.
        height: u32,
    },
    /// A path has a NaN or infinite coordinate, colour or opacity.
    #[error("path {index} has a non-finite parameter")]
    NonFinite {
        /// Index of the offending path in the input.
        index: usize,
    },
}

/// How [`to_svg_with`] writes a document.
#[derive(Clone, Debug, PartialEq)]
pub struct SvgOptions {
    /// A rectangle of this colour painted first.
    pub background: Option<[f32; 3]>,
    /// Decimals of coordinates and opacity (0 to 6): 2 keeps 1/100 pixel, smaller files take fewer.
    pub decimals: usize,
}

impl Default for SvgOptions {
    fn default() -> Self {
        Self { background: None, decimals: 2 }
    }
}

/// Writes `paths` (unit-square coordinates) as an SVG document of `width × height` pixels.
///
/// The viewBox is in pixels; a background rectangle is painted first when `background` is given.
/// Paths with α ≤ 0 are invisible and left out; `fill-opacity` is written when α < 1; a ramp is
/// a `linearGradient` (ids `a`, `b`, …, `aa`, … in painter's order, end points in pixels with the
/// coordinates' decimals, `spreadMethod` left at its default, pad); every path
/// says `fill-rule="nonzero"` so all viewers fill self-intersections the way the renderers do.
/// Colours and α are clamped to [0, 1]. Coordinates are written with 1/100 pixel precision.
pub fn to_svg<F: Filled>(
    paths: &[F],
    width: u32,
    height: u32,
    background: Option<[f32; 3]>,
) -> Result<String, SvgError> {
    let layers = vec![None; paths.len()];
    to_svg_with(paths, &layers, width, height, &SvgOptions { background, ..SvgOptions::default() })
}

/// [`to_svg`] with options, and each path's layer: consecutive paths of one layer `Some(n)` go
/// in one `<g class="region-n">` (an editor selects a superpixel's paths together; painter's
/// order is kept, so a layer may appear more than once), `None` paths stand alone.
///
/// # Panics
/// If `layers` is shorter than `paths` or `options.decimals` exceeds [`MAX_DECIMALS`].
pub fn to_svg_with<F: Filled>(
    paths: &[F],
    layers: &[Option<u32>],
    width: u32,
    height: u32,
    options: &SvgOptions,
) -> Result<String, SvgError> {
    assert!(layers.len() >= paths.len(), "one layer per path");
    assert!(options.decimals <= MAX_DECIMALS, "at most {MAX_DECIMALS} decimals");
    if width == 0 || height == 0 {
        return Err(SvgError::EmptyCanvas { width, height });
    }
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{width}\" height=\"{height}\" \
         viewBox=\"0 0 {width} {height}\">\n"
    );
    if let Some(color) = options.background {
        let _ = writeln!(svg, "<rect width=\"{width}\" height=\"{height}\" fill=\"{}\"/>", hex(color));
    }
    let (sx, sy) = (width as f32, height as f32);
    let decimals = Decimals::new(options.decimals);
    if let Some(index) = paths.iter().position(|path| !path.is_finite()) {
        return Err(SvgError::NonFinite { index });
    }
    let visible = |path: &&F| path.alpha() > 0.0;
    // A ramp whose ends round to one point is written flat ([`Fill::as_written`]).
    let written = |path: &F| path.fill().as_written([sx, sy], decimals);
    let mut ramps = 0;
    for path in paths.iter().filter(visible) {
        if let Fill::Linear(ramp) = written(path) {
            if ramps == 0 {
                svg.push_str("<defs>\n");
            }
            let number = |value: f32| decimals.number(value);
            let _ = writeln!(
                svg,
                "<linearGradient id=\"{}\" gradientUnits=\"userSpaceOnUse\" x1=\"{}\" y1=\"{}\" x2=\"{}\" \
                 y2=\"{}\"><stop stop-color=\"{}\"/><stop offset=\"1\" stop-color=\"{}\"/></linearGradient>",
                gradient_id(ramps),
                number(ramp.start[0] * sx),
                number(ramp.start[1] * sy),
                number(ramp.end[0] * sx),
                number(ramp.end[1] * sy),
                hex(ramp.stops[0]),
                hex(ramp.stops[1]),
            );
            ramps += 1;
        }
    }
    if ramps > 0 {
        svg.push_str("</defs>\n");
    }
    let mut ramps = 0;
    let mut open: Option<u32> = None;
    for (index, path) in paths.iter().enumerate() {
        if !visible(&path) {
            continue;
        }
        if layers[index] != open {
            if open.is_some() {
                svg.push_str("</g>\n");
            }
            if let Some(layer) = layers[index] {
                let _ = writeln!(svg, "<g class=\"region-{layer}\">");
            }
            open = layers[index];
        }
        svg.push_str("<path d=\"");
        path.svg_data([sx, sy], decimals, &mut svg);
        match written(path) {
            Fill::Solid(color) => {
                let _ = write!(svg, "\" fill=\"{}\"", hex(color));
            }
            Fill::Linear(_) => {
                let _ = write!(svg, "\" fill=\"url(#{})\"", gradient_id(ramps));
                ramps += 1;
            }
        }
        if path.alpha() < 1.0 {
            let _ = write!(svg, " fill-opacity=\"{}\"", decimals.number(path.alpha()));
        }
        svg.push_str(" fill-rule=\"nonzero\"/>\n");
    }
    if open.is_some() {
        svg.push_str("</g>\n");
    }
    svg.push_str("</svg>\n");
    Ok(svg)
}

/// The id of the `index`-th gradient: `a` … `z`, then `aa`, `ab`, … (bijective base 26).
fn gradient_id(mut index: usize) -> String {
    let mut id = Vec::new();
    loop {
        id.push(b'a' + (index % 26) as u8);
        if index < 26 {
            break;
        }
        index = index / 26 - 1;
    }
    id.reverse();
    String::from_utf8(id).expect("ASCII letters")
}

/// `#rrggbb` of a colour in [0, 1] (clamped).
fn hex(color: [f32; 3]) -> String {
    let [r, g, b] = color.map(to_8_bits);
    format!("#{r:02x}{g:02x}{b:02x}")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::path::Path;

    fn square(alpha: f32) -> Path {
        Path::quadrilateral([[0.25, 0.25], [0.75, 0.25], [0.75, 0.75], [0.25, 0.75]], [1.0, 0.5, 0.0], alpha)
    }

    #[test]
    fn writes_visible_paths_with_rule_and_opacity() {
        let svg = to_svg(&[square(1.0), square(0.0), square(0.5)], 100, 50, Some([1.0; 3])).unwrap();
        assert_eq!(svg.matches("<path").count(), 2);
        assert!(svg.contains("viewBox=\"0 0 100 50\""));
        assert!(svg.contains("<rect width=\"100\" height=\"50\" fill=\"#ffffff\"/>"));
        assert!(svg.contains("M25 12.5C"));
        assert!(svg.contains("fill=\"#ff8000\""));
        assert_eq!(svg.matches("fill-opacity=\"0.5\"").count(), 1);
        assert_eq!(svg.matches("fill-rule=\"nonzero\"").count(), 2);
    }

    #[test]
    fn rejects_non_finite_and_empty_canvas() {
        let mut bad = square(1.0);
        bad.points[4][1] = f32::NAN;
        assert_eq!(to_svg(&[square(1.0), bad], 10, 10, None), Err(SvgError::NonFinite { index: 1 }));
        assert!(matches!(to_svg::<Path>(&[], 0, 10, None), Err(SvgError::EmptyCanvas { .. })));
    }

    #[test]
    fn consecutive_paths_of_a_region_share_a_group() {
        let paths = [square(1.0), square(1.0), square(1.0), square(1.0), square(1.0)];
        let layers = [None, Some(3), Some(3), Some(5), Some(3)];
        let svg =
            to_svg_with(&paths, &layers, 100, 100, &SvgOptions { decimals: 0, ..SvgOptions::default() })
                .unwrap();
        assert_eq!(svg.matches("<g class=\"region-3\">").count(), 2, "{svg}");
        assert_eq!(svg.matches("<g class=\"region-5\">").count(), 1);
        assert_eq!(svg.matches("</g>").count(), 3);
        assert!(svg.contains("M25 25C"), "{svg}");
        let tree = resvg::usvg::Tree::from_str(&svg, &resvg::usvg::Options::default());
        assert!(tree.is_ok(), "well-formed");
    }

    #[test]
    fn a_ramp_is_a_gradient_that_resvg_draws_as_the_exact_renderer_does() {
        // Two ramps (one across the canvas, one in a hole-free quarter) and a flat square, over
        // white, written at 2 decimals: resvg's reading matches render_exact to the rounding of
        // 8-bit stops.
        use crate::shape::Outline;
        use common::Ramp;
        let big = Outline::polygon(
            &[[0.05, 0.05], [0.95, 0.1], [0.9, 0.95], [0.1, 0.9]],
            Ramp { start: [0.1, 0.2], end: [0.8, 0.7], stops: [[0.9, 0.2, 0.1], [0.1, 0.3, 0.8]] },
            1.0,
        )
        .unwrap();
        let small = Outline::polygon(
            &[[0.5, 0.5], [0.9, 0.5], [0.9, 0.9]],
            Ramp { start: [0.9, 0.5], end: [0.5, 0.9], stops: [[1.0, 1.0, 0.0], [0.0, 0.5, 0.5]] },
            0.75,
        )
        .unwrap();
        let flat = Outline::polygon(&[[0.2, 0.6], [0.4, 0.6], [0.4, 0.8], [0.2, 0.8]], [0.3, 0.6, 0.3], 1.0)
            .unwrap();
        let shapes = [big, flat, small];
        let svg = to_svg(&shapes, 120, 80, Some([1.0; 3])).unwrap();
        assert_eq!(svg.matches("<linearGradient").count(), 2, "{svg}");
        assert!(svg.contains("fill=\"url(#a)\"") && svg.contains("fill=\"url(#b)\""), "{svg}");
        assert!(svg.contains("x1=\"12\" y1=\"16\" x2=\"96\" y2=\"56\""), "{svg}");
        let tree = resvg::usvg::Tree::from_str(&svg, &resvg::usvg::Options::default()).unwrap();
        let mut read = resvg::tiny_skia::Pixmap::new(120, 80).unwrap();
        resvg::render(&tree, resvg::tiny_skia::Transform::identity(), &mut read.as_mut());
        let ours = crate::render_exact(&shapes, 120, 80, [1.0; 3]);
        let diffs: Vec<(usize, u8)> = read
            .pixels()
            .iter()
            .zip(ours.pixels())
            .map(|(a, b)| [a.red().abs_diff(b.0[0]), a.green().abs_diff(b.0[1]), a.blue().abs_diff(b.0[2])])
            .map(|d| d.into_iter().max().unwrap())
            .enumerate()
            .filter(|d| d.1 > 2)
            .collect();
        let at: Vec<(usize, usize, u8)> =
            diffs.iter().map(|&(i, d)| (i % 120, i / 120, d)).take(40).collect();
        assert!(diffs.is_empty(), "{} differ: {at:?}", diffs.len());
        // The ramp shows: the big shape's corners differ in colour as its stops do.
        let (near, far) = (ours.get_pixel(14, 18).0, ours.get_pixel(100, 68).0);
        assert!(near[0] > 200 && near[2] < 50 && far[2] > 150 && far[0] < 50, "{near:?} … {far:?}");
    }

    #[test]
    fn gradient_ids_are_short_and_distinct() {
        let ids: Vec<String> = [0, 1, 25, 26, 27, 701, 702].into_iter().map(gradient_id).collect();
        assert_eq!(ids, ["a", "b", "z", "aa", "ab", "zz", "aaa"]);
        let many: std::collections::HashSet<String> = (0..5000).map(gradient_id).collect();
        assert_eq!(many.len(), 5000);
    }
}
