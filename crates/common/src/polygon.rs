//! Closed polygons as lists of corners.

/// The area a closed polygon encloses (shoelace formula), signed: positive when it turns
/// clockwise on screen (y down). Self-overlapping parts count with their winding.
pub fn signed_area(points: &[[f32; 2]]) -> f32 {
    let n = points.len();
    let twice: f32 = (0..n)
        .map(|i| {
            let (a, b) = (points[i], points[(i + 1) % n]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum();
    twice / 2.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clockwise_on_screen_is_positive() {
        let square = [[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]];
        assert_eq!(signed_area(&square), 4.0);
        let mut backwards = square;
        backwards.reverse();
        assert_eq!(signed_area(&backwards), -4.0);
        assert_eq!(signed_area(&[[1.0, 1.0]]), 0.0);
    }
}
