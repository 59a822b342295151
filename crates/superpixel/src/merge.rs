//! Fewer, better regions: SLIC at a finer scale, then the most alike neighbours merged.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use common::Moments;
use image::Rgb32FImage;

use crate::connectivity::{neighbours4, relabel};
use crate::slic::{Segmentation, SlicError, SlicOptions, slic};

impl Segmentation {
    /// The same segmentation with at most `max_regions` regions: while there are more, the two
    /// 4-adjacent regions whose union raises the squared colour error of a mean-colour fill the
    /// least (Ward's criterion, `n₁n₂/(n₁+n₂)·|c₁ − c₂|²`) become one, among the pairs whose
    /// union keeps an isoperimetric quotient 4πn/P² of at least `min_compactness` (when no such
    /// pair is left, among all pairs). Regions stay 4-connected. Statistics are recomputed from
    /// `image`, the image this segmentation was computed on.
    ///
    /// Merging by colour rather than by size matters: SLIC's smallest regions sit on
    /// high-contrast detail, and merging them away costs far more than joining two flat
    /// neighbours (measured in docs/method.md, "Figures behind constants"). The compactness floor
    /// matters on flat art, where merges of one colour cost nothing and would otherwise chain
    /// cells into rings and snakes that one path cannot draw.
    ///
    /// # Panics
    /// If `max_regions` is 0 or the image size differs.
    pub fn limit_regions(self, image: &Rgb32FImage, max_regions: usize, min_compactness: f64) -> Self {
        assert!(max_regions > 0, "at least one region");
        assert_eq!(image.dimensions(), (self.width, self.height), "image and segmentation differ in size");
        let count = self.regions.len();
        if count <= max_regions {
            return self;
        }
        let mut merging = Merging::new(&self, image, RegionFill::Mean, min_compactness);
        let mut alive = count;
        while alive > max_regions && merging.merge_cheapest().is_some() {
            alive -= 1;
        }
        let labels: Vec<u32> = self.labels.iter().map(|&l| merging.root(l)).collect();
        let (labels, count) = relabel(&labels);
        Self::from_labels(image, labels, count)
    }
}

/// What a region is taken to be filled with when merges are costed: a merge costs how much it
/// raises the squared error of that fill (with ramps, plus their price).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum RegionFill {
    /// Its mean colour (Ward's criterion).
    #[default]
    Mean,
    /// Its mean colour or its best linear colour ramp ([`Moments::linear_fit`]), whichever
    /// costs less, a ramp costing its error plus `price`: a smooth shading becomes one region,
    /// not bands of mean colours. The price matters: priced at nothing, a small region fits a
    /// ramp to anything, and merges chosen on that go astray early (docs/eval/fills.md).
    Ramp {
        /// What a ramp costs beside its error (squared RGB error, summed over pixels).
        price: f64,
    },
}

impl RegionFill {
    /// What the pixels of `moments` cost in this fill.
    fn cost(self, moments: &Moments) -> f64 {
        let flat = moments.flat_error();
        match self {
            RegionFill::Mean => flat,
            // A ramp costs at least its price: below it, no ramp need be fitted.
            RegionFill::Ramp { price } if flat <= price => flat,
            RegionFill::Ramp { price } => {
                let reduction = moments.linear_fit().map_or(0.0, |fit| fit.reduction);
                flat.min((flat - reduction).max(0.0) + price)
            }
        }
    }
}

/// A segmentation and the order in which its regions are merged, down to one, cheapest first
/// for a [`RegionFill`]: every region count up to the base's is a cut of it ([`Hierarchy::cut`];
/// with [`RegionFill::Mean`], what [`Segmentation::limit_regions`] with no compactness floor
/// gives), and the cost of each cut's fill is known without cutting or drawing it
/// ([`Hierarchy::fill_error`]). One over-segmentation then serves every budget.
#[derive(Clone, Debug)]
pub struct Hierarchy {
    base: Segmentation,
    /// What the regions are filled with.
    fill: RegionFill,
    /// The merges in order: (root kept, root merged into it), labels of the base.
    merges: Vec<(u32, u32)>,
    /// The squared colour error of the fill after each number of merges (index 0: the base).
    errors: Vec<f64>,
}

impl Hierarchy {
    /// Merges the regions of `base`, computed on `image`, down to one by Ward's criterion.
    ///
    /// # Panics
    /// If the image size differs.
    pub fn new(image: &Rgb32FImage, base: Segmentation) -> Self {
        Self::with_fill(image, base, RegionFill::Mean)
    }

    /// Merges the regions of `base`, computed on `image`, down to one, each merge the one that
    /// raises the cost of `fill` the least.
    ///
    /// # Panics
    /// If the image size differs.
    pub fn with_fill(image: &Rgb32FImage, base: Segmentation, fill: RegionFill) -> Self {
        assert_eq!(image.dimensions(), (base.width, base.height), "image and segmentation differ in size");
        let mut merging = Merging::new(&base, image, fill, 0.0);
        let mut errors = vec![match fill {
            RegionFill::Mean => base.flat_error(image),
            RegionFill::Ramp { .. } => merging.error.iter().sum(),
        }];
        let mut merges = Vec::with_capacity(base.regions.len().saturating_sub(1));
        while let Some((kept, merged, cost)) = merging.merge_cheapest() {
            merges.push((kept, merged));
            errors.push(errors[errors.len() - 1] + cost);
        }
        Self { base, fill, merges, errors }
    }

    /// What the regions are taken to be filled with.
    pub fn fill(&self) -> RegionFill {
        self.fill
    }

    /// The cut into `regions` regions (of `image`, which the base was computed on) merged
    /// again, down to one, for `fill`: its cuts into fewer regions follow `fill`, and none has
    /// more.
    pub fn refilled(&self, image: &Rgb32FImage, fill: RegionFill, regions: usize) -> Self {
        Self::with_fill(image, self.cut(image, regions), fill)
    }

    /// The most regions a cut has: the base's.
    pub fn most_regions(&self) -> usize {
        self.base.regions.len()
    }

    /// The fewest regions a cut has: one per part of the image no merge connects (one, for an
    /// image in one piece).
    pub fn fewest_regions(&self) -> usize {
        self.most_regions() - self.merges.len()
    }

    /// The squared RGB error (summed over pixels) of filling each region of the cut into
    /// `regions` ([`Hierarchy::cut`]) with its fill ([`Hierarchy::fill`]; ramps counted with
    /// their price).
    pub fn fill_error(&self, regions: usize) -> f64 {
        self.errors[self.merges_for(regions)]
    }

    /// The segmentation into `regions` regions (clamped to the hierarchy's range) that Ward's
    /// merges reach; `image` is the image the base was computed on.
    pub fn cut(&self, image: &Rgb32FImage, regions: usize) -> Segmentation {
        let mut parent: Vec<u32> = (0..self.most_regions() as u32).collect();
        for &(kept, merged) in &self.merges[..self.merges_for(regions)] {
            parent[merged as usize] = kept;
        }
        let root = |mut label: u32| {
            while parent[label as usize] != label {
                label = parent[label as usize];
            }
            label
        };
        let roots: Vec<u32> = (0..self.most_regions() as u32).map(root).collect();
        let labels: Vec<u32> = self.base.labels.iter().map(|&l| roots[l as usize]).collect();
        let (labels, count) = relabel(&labels);
        Segmentation::from_labels(image, labels, count)
    }

    /// How many merges leave `regions` regions.
    fn merges_for(&self, regions: usize) -> usize {
        self.most_regions().saturating_sub(regions.max(1)).min(self.merges.len())
    }
}

/// How [`segment`] splits an image into a given number of regions.
#[derive(Clone, Debug, PartialEq)]
pub struct SegmentOptions {
    /// SLIC's compactness (the method's 30).
    pub compactness: f32,
    /// SLIC is asked for this many times the wanted regions, which are then merged down to the
    /// count by colour ([`Segmentation::limit_regions`]): 1 is plain SLIC; more spends regions
    /// where colour varies.
    pub oversegment: f32,
    /// Merges whose union would have an isoperimetric quotient (4πn/P², π/4 for a square of
    /// pixels) below this are made only when nothing else is left to merge.
    pub min_compactness: f32,
    /// SLIC's Gaussian pre-smoothing (pixels; [`SlicOptions::sigma`]).
    pub sigma: f32,
    /// SLIC's rounds at most ([`SlicOptions::max_iterations`]).
    pub iterations: usize,
    /// SLIC's fragments of a cluster too small to stand alone are kept as regions of their own
    /// ([`SlicOptions::min_size_factor`] 0), for the merge by colour to join where they fit,
    /// instead of being joined to whatever region lies left of them.
    pub keep_fragments: bool,
    /// Where an image has no more areas of one exact colour than SLIC would be asked for
    /// segments (flat art), those areas are the over-segmentation instead
    /// ([`Segmentation::flat_areas`]): SLIC's segments, a few pixels each at such counts,
    /// straddle the one-pixel anti-aliased edges of flat art, and no merge splits them again.
    pub flat_areas: bool,
}

impl Default for SegmentOptions {
    /// SLIC as the method runs it (compactness 30, [`SlicOptions::default`]), not merged.
    fn default() -> Self {
        let slic = SlicOptions::default();
        Self {
            compactness: 30.0,
            oversegment: 1.0,
            min_compactness: 0.0,
            sigma: slic.sigma,
            iterations: slic.max_iterations,
            keep_fragments: false,
            flat_areas: false,
        }
    }
}

impl SegmentOptions {
    /// Regions that take the shape of an image's colour areas, for drawing it with flat fills:
    /// SLIC for [`WARD_OVERSEGMENT`] times the regions at a tenth of `compactness` (30 is the
    /// method's), unsmoothed, its fragments kept, then merged by colour with no compactness
    /// floor. The finer and the less regular the pieces merging starts from, the nearer Ward's
    /// merges come to the least flat-fill error (docs/segmentation.md measures each knob
    /// against the previous recipe; docs/method.md has the figures). Smoothing moves edges,
    /// joined fragments land in whatever region lies left of them, and at a compactness of 10
    /// the clusters stay rounder than the colour areas.
    pub fn ward(compactness: f32) -> Self {
        Self {
            compactness: compactness / 10.0,
            oversegment: WARD_OVERSEGMENT,
            min_compactness: 0.0,
            sigma: 0.0,
            keep_fragments: true,
            flat_areas: true,
            ..Self::default()
        }
    }

    /// The SLIC options of the over-segmentation into `segments` (before merging).
    pub fn slic_options(&self, segments: usize) -> SlicOptions {
        let defaults = SlicOptions::default();
        SlicOptions {
            n_segments: segments,
            compactness: self.compactness,
            sigma: self.sigma,
            max_iterations: self.iterations,
            min_size_factor: if self.keep_fragments { 0.0 } else { defaults.min_size_factor },
            ..defaults
        }
    }

    /// How many segments SLIC is asked for, for `regions` regions of an image of `pixels`
    /// pixels: `regions × oversegment`, at most the pixels.
    pub fn segments_for(&self, regions: usize, pixels: usize) -> usize {
        ((regions as f64 * self.oversegment as f64).ceil() as usize).clamp(1, pixels.max(1))
    }

    /// The segments that merging starts from, for `regions` regions of `image`: its areas of
    /// one colour ([`Segmentation::flat_areas`]) if `flat_areas` is set and they are no more
    /// than [`SegmentOptions::segments_for`] gives, else SLIC for that many segments.
    ///
    /// Flat art's areas give the merges its exact edges, where SLIC's pieces straddle its
    /// one-pixel anti-aliased ones (docs/method.md measures both). Photos have nearly as many
    /// areas as pixels and keep SLIC.
    pub fn over_segment(&self, image: &Rgb32FImage, regions: usize) -> Result<Segmentation, SlicError> {
        if !(self.oversegment.is_finite() && self.oversegment >= 1.0) {
            return Err(SlicError::BadOption("oversegment must be at least 1"));
        }
        let pixels = (image.width() as usize) * (image.height() as usize);
        let segments = self.segments_for(regions, pixels);
        match self.flat_areas.then(|| Segmentation::flat_areas(image, segments)).flatten() {
            Some(areas) => Ok(areas),
            None => slic(image, &self.slic_options(segments)),
        }
    }
}

/// How many times the regions [`SegmentOptions::ward`] asks SLIC for: fewer pieces draw worse,
/// more draw no better in more time (docs/method.md, "Figures behind constants").
pub const WARD_OVERSEGMENT: f32 = 8.0;

/// `image` split into at most `regions` superpixels: its over-segmentation for them
/// ([`SegmentOptions::over_segment`]), merged down by colour. SLIC itself returns a few percent
/// fewer regions than asked for (its grid and connectivity steps), so an oversegment slightly
/// above 1 gives the count exactly.
pub fn segment(
    image: &Rgb32FImage,
    regions: usize,
    options: &SegmentOptions,
) -> Result<Segmentation, SlicError> {
    Ok(options.over_segment(image, regions)?.limit_regions(
        image,
        regions.max(1),
        options.min_compactness as f64,
    ))
}

/// A root's cheapest merge as it was when queued: its cost, the root and its partner.
#[derive(Clone, Copy, PartialEq)]
struct Candidate {
    cost: f64,
    a: u32,
    b: u32,
}

impl Eq for Candidate {}

impl Ord for Candidate {
    /// [`merge_order`] reversed: the queue is a max-heap.
    fn cmp(&self, other: &Self) -> Ordering {
        merge_order((other.cost, other.a, other.b), (self.cost, self.a, self.b))
    }
}

impl PartialOrd for Candidate {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// Regions being merged: union-find over labels, each root's pixel count, colour sum, perimeter
/// (pixel edges) and (for ramps) pixel sums and cost, the length of border each pair of
/// touching roots shares, and a queue of merges with at most one live entry per root.
///
/// The queue is lazy. Every touching pair is *covered*: some live entry is at most its cost (by
/// the queue's order). A merge changes only the costs of pairs with the root kept, and that
/// root's cheapest merge is queued exactly, so its pairs stay covered; an entry is checked when
/// it comes out (its pair still touching, its cost still the pair's cost) and, when it is not,
/// its root's cheapest merge is found and queued then. An entry that passes is the cheapest
/// pair of all. Neighbours of a region that grows are not costed again at every merge: on flat
/// art one background region grows through thousands of merges and has thousands of
/// neighbours, and recosting them all at every merge was most of segmenting an emoji.
struct Merging {
    parent: Vec<u32>,
    size: Vec<f64>,
    sum: Vec<[f64; 3]>,
    /// Each root's `sum / size`, kept so that costing a pair divides nothing (costing is most of
    /// merging's time: a region that grows is costed against all of its neighbours each time).
    mean: Vec<[f64; 3]>,
    perimeter: Vec<f64>,
    /// What the roots are filled with.
    fill: RegionFill,
    /// Each root's pixel sums and its cost in its fill ([`RegionFill::cost`]); for
    /// [`RegionFill::Ramp`] only (Ward's costs need neither), empty otherwise.
    moments: Vec<Moments>,
    error: Vec<f64>,
    borders: Vec<Borders>,
    /// Each root's live entry in the queue (cost, partner); the queue's other entries are stale.
    queued: Vec<Option<(f64, u32)>>,
    queue: BinaryHeap<Candidate>,
    /// Merges whose union would be less compact than this are passed over.
    min_compactness: f64,
}

impl Merging {
    fn new(segmentation: &Segmentation, image: &Rgb32FImage, fill: RegionFill, min_compactness: f64) -> Self {
        let count = segmentation.regions.len();
        let moments = match fill {
            RegionFill::Mean => Vec::new(),
            RegionFill::Ramp { .. } => Moments::per_label(image, &segmentation.labels, count),
        };
        let error = moments.iter().map(|m| fill.cost(m)).collect();
        let size = segmentation.regions.iter().map(|r| r.pixels as f64).collect();
        let sum: Vec<[f64; 3]> =
            segmentation.regions.iter().map(|r| r.mean_color.map(|c| c as f64 * r.pixels as f64)).collect();
        let mean = sum.iter().zip(&size).map(|(s, &n): (&[f64; 3], &f64)| s.map(|c| c / n)).collect();
        let mut borders = vec![Borders::default(); count];
        let mut perimeter = vec![0.0; count];
        let (width, height) = (segmentation.width as usize, segmentation.height as usize);
        for (index, &label) in segmentation.labels.iter().enumerate() {
            let neighbours = neighbours4(index, width, height);
            for neighbour in neighbours {
                match neighbour.map(|n| segmentation.labels[n]) {
                    Some(other) if other == label => {}
                    Some(other) => {
                        perimeter[label as usize] += 1.0;
                        borders[label as usize].add_unsorted(other, 1.0);
                    }
                    None => perimeter[label as usize] += 1.0,
                }
            }
        }
        borders.iter_mut().for_each(Borders::sort);
        let mut merging = Self {
            parent: (0..count as u32).collect(),
            size,
            sum,
            mean,
            perimeter,
            fill,
            moments,
            error,
            borders,
            queued: vec![None; count],
            queue: BinaryHeap::new(),
            min_compactness,
        };
        merging.enqueue_all();
        merging
    }

    fn root(&self, mut label: u32) -> u32 {
        while self.parent[label as usize] != label {
            label = self.parent[label as usize];
        }
        label
    }

    /// Finds and queues every root's cheapest merge.
    fn enqueue_all(&mut self) {
        self.queue.clear();
        for a in 0..self.parent.len() as u32 {
            if self.parent[a as usize] == a {
                self.queued[a as usize] = None;
                let cheapest = self.cheapest(a);
                self.enqueue(a, cheapest);
            }
        }
    }

    /// The cost of merging roots `a` and `b`: how much the cost of their fill grows (for the
    /// mean colour, Ward's `n₁n₂/(n₁+n₂)·|c₁ − c₂|²`).
    fn cost(&self, a: u32, b: u32) -> f64 {
        let (ia, ib) = (a as usize, b as usize);
        if let RegionFill::Ramp { .. } = self.fill {
            let mut union = self.moments[ia];
            union += self.moments[ib];
            // Negative where the union saves a ramp's price more than its error grows.
            return self.fill.cost(&union) - self.error[ia] - self.error[ib];
        }
        let (na, nb) = (self.size[ia], self.size[ib]);
        let (ma, mb) = (&self.mean[ia], &self.mean[ib]);
        let difference: f64 = (0..3).map(|c| (ma[c] - mb[c]).powi(2)).sum();
        na * nb / (na + nb) * difference
    }

    /// The cost of merging roots `a` and `b`, which share `shared` pixel edges, if their union
    /// is compact enough: the isoperimetric quotient 4πn/P² (1 for a disc, π/4 for a square of
    /// pixels, small for thin or ragged shapes) of at least the floor.
    fn allowed_cost(&self, a: u32, b: u32, shared: f64) -> Option<f64> {
        if self.min_compactness <= 0.0 {
            return Some(self.cost(a, b));
        }
        let (ia, ib) = (a as usize, b as usize);
        let perimeter = self.perimeter[ia] + self.perimeter[ib] - 2.0 * shared;
        let compactness =
            4.0 * std::f64::consts::PI * (self.size[ia] + self.size[ib]) / perimeter.powi(2).max(1.0);
        (compactness >= self.min_compactness).then(|| self.cost(a, b))
    }

    /// Root `a`'s cheapest allowed merge with a touching root, by the queue's order.
    fn cheapest(&self, a: u32) -> Option<(f64, u32)> {
        let mut best = None;
        for &(b, shared) in &self.borders[a as usize].0 {
            if let Some(cost) = self.allowed_cost(a, b, shared)
                && precedes((cost, a, b), best.map(|(c, p)| (c, a, p)))
            {
                best = Some((cost, b));
            }
        }
        best
    }

    /// Queues `merge` as root `a`'s entry if it comes before the root's live entry (which
    /// covers `a`'s pairs until it comes out).
    fn enqueue(&mut self, a: u32, merge: Option<(f64, u32)>) {
        if let Some((cost, b)) = merge
            && precedes((cost, a, b), self.queued[a as usize].map(|(c, p)| (c, a, p)))
        {
            self.queued[a as usize] = merge;
            self.queue.push(Candidate { cost, a, b });
        }
    }

    /// Merges the touching pair of roots that is cheapest to merge among those whose union is
    /// compact enough; when none is left, drops the compactness floor for good, so the count can
    /// always be reached. Returns the root kept, the root merged into it and the merge's cost
    /// (how much the squared error of the mean-colour fill grows); `None` only when no two
    /// regions touch. Of the pair, the root with more neighbours is kept (fewer borders move).
    fn merge_cheapest(&mut self) -> Option<(u32, u32, f64)> {
        loop {
            while let Some(Candidate { cost, a, b }) = self.queue.pop() {
                if self.parent[a as usize] != a || self.queued[a as usize] != Some((cost, b)) {
                    continue;
                }
                self.queued[a as usize] = None;
                let shared = self.borders[a as usize].get(b);
                let now = shared.and_then(|shared| self.allowed_cost(a, b, shared));
                if now != Some(cost) {
                    // Its partner merged away (no longer a neighbour) or the pair costs
                    // otherwise: queued again as `a` is now.
                    let cheapest = self.cheapest(a);
                    self.enqueue(a, cheapest);
                } else {
                    let (na, nb) = (self.borders[a as usize].0.len(), self.borders[b as usize].0.len());
                    let (kept, merged) = if (nb, a) > (na, b) { (b, a) } else { (a, b) };
                    self.join(kept, merged);
                    return Some((kept, merged, cost));
                }
            }
            if self.min_compactness <= 0.0 {
                return None;
            }
            self.min_compactness = 0.0;
            self.enqueue_all();
        }
    }

    /// Merges root `b` into root `a`, then queues `a`'s cheapest merge (only `a`'s pairs
    /// changed; its neighbours' entries are checked when they come out).
    fn join(&mut self, a: u32, b: u32) {
        let (ia, ib) = (a as usize, b as usize);
        let shared = self.borders[ia].get(b).unwrap_or(0.0);
        self.parent[ib] = a;
        self.size[ia] += self.size[ib];
        self.perimeter[ia] += self.perimeter[ib] - 2.0 * shared;
        for c in 0..3 {
            self.sum[ia][c] += self.sum[ib][c];
        }
        self.mean[ia] = self.sum[ia].map(|c| c / self.size[ia]);
        if let RegionFill::Ramp { .. } = self.fill {
            let merged = self.moments[ib];
            self.moments[ia] += merged;
            self.error[ia] = self.fill.cost(&self.moments[ia]);
        }
        self.queued[ib] = None;
        let moved = std::mem::take(&mut self.borders[ib]);
        for &(other, length) in &moved.0 {
            if other != a {
                self.borders[other as usize].rename(b, a, length);
            }
        }
        let kept = std::mem::take(&mut self.borders[ia]);
        self.borders[ia] = kept.union_without(&moved, [a, b]);
        let cheapest = self.cheapest(a);
        self.enqueue(a, cheapest);
    }
}

/// A root's touching roots and the length of border (pixel edges) it shares with each, sorted
/// by label: looked up by binary search and joined by one linear merge (a tree map spent most of
/// merging's time on allocation and rebalancing, at 128k regions).
#[derive(Clone, Debug, Default)]
struct Borders(Vec<(u32, f64)>);

impl Borders {
    /// Adds `length` to the border with `other` while the list is being built (before
    /// [`Borders::sort`]): a region touches a handful of others then, so a scan is cheapest.
    fn add_unsorted(&mut self, other: u32, length: f64) {
        match self.0.iter_mut().find(|(label, _)| *label == other) {
            Some((_, shared)) => *shared += length,
            None => self.0.push((other, length)),
        }
    }

    fn sort(&mut self) {
        self.0.sort_unstable_by_key(|&(label, _)| label);
    }

    fn position(&self, other: u32) -> Result<usize, usize> {
        self.0.binary_search_by_key(&other, |&(label, _)| label)
    }

    /// The border shared with `other`, if they touch.
    fn get(&self, other: u32) -> Option<f64> {
        self.position(other).ok().map(|i| self.0[i].1)
    }

    /// The neighbour `from` became `to`: its border (`length`) is added to `to`'s.
    fn rename(&mut self, from: u32, to: u32, length: f64) {
        if let Ok(i) = self.position(from) {
            self.0.remove(i);
        }
        match self.position(to) {
            Ok(i) => self.0[i].1 += length,
            Err(i) => self.0.insert(i, (to, length)),
        }
    }

    /// Both lists in one, borders with the same neighbour added, without the labels `skip`.
    fn union_without(self, other: &Self, skip: [u32; 2]) -> Self {
        let (mut mine, mut theirs) = (self.0.into_iter().peekable(), other.0.iter().copied().peekable());
        let mut union = Vec::with_capacity(mine.len() + theirs.len());
        loop {
            let next = match (mine.peek(), theirs.peek()) {
                (Some(&(x, lx)), Some(&(y, ly))) if x == y => {
                    (mine.next(), theirs.next());
                    (x, lx + ly)
                }
                (Some(&(x, _)), Some(&(y, _))) if y < x => theirs.next().unwrap(),
                (Some(_), _) => mine.next().unwrap(),
                (None, Some(_)) => theirs.next().unwrap(),
                (None, None) => break,
            };
            if !skip.contains(&next.0) {
                union.push(next);
            }
        }
        Self(union)
    }
}

/// The order merges `(cost, root, partner)` are made in: cheaper first, ties to the lower pair
/// of labels (a merge is the same whichever of its roots queued it).
fn merge_order((cost, a, b): (f64, u32, u32), (other_cost, c, d): (f64, u32, u32)) -> Ordering {
    let pair = |x: u32, y: u32| (x.min(y), x.max(y));
    cost.total_cmp(&other_cost).then_with(|| pair(a, b).cmp(&pair(c, d)))
}

/// Whether `merge` comes before `other` in [`merge_order`]; everything comes before `None`.
fn precedes(merge: (f64, u32, u32), other: Option<(f64, u32, u32)>) -> bool {
    other.is_none_or(|other| merge_order(merge, other).is_lt())
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use image::{Rgb, Rgb32FImage};

    use super::*;

    /// The greedy merge by brute force: every step, every touching pair of roots is costed
    /// (borders and perimeters counted from the label map anew) and the first by the queue's
    /// order among the compact enough ones is merged, the root with more neighbours kept.
    fn brute_force(segmentation: &Segmentation, mut min_compactness: f64) -> Vec<(u32, u32, f64)> {
        let (width, height) = (segmentation.width as usize, segmentation.height as usize);
        let count = segmentation.regions.len();
        let mut root: Vec<u32> = (0..count as u32).collect();
        let mut size: Vec<f64> = segmentation.regions.iter().map(|r| r.pixels as f64).collect();
        let mut sum: Vec<[f64; 3]> =
            segmentation.regions.iter().map(|r| r.mean_color.map(|c| c as f64 * r.pixels as f64)).collect();
        let mut merges = Vec::new();
        loop {
            let label = |index: usize| root[segmentation.labels[index] as usize];
            let mut perimeter = vec![0.0f64; count];
            let mut borders = vec![BTreeMap::<u32, f64>::new(); count];
            for index in 0..width * height {
                for neighbour in neighbours4(index, width, height) {
                    match neighbour.map(label) {
                        Some(other) if other == label(index) => {}
                        Some(other) => {
                            perimeter[label(index) as usize] += 1.0;
                            *borders[label(index) as usize].entry(other).or_insert(0.0) += 1.0;
                        }
                        None => perimeter[label(index) as usize] += 1.0,
                    }
                }
            }
            let mut best: Option<(f64, u32, u32)> = None;
            for a in 0..count as u32 {
                for (&b, &shared) in &borders[a as usize] {
                    let (ia, ib) = (a as usize, b as usize);
                    let union = size[ia] + size[ib];
                    let outline = perimeter[ia] + perimeter[ib] - 2.0 * shared;
                    if 4.0 * std::f64::consts::PI * union / outline.powi(2).max(1.0) < min_compactness {
                        continue;
                    }
                    let difference: f64 =
                        (0..3).map(|c| (sum[ia][c] / size[ia] - sum[ib][c] / size[ib]).powi(2)).sum();
                    let cost = size[ia] * size[ib] / union * difference;
                    if precedes((cost, a, b), best) {
                        best = Some((cost, a, b));
                    }
                }
            }
            let Some((cost, a, b)) = best else {
                if min_compactness <= 0.0 {
                    return merges;
                }
                min_compactness = 0.0;
                continue;
            };
            let (na, nb) = (borders[a as usize].len(), borders[b as usize].len());
            let (kept, merged) = if (nb, a) > (na, b) { (b, a) } else { (a, b) };
            for r in root.iter_mut().filter(|r| **r == merged) {
                *r = kept;
            }
            size[kept as usize] += size[merged as usize];
            for c in 0..3 {
                sum[kept as usize][c] += sum[merged as usize][c];
            }
            merges.push((kept, merged, cost));
        }
    }

    #[test]
    fn borders_join_sorted_and_summed() {
        let mut kept = Borders::default();
        [(7, 1.0), (2, 3.0), (9, 2.0), (2, 1.0)].into_iter().for_each(|(l, n)| kept.add_unsorted(l, n));
        kept.sort();
        assert_eq!(kept.0, [(2, 4.0), (7, 1.0), (9, 2.0)]);
        let merged = Borders(vec![(1, 5.0), (2, 1.0), (4, 2.0), (9, 6.0)]);
        let union = kept.union_without(&merged, [4, 7]);
        assert_eq!(union.0, [(1, 5.0), (2, 5.0), (9, 8.0)]);
        let mut theirs = Borders(vec![(3, 1.0), (5, 2.0), (8, 1.0)]);
        theirs.rename(8, 1, 1.0);
        theirs.rename(5, 3, 2.0);
        assert_eq!(theirs.0, [(1, 1.0), (3, 3.0)]);
        assert_eq!((theirs.get(3), theirs.get(5)), (Some(3.0), None));
    }

    #[test]
    fn the_queue_merges_in_the_brute_force_order() {
        // Flat art's case: colours from a small palette, so many merges cost nothing and tie
        // (the order then rests on the labels alone); one pixel a region to start.
        let palette = [0.0, 0.25, 0.5, 1.0];
        let image = Rgb32FImage::from_fn(11, 9, |x, y| {
            let i = (x * 7 + y * 13 + (x * y) % 5) as usize;
            Rgb([palette[i % 4], palette[(i / 2) % 4], palette[(x / 4 + y / 3) as usize % 4]])
        });
        // A photo's case: every colour different, so a region's growth changes which
        // neighbour is its cheapest (what the queue learns only when an entry comes out).
        let noise = Rgb32FImage::from_fn(11, 9, |x, y| {
            let h = |c: u32| {
                ((x.wrapping_mul(2_654_435_761) ^ y.wrapping_mul(40_503) ^ (c * 97)) % 1009) as f32 / 1008.0
            };
            Rgb([h(1), h(2), h(3)])
        });
        for (name, image) in [("palette", image), ("noise", noise)] {
            let labels: Vec<u32> = (0..11 * 9).collect();
            let base = Segmentation::from_labels(&image, labels, 11 * 9);
            for floor in [0.0, 0.3, 0.5, 0.6, 0.7, 0.75] {
                let mut merging = Merging::new(&base, &image, RegionFill::Mean, floor);
                let merges: Vec<(u32, u32, f64)> = std::iter::from_fn(|| merging.merge_cheapest()).collect();
                assert_eq!(merges.len(), 11 * 9 - 1, "down to one region");
                assert_eq!(merges, brute_force(&base, floor), "{name}, floor {floor}");
            }
        }
    }

    #[test]
    fn limiting_merges_the_most_alike_neighbours() {
        // Regions 0 and 1 are both black, 2 is white, 3 is black but only touches 2.
        let seg = Segmentation::from_rows(&["0011", "0011", "2222", "3333"]);
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

    /// A 32 × 32 flag: white over blue, with the one-pixel row between them anti-aliased grey,
    /// and a one-pixel red spot on each stripe.
    fn flag() -> Rgb32FImage {
        Rgb32FImage::from_fn(32, 32, |x, y| {
            image::Rgb(match (x, y) {
                (5, 5) | (20, 25) => [1.0, 0.0, 0.0],
                (_, 0..=15) => [1.0; 3],
                (_, 16) => [0.5, 0.5, 0.75],
                _ => [0.0, 0.0, 0.5],
            })
        })
    }

    #[test]
    fn flat_areas_are_the_connected_areas_of_one_colour() {
        let image = flag();
        let areas = Segmentation::flat_areas(&image, 5).unwrap();
        // White, the grey row, blue, and the two red spots (one colour, not touching).
        assert_eq!(areas.regions.len(), 5);
        assert_eq!(Segmentation::flat_areas(&image, 4), None, "more areas than asked for");
        assert_ne!(areas.label(5, 5), areas.label(20, 25), "the two red spots apart");
        assert_eq!(areas.flat_error(&image), 0.0);
        assert_eq!(areas.label(0, 16), areas.label(31, 16));
        assert_eq!(Segmentation::flat_areas(&Rgb32FImage::new(0, 0), 5), None);
    }

    #[test]
    fn flat_art_is_merged_from_its_areas_and_photos_from_slic() {
        let ward = SegmentOptions::ward(30.0);
        // Flat art: its five areas, not SLIC's 32 segments for 4 regions; the anti-aliased row
        // on its own.
        let image = flag();
        let regions = ward.over_segment(&image, 4).unwrap();
        assert_eq!(Some(regions), Segmentation::flat_areas(&image, 5));
        let slic_only = SegmentOptions { flat_areas: false, ..ward.clone() };
        assert!(slic_only.over_segment(&image, 4).unwrap().regions.len() > 5, "SLIC's segments");
        let merged = segment(&image, 4, &ward).unwrap();
        assert_eq!(merged.regions.len(), 4);
        assert_eq!(merged.label(0, 16), merged.label(31, 16), "the grey row is one region");
        assert_ne!(merged.label(0, 16), merged.label(0, 15));
        assert_ne!(merged.label(0, 16), merged.label(0, 17));
        // A picture with more areas than segments (every pixel its own colour) is SLIC's.
        let noise = Rgb32FImage::from_fn(32, 32, |x, y| image::Rgb([x as f32 / 32.0, y as f32 / 32.0, 0.5]));
        let segments = ward.over_segment(&noise, 4).unwrap().regions.len();
        assert!((16..=64).contains(&segments), "{segments} SLIC segments for 32 asked");
    }

    #[test]
    fn ramps_priced_keep_a_smooth_shading_whole_where_ward_bands_it() {
        // A shading across the left two thirds, two flat blocks on the right: with ramps, three
        // regions draw it almost exactly (the shading one ramp); Ward's three regions cut the
        // shading into bands and leave one block merged with it or its neighbour.
        let image = Rgb32FImage::from_fn(96, 48, |x, y| {
            if x < 64 {
                let t = x as f32 / 64.0;
                Rgb([0.1 + 0.8 * t, 0.3 + 0.4 * t, 0.9 - 0.6 * t])
            } else if y < 24 {
                Rgb([0.9, 0.1, 0.2])
            } else {
                Rgb([0.1, 0.6, 0.2])
            }
        });
        let base = SegmentOptions::ward(30.0).over_segment(&image, 3).unwrap();
        assert!(base.regions.len() > 12, "{} base regions", base.regions.len());
        let ward = Hierarchy::new(&image, base.clone());
        let price = 0.5;
        let ramps = ward.refilled(&image, RegionFill::Ramp { price }, base.regions.len());
        assert_eq!((ward.fill(), ramps.fill()), (RegionFill::Mean, RegionFill::Ramp { price }));
        let cut = ramps.cut(&image, 3);
        assert_eq!(cut.regions.len(), 3);
        let shading: std::collections::BTreeSet<u32> =
            (0..64).flat_map(|x| (0..48).map(move |y| (x, y))).map(|(x, y)| cut.label(x, y)).collect();
        assert_eq!(shading.len(), 1, "the shading is one region");
        // What is left: SLIC's cells that straddle the blocks' edges, and one ramp's price.
        assert!(
            ward.fill_error(3) > 5.0 * ramps.fill_error(3),
            "Ward's {} against {}",
            ward.fill_error(3),
            ramps.fill_error(3)
        );
        // The costs are the fills' errors: a cut's, as the tree says, is what each region's
        // ramp (or mean colour) leaves, plus a price per ramp.
        let sums = Moments::per_label(&image, &cut.labels, cut.regions.len());
        let direct: f64 = sums.iter().map(|m| RegionFill::Ramp { price }.cost(m)).sum();
        assert!((direct - ramps.fill_error(3)).abs() < 1e-6 * direct.max(1.0), "{direct} against the tree's");
    }
}
