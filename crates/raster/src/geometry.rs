//! Geometry of paths on the CPU: evaluating, differentiating and flattening the cubics, the
//! straight cubic, the area a path encloses.
//!
//! The one owner of Bézier evaluation: the soft rasterizer's flattening matrix, the area a path
//! encloses and the fitting of outlines all take their weights from [`bernstein`], their
//! tangents from [`cubic_derivative`] and their straight segments from [`straight_cubic`].

/// The cubic Bernstein weights at `t`: `[(1−t)³, 3(1−t)²t, 3(1−t)t², t³]`.
pub fn bernstein(t: f32) -> [f32; 4] {
    let s = 1.0 - t;
    [s * s * s, 3.0 * s * s * t, 3.0 * s * t * t, t * t * t]
}

/// The point of the cubic with control points `control` at `t`.
pub fn cubic_point(control: &[[f32; 2]; 4], t: f32) -> [f32; 2] {
    let w = bernstein(t);
    let mut point = [0.0; 2];
    for (weight, p) in w.iter().zip(control) {
        point[0] += weight * p[0];
        point[1] += weight * p[1];
    }
    point
}

/// The derivative `dP/dt` of the cubic with control points `control` at `t` (its tangent, as
/// long as the curve's speed).
pub fn cubic_derivative(control: &[[f32; 2]; 4], t: f32) -> [f32; 2] {
    let s = 1.0 - t;
    let [p0, p1, p2, p3] = control;
    [0, 1].map(|d| 3.0 * (s * s * (p1[d] - p0[d]) + 2.0 * s * t * (p2[d] - p1[d]) + t * t * (p3[d] - p2[d])))
}

/// The cubic from `a` to `b` that is the straight segment between them, its handles at a third
/// and two thirds (so it is also evenly parameterized).
pub fn straight_cubic(a: [f32; 2], b: [f32; 2]) -> [[f32; 2]; 4] {
    let at = |t: f32| [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
    [a, at(1.0 / 3.0), at(2.0 / 3.0), b]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::path::Path;
    use crate::shape::Filled;

    fn square(lo: f32, hi: f32) -> Path {
        Path::quadrilateral([[lo, lo], [hi, lo], [hi, hi], [lo, hi]], [0.0; 3], 1.0)
    }

    #[test]
    fn area_of_squares_keeps_its_sign() {
        assert!((square(0.25, 0.75).signed_area() - 0.25).abs() < 1e-6);
        // The same outline walked backwards: anchors stay at multiples of three.
        let mut reversed = square(0.25, 0.75);
        reversed.points.reverse();
        reversed.points.rotate_right(1);
        assert!((reversed.signed_area() + 0.25).abs() < 1e-6);
    }

    #[test]
    fn flattening_passes_through_the_anchors_and_bounds_contain_it() {
        let mut path = square(0.1, 0.6);
        path.points[1] = [0.3, -0.2]; // bend the top edge upwards
        let polygon = path.flatten(8);
        assert_eq!(polygon.len(), 32);
        assert_eq!(polygon[0], path.points[0]);
        assert_eq!(polygon[8], path.points[3]);
        let bounds = path.bounds().unwrap();
        assert_eq!(bounds, common::Bounds::new(0.1, -0.2, 0.6, 0.6).unwrap());
        let inside = |v: f32, lo: f32, hi: f32| v >= lo - 1e-6 && v <= hi + 1e-6;
        assert!(
            polygon
                .iter()
                .all(|&[x, y]| inside(x, bounds.x0(), bounds.x1()) && inside(y, bounds.y0(), bounds.y1()))
        );
        let straight = straight_cubic([0.0, 3.0], [6.0, 0.0]);
        assert_eq!(cubic_point(&straight, 0.5), [3.0, 1.5]);
        assert_eq!(cubic_derivative(&straight, 0.2), [6.0, -3.0]);
        assert!(bernstein(0.3).iter().sum::<f32>() - 1.0 < 1e-6);
    }
}
