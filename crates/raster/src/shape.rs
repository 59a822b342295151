//! What the exact renderer and the SVG writer fill: a model's [`Path`] (four cubics) or an
//! [`Outline`] (contours of any number of lines and cubics: superpixels drawn along the
//! boundaries they share, which one path can only approximate).

use std::sync::Arc;

use common::{Bounds, PixelBox, signed_area};
use tiny_skia::PathBuilder;

use crate::decimals::Decimals;
use crate::fill::Fill;
use crate::geometry::{cubic_point, straight_cubic};
use crate::path::{POINTS, Path, SEGMENTS};

/// A closed outline and its paint, in the unit square of a canvas.
pub trait Filled {
    /// The one colour that stands for its paint ([`Fill::color`]), RGB in [0, 1]: what a
    /// consumer that fills with one colour uses.
    fn color(&self) -> [f32; 3];
    /// Its paint: one colour unless the shape carries a ramp.
    fn fill(&self) -> Fill {
        Fill::Solid(self.color())
    }
    /// Opacity in [0, 1]; 0 means invisible.
    fn alpha(&self) -> f32;
    /// Whether every coordinate, the colour and the opacity are finite numbers.
    fn is_finite(&self) -> bool;
    /// A rectangle containing the whole outline; `None` if a coordinate is not finite.
    fn bounds(&self) -> Option<Bounds>;
    /// The outline as tiny-skia geometry in unit-square coordinates, whatever the opacity;
    /// `None` when it is not finite or encloses nothing.
    fn geometry(&self) -> Option<tiny_skia::Path>;
    /// Writes SVG path data (`M…Z`) of the outline scaled by `scale` = (width, height) to
    /// `out`, numbers rounded to `decimals`.
    fn svg_data(&self, scale: [f32; 2], decimals: Decimals, out: &mut String);

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

    fn fill(&self) -> Fill {
        (**self).fill()
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

    fn svg_data(&self, scale: [f32; 2], decimals: Decimals, out: &mut String) {
        (**self).svg_data(scale, decimals, out)
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

    fn svg_data(&self, [sx, sy]: [f32; 2], decimals: Decimals, out: &mut String) {
        let mut point = |[x, y]: [f32; 2], before: char| {
            out.push(before);
            decimals.write(out, decimals.ticks(x * sx), false);
            out.push(' ');
            decimals.write(out, decimals.ticks(y * sy), false);
        };
        point(self.points[0], 'M');
        for j in 0..SEGMENTS {
            let [_, c1, c2, end] = self.segment(j);
            point(c1, 'C');
            point(c2, ' ');
            point(end, ' ');
        }
        out.push('Z');
    }
}

impl Path {
    /// Its four cubics as the window samples them ([`Path::segment`]'s points).
    pub(crate) fn pieces(&self) -> Vec<Piece> {
        (0..SEGMENTS)
            .map(|j| Piece {
                control: self.segment(j),
                indices: PieceIndices::Cubic([0, 1, 2, 3].map(|k| (3 * j + k) % POINTS)),
            })
            .collect()
    }
}

/// A piece of an outline as the window samples it: its cubic (a line as its straight cubic)
/// and where its points lie among the shape's points.
pub(crate) struct Piece {
    pub control: [[f32; 2]; 4],
    pub indices: PieceIndices,
}

/// Where a piece's points lie among its shape's points: a cubic's four, a line's two ends.
pub(crate) enum PieceIndices {
    Cubic([usize; 4]),
    Line([usize; 2]),
}

/// One piece of a [`Contour`], from where the previous piece ended: a straight edge or a cubic.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Segment {
    /// A straight edge to this point.
    Line([f32; 2]),
    /// A cubic with these two handles, to the last point.
    Cubic([f32; 2], [f32; 2], [f32; 2]),
}

impl Segment {
    /// Where it ends.
    pub fn end(&self) -> [f32; 2] {
        match *self {
            Segment::Line(end) | Segment::Cubic(_, _, end) => end,
        }
    }

    /// The same piece walked the other way, from its end to `start` (where it began): the same
    /// points, so a boundary shared by two outlines is the same curve in both.
    pub fn reversed(&self, start: [f32; 2]) -> Segment {
        match *self {
            Segment::Line(_) => Segment::Line(start),
            Segment::Cubic(c1, c2, _) => Segment::Cubic(c2, c1, start),
        }
    }

    /// Its points (handles and end) mapped by `f`.
    pub fn map(&self, f: impl Fn([f32; 2]) -> [f32; 2]) -> Segment {
        match *self {
            Segment::Line(end) => Segment::Line(f(end)),
            Segment::Cubic(c1, c2, end) => Segment::Cubic(f(c1), f(c2), f(end)),
        }
    }

    fn points(&self) -> impl Iterator<Item = [f32; 2]> {
        let (points, count) = match *self {
            Segment::Line(end) => ([end, end, end], 1),
            Segment::Cubic(c1, c2, end) => ([c1, c2, end], 3),
        };
        points.into_iter().take(count)
    }
}

/// A closed figure: a start point and the pieces that lead back to it.
#[derive(Clone, Debug, PartialEq)]
pub struct Contour {
    /// Where it starts and ends.
    pub start: [f32; 2],
    /// Its pieces in order; the last ends at `start`.
    pub segments: Vec<Segment>,
}

impl Contour {
    /// Its points in order, cubics cut into `steps` straight edges (start included, the closing
    /// point left out): the contour as a polygon.
    pub fn flatten(&self, steps: usize) -> Vec<[f32; 2]> {
        let steps = steps.max(1);
        let mut points = vec![self.start];
        let mut at = self.start;
        for segment in &self.segments {
            if let Segment::Cubic(c1, c2, end) = *segment {
                let control = [at, c1, c2, end];
                points.extend((1..steps).map(|i| cubic_point(&control, i as f32 / steps as f32)));
            }
            at = segment.end();
            points.push(at);
        }
        points.pop();
        points
    }

    fn points(&self) -> impl Iterator<Item = [f32; 2]> + '_ {
        std::iter::once(self.start).chain(self.segments.iter().flat_map(Segment::points))
    }
}

/// Closed contours filled together with one [`Fill`] (nonzero rule: a contour winding the other
/// way is a hole), in the unit square of a canvas: a region, or a set of regions, drawn along
/// the boundary curves it shares with its neighbours.
#[derive(Clone, Debug, PartialEq)]
pub struct Outline {
    contours: Vec<Contour>,
    /// The hull of every point, found once: scenes ask for it at every repaint.
    bounds: Option<Bounds>,
    /// Its paint (ramp points in the unit square, like the contours).
    pub fill: Fill,
    /// Opacity in [0, 1]; 0 means invisible.
    pub alpha: f32,
}

impl Outline {
    /// The outline of `contours`; `None` without a contour of at least two pieces (one piece
    /// encloses nothing).
    pub fn new(contours: Vec<Contour>, fill: impl Into<Fill>, alpha: f32) -> Option<Self> {
        let fill = fill.into();
        let contours: Vec<Contour> = contours.into_iter().filter(|c| !c.segments.is_empty()).collect();
        // A cubic lies within its control points' hull.
        let points: Vec<[f32; 2]> = contours.iter().flat_map(Contour::points).collect();
        let bounds = Bounds::of_points(&points);
        contours.iter().any(|c| c.segments.len() >= 2).then_some(Self { contours, bounds, fill, alpha })
    }

    /// The polygon through `corners` (closed back to the first); `None` with fewer than three.
    pub fn polygon(corners: &[[f32; 2]], fill: impl Into<Fill>, alpha: f32) -> Option<Self> {
        if corners.len() < 3 {
            return None;
        }
        let segments = corners[1..].iter().chain(&corners[..1]).map(|&p| Segment::Line(p)).collect();
        Self::new(vec![Contour { start: corners[0], segments }], fill, alpha)
    }

    /// `path`'s outline (its four cubics) filled with `fill`: a path that paints something other
    /// than one colour, as fine-tuning returns a ramped region. `None` when a number is not finite.
    pub fn from_path(path: &Path, fill: impl Into<Fill>) -> Option<Self> {
        if !path.is_finite() {
            return None;
        }
        let segments = (0..SEGMENTS)
            .map(|j| {
                let [_, c1, c2, end] = path.segment(j);
                Segment::Cubic(c1, c2, end)
            })
            .collect();
        Self::new(vec![Contour { start: path.points[0], segments }], fill, path.alpha)
    }

    /// The points that shape it, in order: each contour's start, then the handles and end of
    /// each of its pieces, the last piece's end left out (it is the start). What fine-tuning
    /// moves, in the order of [`crate::Window::l2_gradient_outlines`]' gradient.
    pub fn points(&self) -> Vec<[f32; 2]> {
        let mut points = Vec::new();
        for contour in &self.contours {
            points.push(contour.start);
            for segment in &contour.segments {
                points.extend(segment.points());
            }
            points.pop();
        }
        points
    }

    /// The same pieces, fill and opacity through `points` ([`Self::points`]' order).
    ///
    /// # Panics
    /// If `points` does not hold as many points as [`Self::points`].
    pub fn with_points(&self, points: &[[f32; 2]]) -> Self {
        assert_eq!(points.len(), self.point_count(), "one point per point of the outline");
        let contours: Vec<Contour> = (self.contours.iter().zip(self.layout()))
            .map(|(contour, (start, pieces))| Contour {
                start: points[start],
                segments: (contour.segments.iter().zip(pieces))
                    .map(|(segment, (handles, end))| match (segment, handles) {
                        (Segment::Cubic(..), Some([c1, c2])) => {
                            Segment::Cubic(points[c1], points[c2], points[end])
                        }
                        _ => Segment::Line(points[end]),
                    })
                    .collect(),
            })
            .collect();
        let bounds = Bounds::of_points(&contours.iter().flat_map(Contour::points).collect::<Vec<_>>());
        Self { contours, bounds, ..*self }
    }

    /// How many points [`Self::points`] holds: each contour's start and its pieces' points,
    /// but the last piece's end (the start again).
    pub(crate) fn point_count(&self) -> usize {
        let count = |segment: &Segment| match segment {
            Segment::Line(_) => 1,
            Segment::Cubic(..) => 3,
        };
        self.contours.iter().map(|c| c.segments.iter().map(count).sum::<usize>()).sum()
    }

    /// Its pieces as the window samples them, with where their points lie in [`Self::points`].
    pub(crate) fn pieces(&self) -> Vec<Piece> {
        let mut pieces = Vec::new();
        for (contour, (start, layout)) in self.contours.iter().zip(self.layout()) {
            let (mut at, mut at_index) = (contour.start, start);
            for (segment, (handles, end)) in contour.segments.iter().zip(layout) {
                let (control, indices) = match (*segment, handles) {
                    (Segment::Cubic(c1, c2, to), Some([h1, h2])) => {
                        ([at, c1, c2, to], PieceIndices::Cubic([at_index, h1, h2, end]))
                    }
                    _ => (straight_cubic(at, segment.end()), PieceIndices::Line([at_index, end])),
                };
                pieces.push(Piece { control, indices });
                (at, at_index) = (segment.end(), end);
            }
        }
        pieces
    }

    /// Where each contour's points lie in [`Self::points`]: its start's index, and per piece
    /// its handles' (a cubic's) and its end's, the last piece's end being the start's. The one
    /// place that layout is laid down.
    fn layout(&self) -> Vec<(usize, Vec<(Option<[usize; 2]>, usize)>)> {
        let mut next = 0;
        let mut take = || {
            next += 1;
            next - 1
        };
        self.contours
            .iter()
            .map(|contour| {
                let start = take();
                let last = contour.segments.len() - 1;
                let pieces = (contour.segments.iter().enumerate())
                    .map(|(index, segment)| {
                        let handles = matches!(segment, Segment::Cubic(..)).then(|| [take(), take()]);
                        (handles, if index == last { start } else { take() })
                    })
                    .collect();
                (start, pieces)
            })
            .collect()
    }

    /// The same outline with each contour of straight pieces only simplified to the fewest
    /// corners within `tolerance` pixels of it (Douglas–Peucker) on a `width × height` canvas:
    /// what a traced staircase moved onto a slanted edge needs of its corners. Contours with a
    /// cubic, and any that would keep fewer than three corners, stay as they are.
    pub fn simplified(&self, tolerance: f32, (width, height): (u32, u32)) -> Self {
        let (w, h) = (width as f32, height as f32);
        let contours: Vec<Contour> = (self.contours.iter())
            .map(|contour| {
                let straight = contour.segments.iter().all(|s| matches!(s, Segment::Line(_)));
                if !straight || contour.segments.len() < 4 {
                    return contour.clone();
                }
                let ring: Vec<[f32; 2]> =
                    (contour.points().take(contour.segments.len())).map(|p| [p[0] * w, p[1] * h]).collect();
                let kept: Vec<[f32; 2]> = (corners(&ring, tolerance).into_iter())
                    .map(|k| [ring[k][0] / w, ring[k][1] / h])
                    .collect();
                if kept.len() < 3 {
                    return contour.clone();
                }
                let segments = kept[1..].iter().chain(&kept[..1]).map(|&p| Segment::Line(p)).collect();
                Contour { start: kept[0], segments }
            })
            .collect();
        Self::new(contours, self.fill, self.alpha).unwrap_or_else(|| self.clone())
    }

    /// Its contours.
    pub fn contours(&self) -> &[Contour] {
        &self.contours
    }

    /// The contour enclosing the most area ([`Contour::flatten`] with `steps` edges a cubic):
    /// what one path can approximate of the outline.
    pub fn largest_contour(&self, steps: usize) -> Vec<[f32; 2]> {
        self.contours
            .iter()
            .map(|c| c.flatten(steps))
            .max_by(|a, b| signed_area(a).abs().total_cmp(&signed_area(b).abs()))
            .unwrap_or_default()
    }
}

impl Filled for Outline {
    fn color(&self) -> [f32; 3] {
        self.fill.color()
    }

    fn fill(&self) -> Fill {
        self.fill
    }

    fn alpha(&self) -> f32 {
        self.alpha
    }

    fn is_finite(&self) -> bool {
        let points = self.contours.iter().flat_map(Contour::points).flatten();
        points.chain([self.alpha]).all(f32::is_finite) && self.fill.is_finite()
    }

    fn bounds(&self) -> Option<Bounds> {
        self.bounds
    }

    fn geometry(&self) -> Option<tiny_skia::Path> {
        if !self.is_finite() {
            return None;
        }
        let mut builder = PathBuilder::new();
        for contour in &self.contours {
            builder.move_to(contour.start[0], contour.start[1]);
            for segment in &contour.segments {
                match *segment {
                    Segment::Line([x, y]) => builder.line_to(x, y),
                    Segment::Cubic([x1, y1], [x2, y2], [x, y]) => builder.cubic_to(x1, y1, x2, y2, x, y),
                }
            }
            builder.close();
        }
        builder.finish()
    }

    /// Each contour starts with an absolute `M`; its pieces are relative (`h`, `v`, `l`, `c`)
    /// to the rounded point before them, so they add up to the rounded points exactly; the last
    /// piece, which ends at the start, is `z` alone when it is straight.
    fn svg_data(&self, [sx, sy]: [f32; 2], decimals: Decimals, out: &mut String) {
        let ticks = |[x, y]: [f32; 2]| [decimals.ticks(x * sx), decimals.ticks(y * sy)];
        for contour in &self.contours {
            let mut at = ticks(contour.start);
            out.push('M');
            Numbers::new(out, decimals).write(&at);
            let last = contour.segments.len() - 1;
            for (index, segment) in contour.segments.iter().enumerate() {
                let delta = |p: [f32; 2]| {
                    let p = ticks(p);
                    [p[0] - at[0], p[1] - at[1]]
                };
                let end = delta(segment.end());
                let (command, values) = match *segment {
                    Segment::Line(_) if index == last => (None, &[][..]),
                    Segment::Line(_) if end[1] == 0 => (Some('h'), &end[..1]),
                    Segment::Line(_) if end[0] == 0 => (Some('v'), &end[1..]),
                    Segment::Line(_) => (Some('l'), &end[..]),
                    Segment::Cubic(c1, c2, _) => {
                        let (c1, c2) = (delta(c1), delta(c2));
                        out.push('c');
                        Numbers::new(out, decimals).write(&[c1[0], c1[1], c2[0], c2[1], end[0], end[1]]);
                        (None, &[][..])
                    }
                };
                if let Some(command) = command {
                    out.push(command);
                    Numbers::new(out, decimals).write(values);
                }
                at = ticks(segment.end());
            }
            out.push('z');
        }
    }
}

/// The indices of the corners of the closed polygon `ring` that Douglas–Peucker keeps within
/// `tolerance`, in order: the first corner and the one farthest from it split the ring in two
/// open runs, each simplified alone.
fn corners(ring: &[[f32; 2]], tolerance: f32) -> Vec<usize> {
    let distance2 = |a: [f32; 2], b: [f32; 2]| (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2);
    let far =
        (1..ring.len()).max_by(|&a, &b| distance2(ring[0], ring[a]).total_cmp(&distance2(ring[0], ring[b])));
    let Some(far) = far else { return (0..ring.len()).collect() };
    let mut keep = vec![false; ring.len() + 1];
    (keep[0], keep[far], keep[ring.len()]) = (true, true, true);
    let closed: Vec<[f32; 2]> = ring.iter().chain(&ring[..1]).copied().collect();
    mark_corners(&closed, 0, far, tolerance, &mut keep);
    mark_corners(&closed, far, ring.len(), tolerance, &mut keep);
    (0..ring.len()).filter(|&k| keep[k]).collect()
}

/// Douglas–Peucker between `points[from]` and `points[to]` (both kept): marks in `keep` the
/// corners farther than `tolerance` from the chord, and recursively those between them.
fn mark_corners(points: &[[f32; 2]], from: usize, to: usize, tolerance: f32, keep: &mut [bool]) {
    if to <= from + 1 {
        return;
    }
    let (a, b) = (points[from], points[to]);
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let length = dx.hypot(dy);
    let distance = |p: [f32; 2]| match length < 1e-6 {
        true => (p[0] - a[0]).hypot(p[1] - a[1]),
        false => ((p[0] - a[0]) * dy - (p[1] - a[1]) * dx).abs() / length,
    };
    let (worst, d) = (from + 1..to)
        .map(|k| (k, distance(points[k])))
        .fold((from, -1.0), |m, x| if x.1 > m.1 { x } else { m });
    if d > tolerance {
        keep[worst] = true;
        mark_corners(points, from, worst, tolerance, keep);
        mark_corners(points, worst, to, tolerance, keep);
    }
}

/// Numbers after a path command, written as SVG path data allows them shortest: `0.5` as `.5`,
/// and no space before a minus sign or before a point that cannot continue the number before it.
struct Numbers<'a> {
    out: &'a mut String,
    decimals: Decimals,
}

impl<'a> Numbers<'a> {
    fn new(out: &'a mut String, decimals: Decimals) -> Self {
        Self { out, decimals }
    }

    /// Writes `values` (ticks of [`Decimals`]) one after the other.
    fn write(self, values: &[i64]) {
        let unit = self.decimals.ticks(1.0);
        let mut previous_has_point = false;
        for (i, &value) in values.iter().enumerate() {
            let has_point = value % unit != 0;
            let starts_with_point = has_point && value.abs() < unit;
            let joins = value < 0 || (starts_with_point && previous_has_point);
            if i > 0 && !joins {
                self.out.push(' ');
            }
            previous_has_point = has_point;
            self.decimals.write(self.out, value, true);
        }
    }
}

/// A shape of a drawing: a path or an outline (shared, so that copying a drawing is cheap).
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// Four cubics, as the models draw and fine-tuning moves.
    Path(Path),
    /// Contours of lines and cubics, as a region's boundary is traced and fitted.
    Outline(Arc<Outline>),
}

impl Shape {
    /// The shape as an outline (a path's four cubics as one contour, in its colour): what
    /// moves an outline's points takes. `None` for a path with a number that is not finite.
    pub fn to_outline(&self) -> Option<Outline> {
        match self {
            Shape::Path(path) => Outline::from_path(path, path.color),
            Shape::Outline(outline) => Some((**outline).clone()),
        }
    }

    /// The same shape filled with `fill` (a path given a ramp becomes its outline, which can
    /// hold one); `None` for a path with a number that is not finite given a ramp.
    pub fn with_fill(&self, fill: Fill) -> Option<Shape> {
        match (self, fill) {
            (Shape::Path(path), Fill::Solid(color)) => Some(Shape::Path(Path { color, ..*path })),
            (Shape::Path(_), Fill::Linear(_)) | (Shape::Outline(_), _) => {
                let mut outline = self.to_outline()?;
                outline.fill = fill;
                Some(outline.into())
            }
        }
    }

    /// The shape as an SVG of a canvas of `size` = (width, height) pixels writes it with
    /// `decimals` ([`crate::to_svg_with`]): every point rounded as written, the fill as
    /// [`Fill::as_written`], the opacity as `fill-opacity` writes it. What a measure of the
    /// drawing renders to score what the file shows.
    pub fn as_written(&self, [sx, sy]: [f32; 2], decimals: Decimals) -> Shape {
        let point = |[x, y]: [f32; 2]| [decimals.rounded(x * sx) / sx, decimals.rounded(y * sy) / sy];
        let alpha = |alpha: f32| if alpha >= 1.0 { alpha } else { decimals.rounded(alpha) };
        let fill = self.fill().as_written([sx, sy], decimals);
        match self {
            Shape::Path(path) => Shape::Path(Path {
                points: path.points.map(point),
                color: fill.color(),
                alpha: alpha(path.alpha),
            }),
            Shape::Outline(outline) => {
                let points: Vec<[f32; 2]> = outline.points().into_iter().map(point).collect();
                let mut written = outline.with_points(&points);
                (written.fill, written.alpha) = (fill, alpha(outline.alpha));
                written.into()
            }
        }
    }

    fn filled(&self) -> &dyn Filled {
        match self {
            Shape::Path(path) => path,
            Shape::Outline(outline) => outline.as_ref(),
        }
    }
}

impl From<Path> for Shape {
    fn from(path: Path) -> Self {
        Shape::Path(path)
    }
}

impl From<Outline> for Shape {
    fn from(outline: Outline) -> Self {
        Shape::Outline(Arc::new(outline))
    }
}

impl Filled for Shape {
    fn color(&self) -> [f32; 3] {
        self.filled().color()
    }

    fn fill(&self) -> Fill {
        self.filled().fill()
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

    fn svg_data(&self, scale: [f32; 2], decimals: Decimals, out: &mut String) {
        self.filled().svg_data(scale, decimals, out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The path data of `shape` at `scale`, with `decimals` decimals.
    fn data(shape: &impl Filled, scale: [f32; 2], decimals: usize) -> String {
        let mut out = String::new();
        shape.svg_data(scale, Decimals::new(decimals), &mut out);
        out
    }

    /// A triangle whose long side is traced as a staircase of unit steps: within 0.75 px (the
    /// steps' corners lie 0.71 px from the diagonal) it is the triangle again; within 0.3 px
    /// every step stays; an outline of cubics is left as it is.
    #[test]
    fn simplifying_a_staircase_keeps_the_corners_it_needs() {
        let mut corners = vec![[0.0, 0.0], [8.0, 0.0], [8.0, 8.0]];
        for k in (0..8).rev() {
            corners.extend([[k as f32, k as f32 + 1.0], [k as f32, k as f32]]);
        }
        corners.pop();
        let unit: Vec<[f32; 2]> = corners.iter().map(|p| [p[0] / 16.0, p[1] / 16.0]).collect();
        let stairs = Outline::polygon(&unit, [0.2, 0.4, 0.6], 0.5).unwrap();
        let triangle = stairs.simplified(0.75, (16, 16));
        assert_eq!(triangle.points(), vec![[0.0, 0.0], [0.5, 0.0], [0.5, 0.5]]);
        assert_eq!((triangle.fill, triangle.alpha), (stairs.fill, stairs.alpha));
        assert_eq!(stairs.simplified(0.3, (16, 16)), stairs);
        let path = Path {
            points: std::array::from_fn(|i| [0.1 + 0.05 * i as f32, 0.2]),
            color: [0.0; 3],
            alpha: 1.0,
        };
        let curved = Outline::from_path(&path, [0.0; 3]).unwrap();
        assert_eq!(curved.simplified(5.0, (16, 16)), curved);
    }

    #[test]
    fn a_polygon_needs_three_corners_and_writes_relative_edges_short() {
        assert!(Outline::polygon(&[[0.0, 0.0], [1.0, 0.0]], [0.0; 3], 1.0).is_none());
        let l =
            Outline::polygon(&[[0.0, 0.0], [0.5, 0.0], [0.5, 0.5], [0.25, 1.0], [0.0, 1.0]], [0.0; 3], 1.0)
                .unwrap();
        assert_eq!(data(&l, [4.0, 2.0], 6), "M0 0h2v1l-1 1h-1z");
        let half = Outline::polygon(&[[0.0, 0.0], [0.125, 0.0], [0.125, 0.25]], [0.0; 3], 1.0).unwrap();
        assert_eq!(data(&half, [4.0, 2.0], 6), "M0 0h.5v.5z");
        assert_eq!(l.pixel_box(4, 2), PixelBox::new(0, 0, 3, 2)); // x up to 2 px, widened by one
        let broken = Outline::polygon(&[[0.0, 0.0], [f32::NAN, 0.0], [0.0, 1.0]], [0.0; 3], 1.0).unwrap();
        assert!(broken.geometry().is_none() && broken.pixel_box(4, 2).is_none());
    }

    #[test]
    fn relative_pieces_add_up_to_the_rounded_points() {
        // A cubic contour and a square hole, written with two decimals at 100 px: read back
        // by resvg, the outline has the area it has here.
        let cubic = Contour {
            start: [0.1234, 0.1],
            segments: vec![
                Segment::Cubic([0.5, 0.0], [0.9, 0.05], [0.9, 0.5]),
                Segment::Line([0.9, 0.9]),
                Segment::Cubic([0.6, 0.95], [0.3, 0.95], [0.1, 0.9]),
                Segment::Line([0.1234, 0.1]),
            ],
        };
        let hole = Contour {
            start: [0.4, 0.4],
            segments: vec![
                Segment::Line([0.4, 0.6]),
                Segment::Line([0.6, 0.6]),
                Segment::Line([0.6, 0.4]),
                Segment::Line([0.4, 0.4]),
            ],
        };
        let outline = Outline::new(vec![cubic.clone(), hole], [0.5; 3], 1.0).unwrap();
        let d = data(&outline, [100.0, 100.0], 2);
        assert!(d.starts_with("M12.34 10c"), "{d}");
        assert_eq!(d.matches('M').count(), 2);
        let svg = format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"100\" height=\"100\"><path d=\"{d}\"/></svg>"
        );
        let tree = resvg::usvg::Tree::from_str(&svg, &resvg::usvg::Options::default()).unwrap();
        let mut read = resvg::tiny_skia::Pixmap::new(100, 100).unwrap();
        resvg::render(&tree, resvg::tiny_skia::Transform::identity(), &mut read.as_mut());
        let ours = crate::render_exact(&[outline.clone()], 100, 100, [1.0; 3]);
        let differing = read
            .pixels()
            .iter()
            .zip(ours.pixels())
            .filter(|(a, b)| a.alpha() > 128 && b.0[0] > 200 || a.alpha() < 127 && b.0[0] < 180)
            .count();
        assert!(differing <= 10, "{differing} pixels differ between resvg's reading and the outline");
        // The hole winds the other way: the filled area is the contour's less the hole's.
        let area = signed_area(&cubic.flatten(32)) - 0.04;
        let covered = ours.pixels().filter(|p| p.0[0] < 200).count() as f32 / 10_000.0;
        assert!((covered - area).abs() < 0.01, "{covered} vs {area}");
        let mut numbers = String::new();
        Numbers::new(&mut numbers, Decimals::new(2)).write(&[50, -25, 300, 75, -150, 0, 20]);
        assert_eq!(numbers, ".5-.25 3 .75-1.5 0 .2");
    }

    #[test]
    fn a_shape_is_what_it_wraps() {
        let path = Path::quadrilateral([[0.1, 0.1], [0.9, 0.1], [0.9, 0.9], [0.1, 0.9]], [0.2; 3], 0.5);
        let shape = Shape::from(path);
        assert_eq!(shape, Shape::Path(path));
        assert_eq!((shape.color(), shape.alpha(), shape.bounds()), (path.color, path.alpha, path.bounds()));
        let polygon = Outline::polygon(&[[0.1, 0.1], [0.9, 0.1], [0.9, 0.9]], [0.3; 3], 1.0).unwrap();
        let shape = Shape::from(polygon.clone());
        assert_eq!((shape.fill(), shape.bounds()), (polygon.fill, polygon.bounds()));
    }
}
