//! A region's outline as the polygon that draws it: the outer boundary along its pixel edges,
//! its staircases cut, grown under the regions painted over it.

use crate::planar::without_collinear;
use crate::slic::Segmentation;

/// Headings along pixel edges in image coordinates (y down): east, south, west, north.
const STEPS: [(i64, i64); 4] = [(1, 0), (0, 1), (-1, 0), (0, -1)];

impl Segmentation {
    /// The polygon that draws `region` when regions are painted one over the other, in pixels
    /// (corner (x, y) is the top-left corner of pixel (x, y)), clockwise on screen, without
    /// points on the straight line between their neighbours.
    ///
    /// - Outer boundary: the pixel edges around the region, walked with the region on the
    ///   right. Regions are 4-connected (SLIC enforces it), so it is one loop; holes (regions
    ///   enclosed by this one) are not part of it: they are to be painted after it.
    /// - Cuts: where the boundary turns at a corner that only two regions touch (not
    ///   diagonally), the corner is replaced by the segment between the midpoints of its two
    ///   edges, so a diagonal staircase becomes a straight slope. Corners where three or more
    ///   regions meet, or two diagonally, and corners on the image border, stay.
    /// - Grown: the pixels of each neighbour for which `painted_later` is true that share an
    ///   edge with `region` are taken in. Of a boundary between two regions, what shows is the
    ///   later one's edge, which a cut moves up to half a pixel into the later region; the
    ///   earlier lies under it. Were both to stop at the same line, an anti-aliased renderer
    ///   would let what lies under them show through (two coverages of ½ leave ¼).
    ///
    /// Empty for a region without pixels.
    ///
    /// # Panics
    /// If `region` is not a label of this segmentation.
    pub fn outline(&self, region: u32, painted_later: impl Fn(u32) -> bool) -> Vec<[f32; 2]> {
        let is_region = |x: u32, y: u32| self.label(x, y) == region;
        let member = |x: u32, y: u32| {
            is_region(x, y)
                || (painted_later(self.label(x, y))
                    && ((x > 0 && is_region(x - 1, y))
                        || (y > 0 && is_region(x, y - 1))
                        || (x + 1 < self.width && is_region(x + 1, y))
                        || (y + 1 < self.height && is_region(x, y + 1))))
        };
        let walk = self.walk(region, member);
        let n = walk.len();
        let mid = |a: (i64, i64), b: (i64, i64)| [(a.0 + b.0) as f32 / 2.0, (a.1 + b.1) as f32 / 2.0];
        let mut points: Vec<[f32; 2]> = Vec::with_capacity(n);
        for i in 0..n {
            let (before, corner, after) = (walk[(i + n - 1) % n], walk[i], walk[(i + 1) % n]);
            if self.is_junction(corner) {
                points.push([corner.0 as f32, corner.1 as f32]);
            } else if turns(before, corner, after) {
                points.push(mid(before, corner));
                points.push(mid(corner, after));
            }
        }
        without_redundant_points(points)
    }

    /// Every pixel corner on the outer boundary of the pixels for which `member` is true, in
    /// order (one per unit edge), walked clockwise on screen with them on the right. They are
    /// `region` and pixels sharing an edge with it, so they lie within its bounding box grown
    /// by one and the boundary is one loop. Pixels touching them only at a corner are outside.
    fn walk(&self, region: u32, member: impl Fn(u32, u32) -> bool) -> Vec<(i64, i64)> {
        if self.regions[region as usize].pixels == 0 {
            return Vec::new();
        }
        let bbox = self.regions[region as usize].bbox;
        let bbox = bbox.padded(1, self.width, self.height);
        let (x0, y0, x1, y1) = (bbox.x0() as i64, bbox.y0() as i64, bbox.x1() as i64, bbox.y1() as i64);
        let inside = |x: i64, y: i64| x >= x0 && y >= y0 && x < x1 && y < y1 && member(x as u32, y as u32);
        // The first pixel in row-major order lies on the outer boundary: start on its top edge,
        // heading east, the region below (on the right).
        let (x, y) = (y0..y1)
            .flat_map(|y| (x0..x1).map(move |x| (x, y)))
            .find(|&(x, y)| inside(x, y))
            .expect("every region has a pixel");
        let start = ((x, y), 0usize);
        let (mut corner, mut heading) = start;
        let mut walk = Vec::new();
        loop {
            // The pixels on the right and on the left of the edge ahead.
            let (ahead_right, ahead_left) = match heading {
                0 => ((corner.0, corner.1), (corner.0, corner.1 - 1)),
                1 => ((corner.0 - 1, corner.1), (corner.0, corner.1)),
                2 => ((corner.0 - 1, corner.1 - 1), (corner.0 - 1, corner.1)),
                _ => ((corner.0, corner.1 - 1), (corner.0 - 1, corner.1 - 1)),
            };
            heading = if !inside(ahead_right.0, ahead_right.1) {
                (heading + 1) % 4
            } else if inside(ahead_left.0, ahead_left.1) {
                (heading + 3) % 4
            } else {
                heading
            };
            // The walk comes back up the first pixel's west edge and turns east at the start
            // corner: the loop is closed.
            if (corner, heading) == start && !walk.is_empty() {
                break;
            }
            walk.push(corner);
            let (dx, dy) = STEPS[heading];
            corner = (corner.0 + dx, corner.1 + dy);
        }
        walk
    }

    /// Whether the pixel corner (x, y) must stay where it is when outlines are smoothed: it
    /// lies on the image border, or the four pixels around it hold three or more regions, or
    /// two regions diagonally.
    fn is_junction(&self, (x, y): (i64, i64)) -> bool {
        if x <= 0 || y <= 0 || x >= self.width as i64 || y >= self.height as i64 {
            return true;
        }
        let (x, y) = (x as u32, y as u32);
        let [nw, ne, sw, se] =
            [self.label(x - 1, y - 1), self.label(x, y - 1), self.label(x - 1, y), self.label(x, y)];
        let mut distinct = [nw, ne, sw, se];
        distinct.sort_unstable();
        let count = 1 + distinct.windows(2).filter(|w| w[0] != w[1]).count();
        count >= 3 || (count == 2 && nw == se && ne == sw)
    }
}

/// Whether the walk turns at `corner` (coming from `before`, going to `after`).
fn turns(before: (i64, i64), corner: (i64, i64), after: (i64, i64)) -> bool {
    (corner.0 - before.0, corner.1 - before.1) != (after.0 - corner.0, after.1 - corner.1)
}

/// `points` (a closed polygon) without repeated points and without points on the straight line
/// between their neighbours. Coordinates are multiples of ½, so the tests are exact.
fn without_redundant_points(mut points: Vec<[f32; 2]>) -> Vec<[f32; 2]> {
    points.dedup();
    while points.len() > 1 && points.first() == points.last() {
        points.pop();
    }
    without_collinear(points, true)
}

#[cfg(test)]
mod tests {
    use common::signed_area;
    use image::Rgb32FImage;

    use super::*;

    /// The exact outer boundary: the corners where the walk turns.
    fn corners(seg: &Segmentation, region: u32) -> Vec<[f32; 2]> {
        let walk = seg.walk(region, |x, y| seg.label(x, y) == region);
        let n = walk.len();
        (0..n)
            .filter(|&i| turns(walk[(i + n - 1) % n], walk[i], walk[(i + 1) % n]))
            .map(|i| [walk[i].0 as f32, walk[i].1 as f32])
            .collect()
    }

    #[test]
    fn a_rectangle_has_four_corners() {
        let seg = Segmentation::from_rows(&["0000", "0110", "0110", "0000"]);
        assert_eq!(corners(&seg, 1), vec![[1.0, 1.0], [3.0, 1.0], [3.0, 3.0], [1.0, 3.0]]);
        assert_eq!(corners(&seg, 0), vec![[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]]);
    }

    #[test]
    fn concave_shapes_and_diagonal_neighbours() {
        // An L: area 5 pixels.
        let seg = Segmentation::from_rows(&["100", "100", "111"]);
        let outline = corners(&seg, 1);
        assert_eq!(signed_area(&outline), 5.0);
        assert_eq!(outline.len(), 6);
        // Region 1 touches a pixel of itself only diagonally? Not possible when 4-connected,
        // but the outline must still close around the 4-connected part it starts from.
        let seg = Segmentation::from_rows(&["1100", "1111", "0011"]);
        assert_eq!(signed_area(&corners(&seg, 1)), 8.0);
        // The region around a hole: the outline is the outer boundary only.
        let seg = Segmentation::from_rows(&["1111", "1001", "1111"]);
        assert_eq!(signed_area(&corners(&seg, 1)), 12.0);
        assert_eq!(signed_area(&corners(&seg, 0)), 2.0);
    }

    #[test]
    fn a_diagonal_staircase_becomes_a_slope() {
        let seg = Segmentation::from_rows(&["0001", "0011", "0111", "1111"]);
        let nothing_later = |_: u32| false;
        // The steps cut at their midpoints: one straight edge from (0.5, 3) to (3, 0.5); the
        // corners on the image border stay.
        let slope = [[0.0, 3.0], [0.5, 3.0], [3.0, 0.5], [3.0, 0.0]];
        assert_eq!(
            seg.outline(1, nothing_later),
            [&[[3.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]], &slope[..3]].concat()
        );
        assert_eq!(seg.outline(0, nothing_later), [[0.0, 0.0], slope[3], slope[2], slope[1], slope[0]]);
        // Together the two sides cover the image once.
        assert_eq!(
            signed_area(&seg.outline(0, nothing_later)) + signed_area(&seg.outline(1, nothing_later)),
            16.0
        );
        // Where three regions meet, the corner stays.
        let seg = Segmentation::from_rows(&["0022", "0011", "1111"]);
        assert!(seg.outline(1, nothing_later).contains(&[2.0, 1.0]));
    }

    #[test]
    fn a_region_grows_under_the_neighbours_painted_later() {
        let seg = Segmentation::from_rows(&["0011", "0011"]);
        assert_eq!(seg.outline(0, |_| false), vec![[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]]);
        assert_eq!(seg.outline(0, |l| l == 1), vec![[0.0, 0.0], [3.0, 0.0], [3.0, 2.0], [0.0, 2.0]]);
        // The later region itself is not grown under the earlier one.
        assert_eq!(seg.outline(1, |l| l == 1), vec![[2.0, 0.0], [4.0, 0.0], [4.0, 2.0], [2.0, 2.0]]);
        // Only into neighbours: region 2 lies beyond region 1.
        let seg = Segmentation::from_rows(&["0122"]);
        assert_eq!(seg.outline(0, |l| l == 2), vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]);
    }

    #[test]
    fn outlines_of_a_real_segmentation_enclose_their_regions() {
        let image = Rgb32FImage::from_fn(40, 30, |x, y| {
            image::Rgb([((x * 7 + y * 3) % 17) as f32 / 17.0, (y as f32 / 30.0), ((x / 9) % 2) as f32])
        });
        let seg = crate::slic(&image, &crate::SlicOptions { n_segments: 12, ..Default::default() }).unwrap();
        for (r, region) in seg.regions.iter().enumerate() {
            let outline = corners(&seg, r as u32);
            let enclosed = signed_area(&outline);
            // Clockwise on screen (y down) is a positive shoelace area; holes add to it.
            assert!(enclosed >= region.pixels as f32, "region {r}: {enclosed} < {}", region.pixels);
            let b = region.bbox;
            assert!(outline.iter().all(|&[x, y]| x >= b.x0() as f32
                && x <= b.x1() as f32
                && y >= b.y0() as f32
                && y <= b.y1() as f32));
        }
    }
}
