//! SVG export: one `<path>` per visible shape, in painter's order.

use std::fmt::Write;

use crate::decimals::{Decimals, MAX_DECIMALS};
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
/// Paths with α ≤ 0 are invisible and left out; `fill-opacity` is written when α < 1; every path
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
    let mut open: Option<u32> = None;
    for (index, path) in paths.iter().enumerate() {
        if !path.is_finite() {
            return Err(SvgError::NonFinite { index });
        }
        if path.alpha() <= 0.0 {
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
        let _ = write!(svg, "\" fill=\"{}\"", hex(path.color()));
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

/// `#rrggbb` of a colour in [0, 1] (clamped).
fn hex(color: [f32; 3]) -> String {
    let [r, g, b] = color.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8);
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
}
