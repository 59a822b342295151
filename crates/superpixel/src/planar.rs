//! The segmentation as a planar map: every boundary between two regions, or between a region
//! and the image's edge, traced once as a chain of pixel corners from one junction to the next
//! and shared by the regions on its two sides. The outline of a region, or of any set of
//! regions, is assembled from chains, so neighbours' outlines run along the same line.

use std::collections::HashMap;

use crate::slic::Segmentation;

/// A boundary between two sides, from one junction (a pixel corner where three or more sides
/// meet, or two diagonally) to another, or around an island back to where it started.
#[derive(Clone, Debug, PartialEq)]
pub struct Chain {
    /// Its points in pixels (corner (x, y) is the top-left corner of pixel (x, y)), from one end
    /// to the other, staircases cut: where it turns at a corner inside the image, the corner is
    /// replaced by the midpoints of its two edges, so a diagonal staircase becomes a slope. The
    /// ends stay on their junctions. A closed chain lists its loop once (the first point is not
    /// repeated).
    pub points: Vec<[f32; 2]>,
    /// The region on the right walking along `points` (y down: clockwise around it).
    pub right: u32,
    /// The side on the left: a region, or `None` for the outside of the image.
    pub left: Option<u32>,
    /// Whether it is a loop without junctions (one region enclosed by another).
    pub closed: bool,
    /// The pixel corners it starts and ends on (the same for a loop).
    ends: [(u32, u32); 2],
}

/// A chain walked one way or the other, as part of a contour.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Directed {
    /// Index into [`PlanarMap::chains`].
    pub chain: u32,
    /// Walked from its last point to its first.
    pub reversed: bool,
}

/// Every boundary of a segmentation, once, and which regions each borders.
#[derive(Clone, Debug)]
pub struct PlanarMap {
    chains: Vec<Chain>,
    of_region: Vec<Vec<u32>>,
}

/// Headings along pixel edges (y down): east, south, west, north.
const STEPS: [(i64, i64); 4] = [(1, 0), (0, 1), (-1, 0), (0, -1)];

impl PlanarMap {
    /// Traces every boundary of `segmentation`: O(pixels).
    pub fn new(segmentation: &Segmentation) -> Self {
        let tracer = Tracer::new(segmentation);
        let mut visited = Visited::new(segmentation.width, segmentation.height);
        let mut chains = Vec::new();
        let (width, height) = (segmentation.width as i64, segmentation.height as i64);
        for y in 0..=height {
            for x in 0..=width {
                if !tracer.is_junction((x, y)) {
                    continue;
                }
                for heading in 0..4 {
                    if tracer.is_boundary((x, y), heading) && !visited.get((x, y), heading) {
                        chains.push(tracer.chain((x, y), heading, &mut visited, false));
                    }
                }
            }
        }
        // What is left are loops without junctions: start each on its top-left edge.
        for y in 0..=height {
            for x in 0..width {
                if tracer.is_boundary((x, y), 0) && !visited.get((x, y), 0) {
                    chains.push(tracer.chain((x, y), 0, &mut visited, true));
                }
            }
        }
        let mut of_region = vec![Vec::new(); segmentation.regions.len()];
        for (index, chain) in chains.iter().enumerate() {
            of_region[chain.right as usize].push(index as u32);
            if let Some(left) = chain.left {
                of_region[left as usize].push(index as u32);
            }
        }
        Self { chains, of_region }
    }

    /// Every boundary.
    pub fn chains(&self) -> &[Chain] {
        &self.chains
    }

    /// The chains bordering `region`, by index.
    ///
    /// # Panics
    /// If `region` is not a label of the segmentation.
    pub fn chains_of(&self, region: u32) -> &[u32] {
        &self.of_region[region as usize]
    }

    /// The regions sharing a boundary with `region`, each once, in ascending order.
    pub fn neighbours(&self, region: u32) -> Vec<u32> {
        let mut neighbours: Vec<u32> = self
            .chains_of(region)
            .iter()
            .filter_map(|&c| {
                let chain = &self.chains[c as usize];
                if chain.right == region { chain.left } else { Some(chain.right) }
            })
            .filter(|&other| other != region)
            .collect();
        neighbours.sort_unstable();
        neighbours.dedup();
        neighbours
    }

    /// The boundary of a set of regions, `members` (every one of them): its contours, each
    /// chains walked with the set on the right. Filled with the nonzero rule they cover the
    /// set's pixels and nothing else, whatever encloses what (a hole winds the other way).
    pub fn boundary(&self, members: &[u32]) -> Vec<Vec<Directed>> {
        let inside = |region: Option<u32>| region.is_some_and(|r| members.contains(&r));
        let mut ids: Vec<u32> = members.iter().flat_map(|&r| self.chains_of(r).iter().copied()).collect();
        ids.sort_unstable();
        ids.dedup();
        let mut contours = Vec::new();
        let mut open: Vec<Directed> = Vec::new();
        for id in ids {
            let chain = &self.chains[id as usize];
            let (right, left) = (inside(Some(chain.right)), inside(chain.left));
            if right == left {
                continue;
            }
            let directed = Directed { chain: id, reversed: !right };
            if chain.closed { contours.push(vec![directed]) } else { open.push(directed) }
        }
        let ends = |d: &Directed| {
            let [start, end] = self.chains[d.chain as usize].ends;
            if d.reversed { (end, start) } else { (start, end) }
        };
        let mut starting: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
        for (index, directed) in open.iter().enumerate() {
            starting.entry(ends(directed).0).or_default().push(index);
        }
        let mut used = vec![false; open.len()];
        for first in 0..open.len() {
            if used[first] {
                continue;
            }
            used[first] = true;
            let (home, mut at) = ends(&open[first]);
            let mut contour = vec![open[first]];
            // Each corner has as many chains of the boundary leaving it as arriving, so the walk
            // comes home; which leaving chain follows which arriving one changes no winding.
            while at != home {
                let next = starting.get(&at).and_then(|list| list.iter().copied().find(|&i| !used[i]));
                let Some(next) = next else {
                    debug_assert!(false, "a boundary chain leaving {at:?} is missing: members incomplete");
                    break;
                };
                used[next] = true;
                contour.push(open[next]);
                at = ends(&open[next]).1;
            }
            contours.push(contour);
        }
        contours
    }
}

/// Which directed unit edges a trace has walked (each boundary edge once, either way).
struct Visited {
    horizontal: Vec<bool>,
    vertical: Vec<bool>,
    width: i64,
}

impl Visited {
    fn new(width: u32, height: u32) -> Self {
        let (w, h) = (width as usize, height as usize);
        Self { horizontal: vec![false; w * (h + 1)], vertical: vec![false; (w + 1) * h], width: width as i64 }
    }

    /// Which list holds the unit edge leaving `corner` heading `heading`, and where.
    fn index(&self, (x, y): (i64, i64), heading: usize) -> (bool, usize) {
        match heading {
            0 => (true, (y * self.width + x) as usize),
            2 => (true, (y * self.width + x - 1) as usize),
            1 => (false, (y * (self.width + 1) + x) as usize),
            _ => (false, ((y - 1) * (self.width + 1) + x) as usize),
        }
    }

    fn get(&self, corner: (i64, i64), heading: usize) -> bool {
        match self.index(corner, heading) {
            (true, i) => self.horizontal[i],
            (false, i) => self.vertical[i],
        }
    }

    fn mark(&mut self, corner: (i64, i64), heading: usize) {
        match self.index(corner, heading) {
            (true, i) => self.horizontal[i] = true,
            (false, i) => self.vertical[i] = true,
        }
    }
}

/// Reads boundaries off a label map.
struct Tracer<'a> {
    segmentation: &'a Segmentation,
    width: i64,
    height: i64,
}

impl<'a> Tracer<'a> {
    fn new(segmentation: &'a Segmentation) -> Self {
        Self { segmentation, width: segmentation.width as i64, height: segmentation.height as i64 }
    }

    /// The region of pixel (x, y); `None` outside the image.
    fn label(&self, x: i64, y: i64) -> Option<u32> {
        ((0..self.width).contains(&x) && (0..self.height).contains(&y))
            .then(|| self.segmentation.label(x as u32, y as u32))
    }

    /// The sides (right, left) of the unit edge leaving `corner` heading `heading`.
    fn sides(&self, (x, y): (i64, i64), heading: usize) -> (Option<u32>, Option<u32>) {
        match heading {
            0 => (self.label(x, y), self.label(x, y - 1)),
            1 => (self.label(x - 1, y), self.label(x, y)),
            2 => (self.label(x - 1, y - 1), self.label(x - 1, y)),
            _ => (self.label(x, y - 1), self.label(x - 1, y - 1)),
        }
    }

    /// Whether the unit edge leaving `corner` heading `heading` exists and has different sides.
    fn is_boundary(&self, (x, y): (i64, i64), heading: usize) -> bool {
        let (dx, dy) = STEPS[heading];
        let (nx, ny) = (x + dx, y + dy);
        let on_grid = (0..=self.width).contains(&nx) && (0..=self.height).contains(&ny);
        let (right, left) = self.sides((x, y), heading);
        on_grid && right != left
    }

    /// Whether three or more boundary edges meet at `corner` (three sides, or two diagonally).
    fn is_junction(&self, corner: (i64, i64)) -> bool {
        (0..4).filter(|&heading| self.is_boundary(corner, heading)).count() >= 3
    }

    fn on_border(&self, (x, y): (i64, i64)) -> bool {
        x == 0 || y == 0 || x == self.width || y == self.height
    }

    /// The chain leaving `start` heading `heading`, walked to the next junction (or, `closed`,
    /// back to `start`), its edges marked visited; oriented with a region on its right.
    fn chain(&self, start: (i64, i64), mut heading: usize, visited: &mut Visited, closed: bool) -> Chain {
        let (right, left) = self.sides(start, heading);
        let mut corners = vec![start];
        let mut at = start;
        loop {
            visited.mark(at, heading);
            let (dx, dy) = STEPS[heading];
            at = (at.0 + dx, at.1 + dy);
            if at == start || (!closed && self.is_junction(at)) {
                break;
            }
            corners.push(at);
            let back = (heading + 2) % 4;
            heading = (0..4)
                .find(|&h| h != back && self.is_boundary(at, h))
                .expect("a corner on a boundary that is no junction has two boundary edges");
        }
        if !closed {
            corners.push(at);
        }
        let (mut right, mut left) = (right, left);
        if right.is_none() {
            corners.reverse();
            std::mem::swap(&mut right, &mut left);
        }
        let corner = |c: (i64, i64)| (c.0 as u32, c.1 as u32);
        let ends = [corner(corners[0]), corner(if closed { corners[0] } else { corners[corners.len() - 1] })];
        Chain {
            points: self.cut(&corners, closed),
            right: right.expect("one side of a boundary is a region"),
            left,
            closed,
            ends,
        }
    }

    /// `corners` with their staircases cut (see [`Chain::points`]) and no point on the straight
    /// line between its neighbours. Coordinates are multiples of ½, so the tests are exact.
    fn cut(&self, corners: &[(i64, i64)], closed: bool) -> Vec<[f32; 2]> {
        let n = corners.len();
        let point = |c: (i64, i64)| [c.0 as f32, c.1 as f32];
        let mid = |a: (i64, i64), b: (i64, i64)| [(a.0 + b.0) as f32 / 2.0, (a.1 + b.1) as f32 / 2.0];
        let mut points = Vec::with_capacity(n + 2);
        for i in 0..n {
            let end = !closed && (i == 0 || i == n - 1);
            if end {
                points.push(point(corners[i]));
                continue;
            }
            let (before, corner, after) = (corners[(i + n - 1) % n], corners[i], corners[(i + 1) % n]);
            let turns =
                (corner.0 - before.0, corner.1 - before.1) != (after.0 - corner.0, after.1 - corner.1);
            if !turns {
                continue;
            }
            if self.on_border(corner) {
                points.push(point(corner));
            } else {
                points.push(mid(before, corner));
                points.push(mid(corner, after));
            }
        }
        points.dedup();
        if closed {
            while points.len() > 1 && points.first() == points.last() {
                points.pop();
            }
        }
        without_collinear(points, closed)
    }
}

/// `points` without those on the straight line between their neighbours (the ends of an open
/// line stay).
pub(crate) fn without_collinear(points: Vec<[f32; 2]>, closed: bool) -> Vec<[f32; 2]> {
    let n = points.len();
    if n < 3 {
        return points;
    }
    let cross =
        |a: [f32; 2], b: [f32; 2], c: [f32; 2]| (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0]);
    let mut kept: Vec<[f32; 2]> = Vec::with_capacity(n);
    for i in 0..n {
        let end = !closed && (i == 0 || i == n - 1);
        let before = *kept.last().unwrap_or(&points[(i + n - 1) % n]);
        if end || cross(before, points[i], points[(i + 1) % n]) != 0.0 {
            kept.push(points[i]);
        }
    }
    kept
}

#[cfg(test)]
mod tests {
    use common::signed_area;
    use image::Rgb32FImage;

    use super::*;

    /// The polygons of the contours of `members`' boundary.
    fn polygons(map: &PlanarMap, members: &[u32]) -> Vec<Vec<[f32; 2]>> {
        map.boundary(members)
            .iter()
            .map(|contour| {
                let mut points = Vec::new();
                for d in contour {
                    let chain = &map.chains()[d.chain as usize];
                    let mut run = chain.points.clone();
                    if d.reversed {
                        run.reverse();
                    }
                    // The next chain starts where this one ends.
                    if !chain.closed {
                        run.pop();
                    }
                    points.extend(run);
                }
                points
            })
            .collect()
    }

    fn area(map: &PlanarMap, members: &[u32]) -> f32 {
        polygons(map, members).iter().map(|p| signed_area(p)).sum()
    }

    #[test]
    fn every_boundary_is_traced_once_between_its_two_sides() {
        let seg = Segmentation::from_rows(&["0011", "0011", "2211"]);
        let map = PlanarMap::new(&seg);
        // 0|1, 0|2, 2|1 inside; 0, 1, 2 against the outside.
        let mut pairs: Vec<(u32, Option<u32>)> = map.chains().iter().map(|c| (c.right, c.left)).collect();
        pairs.sort();
        assert_eq!(pairs.len(), 6, "{pairs:?}");
        let inner = pairs.iter().filter(|(_, left)| left.is_some()).count();
        assert_eq!(inner, 3);
        assert_eq!(map.neighbours(0), vec![1, 2]);
        assert_eq!(map.neighbours(2), vec![0, 1]);
        // Each region's own boundary encloses its pixels exactly; their sum is the image.
        let areas: Vec<f32> = (0..3).map(|r| area(&map, &[r])).collect();
        assert_eq!(areas, vec![4.0, 6.0, 2.0]);
        assert_eq!(area(&map, &[0, 1, 2]), 12.0);
    }

    #[test]
    fn islands_are_loops_and_holes_wind_the_other_way() {
        let seg = Segmentation::from_rows(&["00000", "01110", "01210", "01110", "00000"]);
        let map = PlanarMap::new(&seg);
        assert_eq!(map.chains().len(), 3, "outer border, 0|1 and 1|2 loops");
        assert!(map.chains().iter().all(|c| c.closed));
        // Region 1 is a ring: its outer loop minus the hole where region 2 is. Both loops have
        // their corners cut (an eighth of a pixel each), the border's stay.
        assert_eq!(area(&map, &[1]), 8.0);
        assert_eq!(polygons(&map, &[1]).len(), 2);
        assert_eq!(area(&map, &[1, 2]), 8.5);
        assert_eq!(area(&map, &[2]), 0.5);
        assert_eq!(area(&map, &[0]), 16.5);
    }

    #[test]
    fn staircases_are_cut_and_junctions_stay() {
        let seg = Segmentation::from_rows(&["0001", "0011", "0111", "1111"]);
        let map = PlanarMap::new(&seg);
        let diagonal = map.chains().iter().find(|c| c.left.is_some()).unwrap();
        // One straight slope between the two ends on the image border.
        let mut points = diagonal.points.clone();
        points.sort_by(|a, b| a.partial_cmp(b).unwrap());
        assert_eq!(points, vec![[0.0, 3.0], [0.5, 3.0], [3.0, 0.0], [3.0, 0.5]]);
        assert_eq!(area(&map, &[0]) + area(&map, &[1]), 16.0);
        // Where three regions meet, the corner stays.
        let seg = Segmentation::from_rows(&["0022", "0011", "1111"]);
        let map = PlanarMap::new(&seg);
        let touching: Vec<&Chain> = map.chains().iter().filter(|c| c.points.contains(&[2.0, 1.0])).collect();
        assert_eq!(touching.len(), 3, "three chains end on the junction");
    }

    #[test]
    fn the_boundary_of_any_set_covers_its_pixels() {
        let image = Rgb32FImage::from_fn(40, 30, |x, y| {
            image::Rgb([((x * 7 + y * 3) % 17) as f32 / 17.0, (y as f32 / 30.0), ((x / 9) % 2) as f32])
        });
        let seg = crate::slic(&image, &crate::SlicOptions { n_segments: 30, ..Default::default() }).unwrap();
        let map = PlanarMap::new(&seg);
        // The staircase cut moves area between neighbours but not off the image: the regions'
        // own boundaries sum to it; a region with its neighbours encloses at least it.
        let total: f32 = (0..seg.regions.len() as u32).map(|r| area(&map, &[r])).sum();
        assert!((total - 1200.0).abs() < 1e-3, "{total}");
        for r in 0..seg.regions.len() as u32 {
            let mut members = map.neighbours(r);
            members.push(r);
            let pixels: usize = members.iter().map(|&m| seg.regions[m as usize].pixels).sum();
            let enclosed = area(&map, &members);
            assert!(
                (enclosed - pixels as f32).abs() <= 0.5 * members.len() as f32 + 4.0,
                "{r}: {enclosed} vs {pixels}"
            );
            // Every contour closes: consecutive chains meet.
            for contour in polygons(&map, &members) {
                assert!(contour.len() >= 3);
            }
        }
    }
}
