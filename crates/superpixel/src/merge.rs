//! Fewer, better regions: SLIC at a finer scale, then the most alike neighbours merged.

use std::cmp::Ordering;
use std::collections::{BTreeSet, BinaryHeap};

use image::Rgb32FImage;

use crate::connectivity::relabel;
use crate::slic::{Segmentation, SlicError, SlicOptions, slic};

impl Segmentation {
    /// The same segmentation with at most `max_regions` regions: while there are more, the two
    /// 4-adjacent regions whose union raises the squared colour error of a mean-colour fill the
    /// least (Ward's criterion, `n₁n₂/(n₁+n₂)·|c₁ − c₂|²`) become one. Regions stay 4-connected.
    /// Statistics are recomputed from `image`, the image this segmentation was computed on.
    ///
    /// Merging by colour rather than by size matters: SLIC's smallest regions sit on
    /// high-contrast detail, and merging them away costs far more than joining two flat
    /// neighbours (on a 512² photo, 520 regions cut to 499 by size lose 0.8 dB of mosaic PSNR;
    /// 1000 cut to 499 by colour gain 1.4 dB over asking SLIC for 499).
    ///
    /// # Panics
    /// If `max_regions` is 0 or the image size differs.
    pub fn limit_regions(self, image: &Rgb32FImage, max_regions: usize) -> Self {
        assert!(max_regions > 0, "at least one region");
        assert_eq!(image.dimensions(), (self.width, self.height), "image and segmentation differ in size");
        let count = self.regions.len();
        if count <= max_regions {
            return self;
        }
        let mut merging = Merging::new(&self);
        let mut alive = count;
        while alive > max_regions && merging.merge_cheapest() {
            alive -= 1;
        }
        let labels: Vec<u32> = self.labels.iter().map(|&l| merging.root(l)).collect();
        let (labels, count) = relabel(&labels);
        Self::from_labels(image, labels, count)
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
}

impl Default for SegmentOptions {
    fn default() -> Self {
        Self { compactness: 30.0, oversegment: 1.0 }
    }
}

/// `image` split into at most `regions` superpixels: SLIC for `regions × oversegment` (capped
/// at the pixel count), then merged down by colour. SLIC itself returns a few percent fewer
/// regions than asked for (its grid and connectivity steps), so an oversegment slightly above
/// 1 gives the count exactly.
pub fn segment(image: &Rgb32FImage, regions: usize, options: &SegmentOptions) -> Result<Segmentation, SlicError> {
    if !(options.oversegment.is_finite() && options.oversegment >= 1.0) {
        return Err(SlicError::BadOption("oversegment must be at least 1"));
    }
    let pixels = (image.width() as usize) * (image.height() as usize);
    let asked = ((regions as f64 * options.oversegment as f64).ceil() as usize).clamp(1, pixels.max(1));
    let slic_options = SlicOptions { n_segments: asked, compactness: options.compactness, ..Default::default() };
    Ok(slic(image, &slic_options)?.limit_regions(image, regions.max(1)))
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

/// Regions being merged: union-find over labels, each root's pixel count, colour sum and
/// version, the roots that touch, and a queue of candidate merges.
struct Merging {
    parent: Vec<u32>,
    size: Vec<f64>,
    sum: Vec<[f64; 3]>,
    version: Vec<u32>,
    neighbours: Vec<BTreeSet<u32>>,
    queue: BinaryHeap<Candidate>,
}

impl Merging {
    fn new(segmentation: &Segmentation) -> Self {
        let count = segmentation.regions.len();
        let size = segmentation.regions.iter().map(|r| r.pixels as f64).collect();
        let sum = segmentation.regions.iter().map(|r| r.mean_color.map(|c| c as f64 * r.pixels as f64)).collect();
        let mut neighbours = vec![BTreeSet::new(); count];
        let width = segmentation.width as usize;
        for (index, &label) in segmentation.labels.iter().enumerate() {
            let right = (index % width + 1 < width).then(|| segmentation.labels[index + 1]);
            let below = segmentation.labels.get(index + width).copied();
            for other in [right, below].into_iter().flatten().filter(|&o| o != label) {
                neighbours[label as usize].insert(other);
                neighbours[other as usize].insert(label);
            }
        }
        let mut merging =
            Self { parent: (0..count as u32).collect(), size, sum, version: vec![0; count], neighbours, queue: BinaryHeap::new() };
        for a in 0..count as u32 {
            let later: Vec<u32> = merging.neighbours[a as usize].iter().copied().filter(|&b| b > a).collect();
            later.into_iter().for_each(|b| merging.enqueue(a, b));
        }
        merging
    }

    fn root(&self, mut label: u32) -> u32 {
        while self.parent[label as usize] != label {
            label = self.parent[label as usize];
        }
        label
    }

    fn enqueue(&mut self, a: u32, b: u32) {
        let (ia, ib) = (a as usize, b as usize);
        let (na, nb) = (self.size[ia], self.size[ib]);
        let difference: f64 = (0..3).map(|c| (self.sum[ia][c] / na - self.sum[ib][c] / nb).powi(2)).sum();
        let cost = na * nb / (na + nb) * difference;
        self.queue.push(Candidate { cost, a, b, versions: (self.version[ia], self.version[ib]) });
    }

    /// Merges the touching pair of roots that is cheapest to merge; false if none is left.
    fn merge_cheapest(&mut self) -> bool {
        while let Some(Candidate { a, b, versions, .. }) = self.queue.pop() {
            let current = (self.version[a as usize], self.version[b as usize]);
            let roots = self.parent[a as usize] == a && self.parent[b as usize] == b;
            if roots && versions == current {
                self.join(a, b);
                return true;
            }
        }
        false
    }

    /// Merges root `b` into root `a` and queues `a`'s new candidates.
    fn join(&mut self, a: u32, b: u32) {
        let (ia, ib) = (a as usize, b as usize);
        self.parent[ib] = a;
        self.size[ia] += self.size[ib];
        for c in 0..3 {
            self.sum[ia][c] += self.sum[ib][c];
        }
        self.version[ia] += 1;
        let moved = std::mem::take(&mut self.neighbours[ib]);
        for other in moved {
            self.neighbours[other as usize].remove(&b);
            if other != a {
                self.neighbours[other as usize].insert(a);
                self.neighbours[ia].insert(other);
            }
        }
        self.neighbours[ia].remove(&b);
        let around: Vec<u32> = self.neighbours[ia].iter().copied().collect();
        around.into_iter().for_each(|other| self.enqueue(a, other));
    }
}
