//! What the exact renderer and the SVG writer fill: a model's [`Path`] (four cubics) or a
//! [`Polygon`] (any number of straight edges: a superpixel's outline traced along its pixels,
//! which one path can only approximate).

use std::fmt::Write;
use std::sync::Arc;

use common::{Bounds, PixelBox};
use tiny_skia::PathBuilder;

use crate::path::{Path, SEGMENTS};

/// A closed outline filled with one colour, in the unit square of a canvas.
pub trait Filled {
    /// Fill colour, RGB in [0, 1].
    fn color(&self) -> [f32; 3];
    /// Opacity in [0, 1]; 0 means invisible.
    fn alpha(&self) -> f32;
    /// Whether every coordinate, the colour and the opacity are finite numbers.
    fn is_finite(&self) -> bool;
    /// A rectangle containing the whole outline; `None` if a coordinate is not finite.
    fn bounds(&self) -> Option<Bounds>;
    /// The outline as tiny-skia geometry in unit-square coordinates, whatever the opacity;
    /// `None` when it is not finite or encloses nothing.
    fn geometry(&self) -> Option<tiny_skia::Path>;
    /// SVG path data (`M…Z`) of the outline scaled by `scale` = (width, height), each number
    /// written by `number`.
    fn svg_data(&self, scale: [f32; 2], number: &dyn Fn(f32) -> String) -> String;

    /// The pixels the outline can change on a `width × height` canvas ([`Bounds::pixels`]);
    /// `None` when there are none or a coordinate is not finite.
    fn pixel_box(&self, width: u32, height: u32) -> Option<PixelBox> {
        self.bounds()?.pixels(width, height)
    }
}

impl<T: Filled + ?Sized> Filled for &T {
    fn color(&self) -> [f32; 3] {
        (**self).color()
    }

    fn alpha(&self) -> f32 {
        (**self).alpha()
    }

    fn is_finite(&self) -> bool {
        (**self).is_finite()
    }

    fn bounds(&self) -> Option<Bounds> {
        (**self).bounds()
    }

    fn geometry(&self) -> Option<tiny_skia::Path> {
        (**self).geometry()
    }

    fn svg_data(&self, scale: [f32; 2], number: &dyn Fn(f32) -> String) -> String {
        (**self).svg_data(scale, number)
    }
}

impl Filled for Path {
    fn color(&self) -> [f32; 3] {
        self.color
    }

    fn alpha(&self) -> f32 {
        self.alpha
    }

    fn is_finite(&self) -> bool {
        self.points.iter().flatten().chain(&self.color).chain([&self.alpha]).all(|v| v.is_finite())
    }

    fn bounds(&self) -> Option<Bounds> {
        Bounds::of_points(&self.points)
    }

    fn geometry(&self) -> Option<tiny_skia::Path> {
        if !self.is_finite() {
            return None;
        }
        let mut builder = PathBuilder::new();
        let [x, y] = self.points[0];
        builder.move_to(x, y);
        for j in 0..SEGMENTS {
            let [_, [x1, y1], [x2, y2], [x, y]] = self.segment(j);
            builder.cubic_to(x1, y1, x2, y2, x, y);
        }
        builder.close();
        builder.finish()
    }

    fn svg_data(&self, [sx, sy]: [f32; 2], number: &dyn Fn(f32) -> String) -> String {
        let point = |[x, y]: [f32; 2]| format!("{} {}", number(x * sx), number(y * sy));
        let mut d = format!("M{}", point(self.points[0]));
        for j in 0..SEGMENTS {
            let [_, c1, c2, end] = self.segment(j);
            let _ = write!(d, "C{} {} {}", point(c1), point(c2), point(end));
        }
        d.push('Z');
        d
    }
}

/// A closed polygon filled with one colour, corners in the unit square of a canvas: a region
/// drawn exactly along its pixel edges.
#[derive(Clone, Debug, PartialEq)]
pub struct Polygon {
    corners: Vec<[f32; 2]>,
    /// Fill colour, RGB in [0, 1].
    pub color: [f32; 3],
    /// Opacity in [0, 1]; 0 means invisible.
    pub alpha: f32,
}

impl Polygon {
    /// The polygon through `corners` (closed back to the first); `None` with fewer than three.
    pub fn new(corners: Vec<[f32; 2]>, color: [f32; 3], alpha: f32) -> Option<Self> {
        (corners.len() >= 3).then_some(Self { corners, color, alpha })
    }

    /// Its corners, in order.
    pub fn corners(&self) -> &[[f32; 2]] {
        &self.corners
    }
}

impl Filled for Polygon {
    fn color(&self) -> [f32; 3] {
        self.color
    }

    fn alpha(&self) -> f32 {
        self.alpha
    }

    fn is_finite(&self) -> bool {
        self.corners.iter().flatten().chain(&self.color).chain([&self.alpha]).all(|v| v.is_finite())
    }

    fn bounds(&self) -> Option<Bounds> {
        Bounds::of_points(&self.corners)
    }

    fn geometry(&self) -> Option<tiny_skia::Path> {
        if !self.is_finite() {
            return None;
        }
        let mut builder = PathBuilder::new();
        let [x, y] = self.corners[0];
        builder.move_to(x, y);
        for &[x, y] in &self.corners[1..] {
            builder.line_to(x, y);
        }
        builder.close();
        builder.finish()
    }

    /// Axis-aligned edges (a traced outline has only those) are written `H`/`V`, the others `L`.
    fn svg_data(&self, [sx, sy]: [f32; 2], number: &dyn Fn(f32) -> String) -> String {
        let [x, y] = self.corners[0];
        let mut d = format!("M{} {}", number(x * sx), number(y * sy));
        for pair in self.corners.windows(2) {
            let ([x0, y0], [x, y]) = (pair[0], pair[1]);
            let _ = match (x == x0, y == y0) {
                (false, true) => write!(d, "H{}", number(x * sx)),
                (true, false) => write!(d, "V{}", number(y * sy)),
                _ => write!(d, "L{} {}", number(x * sx), number(y * sy)),
            };
        }
        d.push('Z');
        d
    }
}

/// A shape of a drawing: a path or a polygon (shared, so that copying a drawing is cheap).
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// Four cubics, as the models draw and fine-tuning moves.
    Path(Path),
    /// Straight edges, as a region's outline is traced.
    Polygon(Arc<Polygon>),
}

impl Shape {
    fn filled(&self) -> &dyn Filled {
        match self {
            Shape::Path(path) => path,
            Shape::Polygon(polygon) => polygon.as_ref(),
        }
    }
}

impl From<Path> for Shape {
    fn from(path: Path) -> Self {
        Shape::Path(path)
    }
}

impl From<Polygon> for Shape {
    fn from(polygon: Polygon) -> Self {
        Shape::Polygon(Arc::new(polygon))
    }
}

impl Filled for Shape {
    fn color(&self) -> [f32; 3] {
        self.filled().color()
    }

    fn alpha(&self) -> f32 {
        self.filled().alpha()
    }

    fn is_finite(&self) -> bool {
        self.filled().is_finite()
    }

    fn bounds(&self) -> Option<Bounds> {
        self.filled().bounds()
    }

    fn geometry(&self) -> Option<tiny_skia::Path> {
        self.filled().geometry()
    }

    fn svg_data(&self, scale: [f32; 2], number: &dyn Fn(f32) -> String) -> String {
        self.filled().svg_data(scale, number)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_polygon_needs_three_corners_and_writes_axis_edges_short() {
        assert!(Polygon::new(vec![[0.0, 0.0], [1.0, 0.0]], [0.0; 3], 1.0).is_none());
        let l =
            Polygon::new(vec![[0.0, 0.0], [0.5, 0.0], [0.5, 0.5], [0.25, 1.0], [0.0, 1.0]], [0.0; 3], 1.0)
                .unwrap();
        let number = |v: f32| format!("{v}");
        assert_eq!(l.svg_data([4.0, 2.0], &number), "M0 0H2V1L1 2H0Z");
        assert_eq!(l.pixel_box(4, 2), PixelBox::new(0, 0, 3, 2)); // x up to 2 px, widened by one
        let broken = Polygon::new(vec![[0.0, 0.0], [f32::NAN, 0.0], [0.0, 1.0]], [0.0; 3], 1.0).unwrap();
        assert!(broken.geometry().is_none() && broken.pixel_box(4, 2).is_none());
    }

    #[test]
    fn a_shape_is_what_it_wraps() {
        let path = Path::quadrilateral([[0.1, 0.1], [0.9, 0.1], [0.9, 0.9], [0.1, 0.9]], [0.2; 3], 0.5);
        let shape = Shape::from(path);
        assert_eq!(shape, Shape::Path(path));
        assert_eq!((shape.color(), shape.alpha(), shape.bounds()), (path.color, path.alpha, path.bounds()));
        let polygon = Polygon::new(vec![[0.1, 0.1], [0.9, 0.1], [0.9, 0.9]], [0.3; 3], 1.0).unwrap();
        let shape = Shape::from(polygon.clone());
        assert_eq!((shape.color(), shape.bounds()), (polygon.color, polygon.bounds()));
    }
}
