//! The outer outline of a region: the closed polygon along the pixel edges that separate it from
//! the rest of the image.

use crate::slic::Segmentation;

/// Headings along pixel edges in image coordinates (y down): east, south, west, north.
const STEPS: [(i64, i64); 4] = [(1, 0), (0, 1), (-1, 0), (0, -1)];

impl Segmentation {
    /// The outer boundary of `region` as a closed polygon through pixel corners, in pixels
    /// (corner (x, y) is the top-left corner of pixel (x, y)), walked clockwise on screen with
    /// the region on the right; only the corners where the boundary turns are listed.
    ///
    /// Regions are 4-connected (SLIC enforces it), so the boundary is one loop; holes (regions
    /// enclosed by this one) are not part of it. Pixels touching the region only at a corner are
    /// outside.
    ///
    /// # Panics
    /// If `region` is not a label of this segmentation.
    pub fn outline(&self, region: u32) -> Vec<[f32; 2]> {
        let bbox = self.regions[region as usize].bbox;
        let inside = |x: i64, y: i64| {
            x >= bbox.x0 as i64
                && y >= bbox.y0 as i64
                && x < bbox.x1 as i64
                && y < bbox.y1 as i64
                && self.label(x as u32, y as u32) == region
        };
        // The first pixel in row-major order lies on the outer boundary: start on its top edge,
        // heading east, the region below (on the right).
        let y = bbox.y0 as i64;
        let x = (bbox.x0 as i64..bbox.x1 as i64)
            .find(|&x| inside(x, y))
            .expect("every region has a pixel in its top row");
        let start = ((x, y), 0usize);
        let (mut corner, mut heading) = start;
        let mut polygon = Vec::new();
        loop {
            // The pixels on the right and on the left of the edge ahead.
            let (ahead_right, ahead_left) = match heading {
                0 => ((corner.0, corner.1), (corner.0, corner.1 - 1)),
                1 => ((corner.0 - 1, corner.1), (corner.0, corner.1)),
                2 => ((corner.0 - 1, corner.1 - 1), (corner.0 - 1, corner.1)),
                _ => ((corner.0, corner.1 - 1), (corner.0 - 1, corner.1 - 1)),
            };
            let turned = if !inside(ahead_right.0, ahead_right.1) {
                (heading + 1) % 4
            } else if inside(ahead_left.0, ahead_left.1) {
                (heading + 3) % 4
            } else {
                heading
            };
            if turned != heading || polygon.is_empty() {
                polygon.push([corner.0 as f32, corner.1 as f32]);
            }
            heading = turned;
            // The walk comes back up the first pixel's west edge and turns east at the start
            // corner: the loop is closed (the corner was listed first already).
            if (corner, heading) == start && polygon.len() > 1 {
                polygon.pop();
                break;
            }
            let (dx, dy) = STEPS[heading];
            corner = (corner.0 + dx, corner.1 + dy);
        }
        polygon
    }
}

#[cfg(test)]
mod tests {
    use image::Rgb32FImage;

    use super::*;

    fn segmentation(rows: &[&str]) -> Segmentation {
        let (width, height) = (rows[0].len() as u32, rows.len() as u32);
        let labels: Vec<u32> = rows.iter().flat_map(|row| row.bytes().map(|b| (b - b'0') as u32)).collect();
        let count = *labels.iter().max().unwrap() as usize + 1;
        Segmentation::from_labels(&Rgb32FImage::new(width, height), labels, count)
    }

    fn area(polygon: &[[f32; 2]]) -> f32 {
        (0..polygon.len())
            .map(|i| {
                let (a, b) = (polygon[i], polygon[(i + 1) % polygon.len()]);
                a[0] * b[1] - b[0] * a[1]
            })
            .sum::<f32>()
            / 2.0
    }

    #[test]
    fn a_rectangle_has_four_corners() {
        let seg = segmentation(&["0000", "0110", "0110", "0000"]);
        assert_eq!(seg.outline(1), vec![[1.0, 1.0], [3.0, 1.0], [3.0, 3.0], [1.0, 3.0]]);
        assert_eq!(seg.outline(0), vec![[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]]);
    }

    #[test]
    fn concave_shapes_and_diagonal_neighbours() {
        // An L: area 5 pixels.
        let seg = segmentation(&["100", "100", "111"]);
        let outline = seg.outline(1);
        assert_eq!(area(&outline), 5.0);
        assert_eq!(outline.len(), 6);
        // Region 1 touches a pixel of itself only diagonally? Not possible when 4-connected,
        // but the outline must still close around the 4-connected part it starts from.
        let seg = segmentation(&["1100", "1111", "0011"]);
        assert_eq!(area(&seg.outline(1)), 8.0);
        // The region around a hole: the outline is the outer boundary only.
        let seg = segmentation(&["1111", "1001", "1111"]);
        assert_eq!(area(&seg.outline(1)), 12.0);
        assert_eq!(area(&seg.outline(0)), 2.0);
    }

    #[test]
    fn limiting_merges_the_most_alike_neighbours() {
        // Regions 0 and 1 are both black, 2 is white, 3 is black but only touches 2.
        let seg = segmentation(&["0011", "0011", "2222", "3333"]);
        let image = Rgb32FImage::from_fn(4, 4, |_, y| image::Rgb(if y == 2 { [1.0; 3] } else { [0.0; 3] }));
        let seg = Segmentation::from_labels(&image, seg.labels, 4);
        let limited = seg.clone().limit_regions(&image, 3, 0.0);
        assert_eq!(limited.regions.len(), 3);
        assert_eq!(limited.label(0, 0), limited.label(3, 0), "the two black neighbours merged");
        assert_ne!(limited.label(0, 3), limited.label(0, 0), "black 3 does not touch them");
        assert_eq!(seg.clone().limit_regions(&image, 9, 0.0), seg);
        let one = seg.limit_regions(&image, 1, 0.5);
        assert_eq!(one.regions.len(), 1);
    }

    #[test]
    fn outlines_of_a_real_segmentation_enclose_their_regions() {
        let image = Rgb32FImage::from_fn(40, 30, |x, y| {
            image::Rgb([((x * 7 + y * 3) % 17) as f32 / 17.0, (y as f32 / 30.0), ((x / 9) % 2) as f32])
        });
        let seg = crate::slic(&image, &crate::SlicOptions { n_segments: 12, ..Default::default() }).unwrap();
        for (r, region) in seg.regions.iter().enumerate() {
            let outline = seg.outline(r as u32);
            let enclosed = area(&outline);
            // Clockwise on screen (y down) is a positive shoelace area; holes add to it.
            assert!(enclosed >= region.pixels as f32, "region {r}: {enclosed} < {}", region.pixels);
            assert!(outline.iter().all(|&[x, y]| x >= region.bbox.x0 as f32
                && x <= region.bbox.x1 as f32
                && y >= region.bbox.y0 as f32
                && y <= region.bbox.y1 as f32));
        }
    }
}
