//! Fewer, better regions: SLIC at a finer scale, then the most alike neighbours merged.

use std::cmp::Ordering;
use std::collections::{BTreeMap, BinaryHeap};

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
    /// neighbours (on a 512² photo, 520 regions cut to 499 by size lose 0.8 dB of mosaic PSNR;
    /// 1000 cut to 499 by colour gain 1.4 dB over asking SLIC for 499). The compactness floor
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
        let mut merging = Merging::new(&self, min_compactness);
        let mut alive = count;
        while alive > max_regions && merging.merge_cheapest().is_some() {
            alive -= 1;
        }
        let labels: Vec<u32> = self.labels.iter().map(|&l| merging.root(l)).collect();
        let (labels, count) = relabel(&labels);
        Self::from_labels(image, labels, count)
    }
}

/// A segmentation and the order in which Ward's criterion merges its regions, down to one:
/// every region count up to the base's is a cut of it ([`Hierarchy::cut`], what
/// [`Segmentation::limit_regions`] with no compactness floor gives), and the squared error of
/// each cut's mean-colour fill is known without cutting or drawing it ([`Hierarchy::flat_error`]).
/// One over-segmentation then serves every budget.
#[derive(Clone, Debug)]
pub struct Hierarchy {
    base: Segmentation,
    /// The merges in order: (root kept, root merged into it), labels of the base.
    merges: Vec<(u32, u32)>,
    /// The squared colour error of the mean-colour fill after each number of merges (index 0:
    /// the base).
    errors: Vec<f64>,
}

impl Hierarchy {
    /// Merges the regions of `base`, computed on `image`, down to one.
    ///
    /// # Panics
    /// If the image size differs.
    pub fn new(image: &Rgb32FImage, base: Segmentation) -> Self {
        assert_eq!(image.dimensions(), (base.width, base.height), "image and segmentation differ in size");
        let mut merging = Merging::new(&base, 0.0);
        let mut errors = vec![base.flat_errors(image).iter().sum::<f64>()];
        let mut merges = Vec::with_capacity(base.regions.len().saturating_sub(1));
        while let Some((kept, merged, cost)) = merging.merge_cheapest() {
            merges.push((kept, merged));
            errors.push(errors[errors.len() - 1] + cost);
        }
        Self { base, merges, errors }
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
    /// `regions` ([`Hierarchy::cut`]) with its mean colour.
    pub fn flat_error(&self, regions: usize) -> f64 {
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
        let labels: Vec<u32> = self.base.labels.iter().map(|&l| root(l)).collect();
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
}

impl Default for SegmentOptions {
    fn default() -> Self {
        Self { compactness: 30.0, oversegment: 1.0, min_compactness: 0.0 }
    }
}

/// `image` split into at most `regions` superpixels: SLIC for `regions × oversegment` (capped
/// at the pixel count), then merged down by colour. SLIC itself returns a few percent fewer
/// regions than asked for (its grid and connectivity steps), so an oversegment slightly above
/// 1 gives the count exactly.
pub fn segment(
    image: &Rgb32FImage,
    regions: usize,
    options: &SegmentOptions,
) -> Result<Segmentation, SlicError> {
    if !(options.oversegment.is_finite() && options.oversegment >= 1.0) {
        return Err(SlicError::BadOption("oversegment must be at least 1"));
    }
    let pixels = (image.width() as usize) * (image.height() as usize);
    let asked = ((regions as f64 * options.oversegment as f64).ceil() as usize).clamp(1, pixels.max(1));
    let slic_options =
        SlicOptions { n_segments: asked, compactness: options.compactness, ..Default::default() };
    Ok(slic(image, &slic_options)?.limit_regions(image, regions.max(1), options.min_compactness as f64))
}

/// A candidate merge in the queue: its cost and the two roots with their versions when it was
/// queued (a merge changes a root's version, making its old candidates stale).
#[derive(PartialEq)]
struct Candidate {
    cost: f64,
    a: u32,
    b: u32,
    versions: (u32, u32),
}

impl Eq for Candidate {}

impl Ord for Candidate {
    /// Reversed on cost (the queue is a max-heap), ties broken by the lower labels.
    fn cmp(&self, other: &Self) -> Ordering {
        other.cost.total_cmp(&self.cost).then_with(|| (other.a, other.b).cmp(&(self.a, self.b)))
    }
}

impl PartialOrd for Candidate {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// Regions being merged: union-find over labels, each root's pixel count, colour sum,
/// perimeter (pixel edges) and version, the length of border each pair of touching roots
/// shares, and a queue of candidate merges.
struct Merging {
    parent: Vec<u32>,
    size: Vec<f64>,
    sum: Vec<[f64; 3]>,
    perimeter: Vec<f64>,
    version: Vec<u32>,
    borders: Vec<BTreeMap<u32, f64>>,
    queue: BinaryHeap<Candidate>,
    /// Merges whose union would be less compact than this are passed over.
    min_compactness: f64,
}

impl Merging {
    fn new(segmentation: &Segmentation, min_compactness: f64) -> Self {
        let count = segmentation.regions.len();
        let size = segmentation.regions.iter().map(|r| r.pixels as f64).collect();
        let sum =
            segmentation.regions.iter().map(|r| r.mean_color.map(|c| c as f64 * r.pixels as f64)).collect();
        let mut borders = vec![BTreeMap::new(); count];
        let mut perimeter = vec![0.0; count];
        let (width, height) = (segmentation.width as usize, segmentation.height as usize);
        for (index, &label) in segmentation.labels.iter().enumerate() {
            let neighbours = neighbours4(index, width, height);
            for neighbour in neighbours {
                match neighbour.map(|n| segmentation.labels[n]) {
                    Some(other) if other == label => {}
                    Some(other) => {
                        perimeter[label as usize] += 1.0;
                        *borders[label as usize].entry(other).or_insert(0.0) += 1.0;
                    }
                    None => perimeter[label as usize] += 1.0,
                }
            }
        }
        let mut merging = Self {
            parent: (0..count as u32).collect(),
            size,
            sum,
            perimeter,
            version: vec![0; count],
            borders,
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

    /// Queues every pair of touching roots.
    fn enqueue_all(&mut self) {
        self.queue.clear();
        for a in 0..self.parent.len() as u32 {
            if self.parent[a as usize] != a {
                continue;
            }
            let later: Vec<u32> = self.borders[a as usize].keys().copied().filter(|&b| b > a).collect();
            later.into_iter().for_each(|b| self.enqueue(a, b));
        }
    }

    fn enqueue(&mut self, a: u32, b: u32) {
        let (ia, ib) = (a as usize, b as usize);
        let (na, nb) = (self.size[ia], self.size[ib]);
        let difference: f64 = (0..3).map(|c| (self.sum[ia][c] / na - self.sum[ib][c] / nb).powi(2)).sum();
        let cost = na * nb / (na + nb) * difference;
        self.queue.push(Candidate { cost, a, b, versions: (self.version[ia], self.version[ib]) });
    }

    /// The isoperimetric quotient 4πn/P² of the union of roots `a` and `b` (1 for a disc,
    /// π/4 for a square of pixels, small for thin or ragged shapes).
    fn compactness_of_union(&self, a: u32, b: u32) -> f64 {
        let shared = self.borders[a as usize].get(&b).copied().unwrap_or(0.0);
        let perimeter = self.perimeter[a as usize] + self.perimeter[b as usize] - 2.0 * shared;
        4.0 * std::f64::consts::PI * (self.size[a as usize] + self.size[b as usize])
            / perimeter.powi(2).max(1.0)
    }

    /// Merges the touching pair of roots that is cheapest to merge among those whose union is
    /// compact enough; when none is left, drops the compactness floor for good, so the count can
    /// always be reached. Returns the root kept, the root merged into it and the merge's cost
    /// (how much the squared error of the mean-colour fill grows); `None` only when no two
    /// regions touch.
    fn merge_cheapest(&mut self) -> Option<(u32, u32, f64)> {
        loop {
            while let Some(Candidate { cost, a, b, versions }) = self.queue.pop() {
                let current = (self.version[a as usize], self.version[b as usize]);
                let roots = self.parent[a as usize] == a && self.parent[b as usize] == b;
                if roots && versions == current && self.compactness_of_union(a, b) >= self.min_compactness {
                    self.join(a, b);
                    return Some((a, b, cost));
                }
            }
            if self.min_compactness <= 0.0 {
                return None;
            }
            self.min_compactness = 0.0;
            self.enqueue_all();
        }
    }

    /// Merges root `b` into root `a` and queues `a`'s new candidates.
    fn join(&mut self, a: u32, b: u32) {
        let (ia, ib) = (a as usize, b as usize);
        let shared = self.borders[ia].get(&b).copied().unwrap_or(0.0);
        self.parent[ib] = a;
        self.size[ia] += self.size[ib];
        self.perimeter[ia] += self.perimeter[ib] - 2.0 * shared;
        for c in 0..3 {
            self.sum[ia][c] += self.sum[ib][c];
        }
        self.version[ia] += 1;
        let moved = std::mem::take(&mut self.borders[ib]);
        for (other, length) in moved {
            if other == a {
                continue;
            }
            let theirs = &mut self.borders[other as usize];
            theirs.remove(&b);
            *theirs.entry(a).or_insert(0.0) += length;
            *self.borders[ia].entry(other).or_insert(0.0) += length;
        }
        self.borders[ia].remove(&b);
        let around: Vec<u32> = self.borders[ia].keys().copied().collect();
        around.into_iter().for_each(|other| self.enqueue(a, other));
    }
}
