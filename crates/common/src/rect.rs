//! Axis-aligned rectangles whose corners are in order: the pixel box of a region or of a path
//! ([`PixelBox`]) and the bounds of an outline in a canvas's unit square ([`Bounds`]).

use std::ops::{Range, Sub};

/// The rectangle from `(x0, y0)` to `(x1, y1)` with `x0 ≤ x1` and `y0 ≤ y1`: made only by
/// [`Rect::new`] and the methods here, so no box is ever inverted, and none holds a NaN.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Rect<T> {
    x0: T,
    y0: T,
    x1: T,
    y1: T,
}

/// A half-open pixel rectangle `[x0, x1) × [y0, y1)` (columns, rows).
pub type PixelBox = Rect<u32>;

/// A closed rectangle `[x0, x1] × [y0, y1]` in the unit square of a canvas, finite.
pub type Bounds = Rect<f32>;

impl<T: Copy + PartialOrd> Rect<T> {
    /// The rectangle with these corners; `None` when they are out of order (or one is NaN).
    pub fn new(x0: T, y0: T, x1: T, y1: T) -> Option<Self> {
        (x0 <= x1 && y0 <= y1).then_some(Self { x0, y0, x1, y1 })
    }

    /// Left edge.
    pub fn x0(&self) -> T {
        self.x0
    }

    /// Top edge.
    pub fn y0(&self) -> T {
        self.y0
    }

    /// Right edge.
    pub fn x1(&self) -> T {
        self.x1
    }

    /// Bottom edge.
    pub fn y1(&self) -> T {
        self.y1
    }

    /// The smallest rectangle holding both.
    pub fn union(&self, other: &Self) -> Self {
        let (min, max) = (|a: T, b: T| if b < a { b } else { a }, |a: T, b: T| if b > a { b } else { a });
        Self {
            x0: min(self.x0, other.x0),
            y0: min(self.y0, other.y0),
            x1: max(self.x1, other.x1),
            y1: max(self.y1, other.y1),
        }
    }
}

impl<T: Copy + PartialOrd + Sub<Output = T>> Rect<T> {
    /// `x1 − x0`.
    pub fn width(&self) -> T {
        self.x1 - self.x0
    }

    /// `y1 − y0`.
    pub fn height(&self) -> T {
        self.y1 - self.y0
    }
}

impl PixelBox {
    /// The one pixel `(x, y)`.
    pub fn pixel(x: u32, y: u32) -> Self {
        Self { x0: x, y0: y, x1: x + 1, y1: y + 1 }
    }

    /// The whole `width × height` image.
    pub fn image(width: u32, height: u32) -> Self {
        Self { x0: 0, y0: 0, x1: width, y1: height }
    }

    /// The box grown to hold pixel `(x, y)`.
    pub fn including(&self, x: u32, y: u32) -> Self {
        self.union(&Self::pixel(x, y))
    }

    /// Whether the box holds no pixel.
    pub fn is_empty(&self) -> bool {
        self.x0 == self.x1 || self.y0 == self.y1
    }

    /// Number of pixels.
    pub fn area(&self) -> u64 {
        u64::from(self.width()) * u64::from(self.height())
    }

    /// Its columns.
    pub fn columns(&self) -> Range<u32> {
        self.x0..self.x1
    }

    /// Its rows.
    pub fn rows(&self) -> Range<u32> {
        self.y0..self.y1
    }

    /// The pixels both boxes hold; `None` when they share none.
    pub fn intersection(&self, other: &Self) -> Option<Self> {
        let (x0, y0) = (self.x0.max(other.x0), self.y0.max(other.y0));
        let (x1, y1) = (self.x1.min(other.x1), self.y1.min(other.y1));
        (x0 < x1 && y0 < y1).then_some(Self { x0, y0, x1, y1 })
    }

    /// The box grown by `padding` pixels on every side, within a `width × height` image.
    pub fn padded(&self, padding: u32, width: u32, height: u32) -> Self {
        Self {
            x0: self.x0.saturating_sub(padding),
            y0: self.y0.saturating_sub(padding),
            x1: self.x1.saturating_add(padding).min(width).max(self.x0.saturating_sub(padding)),
            y1: self.y1.saturating_add(padding).min(height).max(self.y0.saturating_sub(padding)),
        }
    }
}

impl Bounds {
    /// The bounds of `points`; `None` when there are none or a coordinate is not finite.
    pub fn of_points<'a>(points: impl IntoIterator<Item = &'a [f32; 2]>) -> Option<Self> {
        let mut bounds: Option<Self> = None;
        for &[x, y] in points {
            if !(x.is_finite() && y.is_finite()) {
                return None;
            }
            let point = Self { x0: x, y0: y, x1: x, y1: y };
            bounds = Some(bounds.map_or(point, |b| b.union(&point)));
        }
        bounds
    }

    /// The pixels of a `width × height` canvas whose colour an outline within these bounds can
    /// change: the bounds scaled to the canvas, widened by a pixel for anti-aliasing, within the
    /// canvas; `None` when no pixel is left.
    pub fn pixels(&self, width: u32, height: u32) -> Option<PixelBox> {
        let scale = |v: f32, size: u32| v * size as f32;
        let (x0, y0) = (scale(self.x0, width).floor() - 1.0, scale(self.y0, height).floor() - 1.0);
        let (x1, y1) = (scale(self.x1, width).ceil() + 1.0, scale(self.y1, height).ceil() + 1.0);
        let clamp = |v: f32, size: u32| if v.is_finite() { v.clamp(0.0, size as f32) as u32 } else { 0 };
        let [x0, y0, x1, y1] = [clamp(x0, width), clamp(y0, height), clamp(x1, width), clamp(y1, height)];
        (x0 < x1 && y0 < y1).then_some(PixelBox { x0, y0, x1, y1 })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corners_out_of_order_or_nan_make_no_box() {
        assert!(PixelBox::new(3, 0, 2, 5).is_none());
        assert!(Bounds::new(0.0, f32::NAN, 1.0, 1.0).is_none());
        assert!(Bounds::of_points(&[[0.0, 0.0], [f32::INFINITY, 1.0]]).is_none());
        assert!(Bounds::of_points(&[]).is_none());
        let b = PixelBox::new(2, 3, 2, 9).unwrap();
        assert!(b.is_empty() && b.area() == 0);
    }

    #[test]
    fn pixel_boxes_grow_pad_and_intersect() {
        let b = PixelBox::pixel(4, 5).including(1, 9);
        assert_eq!((b.x0(), b.y0(), b.x1(), b.y1()), (1, 5, 5, 10));
        assert_eq!((b.width(), b.height(), b.area()), (4, 5, 20));
        assert_eq!(b.padded(2, 6, 11), PixelBox::new(0, 3, 6, 11).unwrap());
        let other = PixelBox::new(4, 0, 8, 6).unwrap();
        assert_eq!(b.intersection(&other), PixelBox::new(4, 5, 5, 6));
        assert_eq!(b.intersection(&PixelBox::new(5, 0, 8, 6).unwrap()), None);
        assert_eq!(b.columns().len() * b.rows().len(), 20);
    }

    #[test]
    fn bounds_become_the_pixels_they_can_touch() {
        let bounds = Bounds::of_points(&[[0.1, 0.2], [0.5, 0.25]]).unwrap();
        assert_eq!((bounds.width(), bounds.x1()), (0.4, 0.5));
        // 10 × 20 canvas: x 1..5 px, y 4..5 px, widened by one and clamped.
        assert_eq!(bounds.pixels(10, 20), PixelBox::new(0, 3, 6, 6));
        let outside = Bounds::new(2.0, 2.0, 3.0, 3.0).unwrap();
        assert_eq!(outside.pixels(10, 10), None);
    }
}
