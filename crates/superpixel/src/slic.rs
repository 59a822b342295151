//! SLIC: simple linear iterative clustering in CIELAB × image plane (Achanta et al., TPAMI 2012).

use common::PixelBox;
use image::Rgb32FImage;
use rayon::prelude::*;

use crate::color::{gaussian_blur, srgb_to_lab};
use crate::connectivity::enforce_connectivity;

/// Options of [`slic`]; the defaults are the method's (compactness 30) and scikit-image's.
#[derive(Clone, Debug, PartialEq)]
pub struct SlicOptions {
    /// Approximate number of regions wanted.
    pub n_segments: usize,
    /// Weight of spatial against colour distance: higher gives more regular, more square regions.
    pub compactness: f32,
    /// Standard deviation in pixels of the Gaussian pre-smoothing (0 turns it off).
    pub sigma: f32,
    /// Upper bound on assignment/update rounds (stops early once no pixel changes region).
    pub max_iterations: usize,
    /// Make every region one 4-connected piece, merging fragments smaller than
    /// `min_size_factor` × the mean region size into a neighbour.
    pub enforce_connectivity: bool,
    /// See `enforce_connectivity`.
    pub min_size_factor: f32,
}

impl Default for SlicOptions {
    fn default() -> Self {
        Self {
            n_segments: 100,
            compactness: 30.0,
            sigma: 1.0,
            max_iterations: 10,
            enforce_connectivity: true,
            min_size_factor: 0.5,
        }
    }
}

/// Why an image cannot be segmented.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SlicError {
    /// The image has no pixels.
    #[error("the image is empty ({width}×{height})")]
    EmptyImage {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
    },
    /// `n_segments` is 0 or larger than the number of pixels.
    #[error("cannot split {pixels} pixels into {n_segments} regions")]
    BadSegmentCount {
        /// Requested region count.
        n_segments: usize,
        /// Pixels in the image.
        pixels: usize,
    },
    /// An option is out of range.
    #[error("invalid SLIC option: {0}")]
    BadOption(&'static str),
}

/// What a region is: size, extent and mean colour.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Region {
    /// Number of pixels.
    pub pixels: usize,
    /// Tight bounding box.
    pub bbox: PixelBox,
    /// Mean RGB of the region's pixels in the input image.
    pub mean_color: [f32; 3],
}

/// A label map with labels `0..regions.len()`, every label used, plus per-region statistics.
#[derive(Clone, Debug, PartialEq)]
pub struct Segmentation {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Row-major label of every pixel.
    pub labels: Vec<u32>,
    /// Statistics of region `r` at index `r`.
    pub regions: Vec<Region>,
}

impl Segmentation {
    /// Every 4-connected area of one exact colour of `image` a region, if there are at most
    /// `most` of them (and any pixels): flat art's over-segmentation, whose regions have no
    /// error of their own and whose anti-aliased edges are regions of their own. A photo, with
    /// about as many colours as pixels, is given up within its first rows.
    pub fn flat_areas(image: &Rgb32FImage, most: usize) -> Option<Self> {
        let mut colours = std::collections::HashMap::new();
        let mut labels = Vec::with_capacity(image.len() / 3);
        for pixel in image.pixels() {
            let next = colours.len() as u32;
            labels.push(*colours.entry(pixel.0.map(f32::to_bits)).or_insert(next));
            if colours.len() > most {
                return None;
            }
        }
        let (labels, count) =
            enforce_connectivity(&labels, image.width() as usize, image.height() as usize, 0);
        (1..=most).contains(&count).then(|| Self::from_labels(image, labels, count))
    }

    /// Label of pixel (x, y).
    pub fn label(&self, x: u32, y: u32) -> u32 {
        self.labels[(y * self.width + x) as usize]
    }

    /// The squared RGB error of filling every region with its mean colour (the sum of
    /// [`Segmentation::flat_errors`]): how well the regions alone can draw the image, without
    /// tracing or rendering them. `image` is the one segmented.
    ///
    /// # Panics
    /// If `image` is not of the segmentation's size.
    pub fn flat_error(&self, image: &Rgb32FImage) -> f64 {
        self.flat_errors(image).iter().sum()
    }

    /// Per region, the squared RGB error of filling it with its mean colour (the sum over its
    /// pixels of ‖pixel − mean‖²): what a region drawn flat leaves to draw. `image` is the
    /// one segmented.
    ///
    /// # Panics
    /// If `image` is not of the segmentation's size.
    pub fn flat_errors(&self, image: &Rgb32FImage) -> Vec<f64> {
        assert_eq!(image.dimensions(), (self.width, self.height), "image and segmentation sizes");
        let mut errors = vec![0.0f64; self.regions.len()];
        for (pixel, &label) in image.pixels().zip(&self.labels) {
            let mean = self.regions[label as usize].mean_color;
            errors[label as usize] += (0..3).map(|c| ((pixel.0[c] - mean[c]) as f64).powi(2)).sum::<f64>();
        }
        errors
    }

    /// A segmentation drawn as text for tests: one row a string, one digit a pixel's label
    /// (labels 0 to the largest digit; the image black).
    #[cfg(test)]
    pub(crate) fn from_rows(rows: &[&str]) -> Self {
        let (width, height) = (rows[0].len() as u32, rows.len() as u32);
        let labels: Vec<u32> = rows.iter().flat_map(|row| row.bytes().map(|b| (b - b'0') as u32)).collect();
        let count = *labels.iter().max().unwrap() as usize + 1;
        Self::from_labels(&Rgb32FImage::new(width, height), labels, count)
    }

    /// Builds the segmentation of `image` from a label map whose labels are `0..count`, all used.
    pub(crate) fn from_labels(image: &Rgb32FImage, labels: Vec<u32>, count: usize) -> Self {
        let (width, height) = image.dimensions();
        // (pixels, box, colour sum) per label; every label is used, so every box gets a pixel.
        let mut sums: Vec<(usize, Option<PixelBox>, [f32; 3])> = vec![(0, None, [0.0; 3]); count];
        for (index, pixel) in image.pixels().enumerate() {
            let (x, y) = (index as u32 % width, index as u32 / width);
            let (pixels, bbox, sum) = &mut sums[labels[index] as usize];
            *pixels += 1;
            *bbox = Some(bbox.map_or(PixelBox::pixel(x, y), |b| b.including(x, y)));
            for c in 0..3 {
                sum[c] += pixel.0[c];
            }
        }
        let regions = sums
            .into_iter()
            .map(|(pixels, bbox, sum)| Region {
                pixels,
                bbox: bbox.expect("every label is used"),
                mean_color: sum.map(|s| s / pixels.max(1) as f32),
            })
            .collect();
        Self { width, height, labels, regions }
    }
}

/// Orders `regions` (labels) by `errors[label]`, largest first, ties by label: the order in
/// which training and inference give regions to a model (the ones a drawing gets most wrong
/// first), deterministic whatever the errors.
pub fn worst_first(regions: &mut [u32], errors: &[f64]) {
    regions.sort_by(|&a, &b| errors[b as usize].total_cmp(&errors[a as usize]).then(a.cmp(&b)));
}

/// An image in CIELAB, one plane per channel (contiguous rows for the assignment loop).
struct Lab {
    l: Vec<f32>,
    a: Vec<f32>,
    b: Vec<f32>,
}

impl Lab {
    fn of(red: &[f32], green: &[f32], blue: &[f32]) -> Self {
        let lab: Vec<[f32; 3]> =
            (red, green, blue).into_par_iter().map(|(&r, &g, &b)| srgb_to_lab([r, g, b])).collect();
        Self {
            l: lab.iter().map(|p| p[0]).collect(),
            a: lab.iter().map(|p| p[1]).collect(),
            b: lab.iter().map(|p| p[2]).collect(),
        }
    }

    fn at(&self, i: usize) -> [f32; 3] {
        [self.l[i], self.a[i], self.b[i]]
    }
}

/// A cluster centre: colour in CIELAB and position in pixels.
#[derive(Clone, Copy, Debug, Default)]
struct Center {
    lab: [f32; 3],
    x: f32,
    y: f32,
}

/// Segments `image` (RGB in [0, 1]) into about `options.n_segments` superpixels.
///
/// Centres start on a regular grid of step `S = √(pixels / n_segments)`, each moved to the lowest
/// CIELAB gradient of its 3×3 neighbourhood. Each round assigns every pixel to the centre, among
/// those whose 2S × 2S window contains it, minimizing `d_lab² + (d_xy / S)² · compactness²`, then
/// moves every centre to the mean of its pixels. Deterministic; parallel over bands of rows.
pub fn slic(image: &Rgb32FImage, options: &SlicOptions) -> Result<Segmentation, SlicError> {
    let (width, height) = (image.width() as usize, image.height() as usize);
    let pixels = width * height;
    if pixels == 0 {
        return Err(SlicError::EmptyImage { width: image.width(), height: image.height() });
    }
    if options.n_segments == 0 || options.n_segments > pixels {
        return Err(SlicError::BadSegmentCount { n_segments: options.n_segments, pixels });
    }
    if !(options.compactness > 0.0 && options.compactness.is_finite()) {
        return Err(SlicError::BadOption("compactness must be positive"));
    }
    if !(options.sigma >= 0.0 && options.sigma.is_finite()) {
        return Err(SlicError::BadOption("sigma must be zero or positive"));
    }

    let planes: Vec<Vec<f32>> = (0..3)
        .map(|c| {
            let plane: Vec<f32> = image.pixels().map(|p| p.0[c]).collect();
            gaussian_blur(&plane, width, height, options.sigma)
        })
        .collect();
    let lab = Lab::of(&planes[0], &planes[1], &planes[2]);
    let grid = Grid::new(width, height, options.n_segments);
    let mut centers = grid.initial_centers(&lab);
    let spatial_weight = (options.compactness / grid.step).powi(2);

    // Every pixel starts in its grid cell's cluster, which is its own centre's initial cell.
    let mut labels: Vec<u32> = (0..pixels)
        .map(|i| {
            let (column, row) = grid.cell((i % width) as f32 + 0.5, (i / width) as f32 + 0.5);
            (row * grid.columns + column) as u32
        })
        .collect();
    for _ in 0..options.max_iterations.max(1) {
        let changed = assign(&mut labels, &centers, &lab, width, grid.step, spatial_weight);
        update_centers(&mut centers, &labels, &lab, width);
        if changed == 0 {
            break;
        }
    }

    let (labels, count) = if options.enforce_connectivity {
        let min_size = (options.min_size_factor * pixels as f32 / centers.len() as f32) as usize;
        enforce_connectivity(&labels, width, height, min_size)
    } else {
        crate::connectivity::relabel(&labels)
    };
    Ok(Segmentation::from_labels(image, labels, count))
}

/// Rows of pixels assigned by one task: tall enough to amortize scanning the centres, short
/// enough that two threads share the work evenly.
const BAND: usize = 16;

/// One SLIC assignment round: every centre claims, within its 2S × 2S window, the pixels it is
/// closer to (in `d_lab² + d_xy² · spatial_weight`) than any centre so far. Parallel over bands
/// of rows, each band scanning only the centres whose window reaches it (listed once per round,
/// in index order, so ties go to the lower index as in one pass over all centres), so no two
/// threads write the same pixel. Pixels no window reaches keep their label. Returns how many
/// changed.
fn assign(
    labels: &mut [u32],
    centers: &[Center],
    lab: &Lab,
    width: usize,
    step: f32,
    spatial_weight: f32,
) -> usize {
    let height = labels.len() / width;
    // Each band's centres: at 128 000 centres (2000 paths' free candidate), every band testing
    // every centre was more work than assigning the pixels.
    let mut reaching: Vec<Vec<u32>> = vec![Vec::new(); height.div_ceil(BAND)];
    for (index, center) in centers.iter().enumerate() {
        let y0 = floor_from(center.y - step, 0);
        let y1 = ceil_from(center.y + step).min(height);
        if y0 < y1 {
            (y0 / BAND..=(y1 - 1) / BAND).for_each(|band| reaching[band].push(index as u32));
        }
    }
    labels
        .par_chunks_mut(width * BAND)
        .zip(&reaching)
        .enumerate()
        .map(|(band, (chunk, near))| {
            let top = band * BAND;
            let bottom = top + chunk.len() / width;
            let before = chunk.to_vec();
            let mut best = vec![f32::INFINITY; chunk.len()];
            for &index in near {
                let center = &centers[index as usize];
                let y0 = floor_from(center.y - step, top);
                let y1 = ceil_from(center.y + step).min(bottom);
                let x0 = floor_from(center.x - step, 0);
                let x1 = ceil_from(center.x + step).min(width);
                for y in y0..y1 {
                    let dy = y as f32 + 0.5 - center.y;
                    let row_cost = dy * dy * spatial_weight;
                    let (pixels, local) =
                        (y * width + x0..y * width + x1, (y - top) * width + x0..(y - top) * width + x1);
                    let colours =
                        lab.l[pixels.clone()].iter().zip(&lab.a[pixels.clone()]).zip(&lab.b[pixels]);
                    let slots = best[local.clone()].iter_mut().zip(&mut chunk[local]);
                    // Branch-free, so that the row compiles to vector compares and blends.
                    for (column, (((&l, &a), &b), (best, label))) in colours.zip(slots).enumerate() {
                        let (dl, da, db) = (l - center.lab[0], a - center.lab[1], b - center.lab[2]);
                        let dx = (x0 + column) as f32 + 0.5 - center.x;
                        let cost = dl * dl + da * da + db * db + dx * dx * spatial_weight + row_cost;
                        let closer = cost < *best;
                        *best = if closer { cost } else { *best };
                        *label = if closer { index } else { *label };
                    }
                }
            }
            chunk.iter().zip(&before).filter(|(a, b)| a != b).count()
        })
        .sum()
}

/// `⌊v⌋`, at least `least`, as an index: without `f32::floor`, which is a call into libm on
/// x86-64's baseline (it was 2% of segmenting).
fn floor_from(v: f32, least: usize) -> usize {
    // Truncation is the floor of a number at least `least` ≥ 0.
    v.max(least as f32) as usize
}

/// `⌈v⌉`, at least 0, as an index (without `f32::ceil`, as [`floor_from`]).
fn ceil_from(v: f32) -> usize {
    let whole = v.max(0.0) as usize;
    whole + usize::from((whole as f32) < v)
}

/// Moves every centre to the mean colour and position of its pixels (empty ones stay put).
/// One pass on one thread: a few additions a pixel, where one accumulator per parallel task (6
/// MB each at 128 000 centres) cost more to zero and add up than the pass itself.
fn update_centers(centers: &mut [Center], labels: &[u32], lab: &Lab, width: usize) {
    let mut sums = vec![[0.0f64; 6]; centers.len()];
    for (y, row) in labels.chunks(width).enumerate() {
        for (x, &label) in row.iter().enumerate() {
            let i = y * width + x;
            let s = &mut sums[label as usize];
            for (acc, v) in s.iter_mut().zip([lab.l[i], lab.a[i], lab.b[i], x as f32, y as f32, 1.0]) {
                *acc += v as f64;
            }
        }
    }
    for (center, s) in centers.iter_mut().zip(sums) {
        let count = s[5];
        if count > 0.0 {
            let mean = |i: usize| (s[i] / count) as f32;
            *center = Center { lab: [mean(0), mean(1), mean(2)], x: mean(3), y: mean(4) };
        }
    }
}

/// The regular grid of initial centres, reused each round to find the centres near a pixel.
struct Grid {
    width: usize,
    height: usize,
    columns: usize,
    rows: usize,
    cell_width: f32,
    cell_height: f32,
    step: f32,
}

impl Grid {
    fn new(width: usize, height: usize, n_segments: usize) -> Self {
        let step = ((width * height) as f32 / n_segments as f32).sqrt();
        let columns = ((width as f32 / step).round() as usize).clamp(1, width);
        let rows = ((height as f32 / step).round() as usize).clamp(1, height);
        Self {
            width,
            height,
            columns,
            rows,
            cell_width: width as f32 / columns as f32,
            cell_height: height as f32 / rows as f32,
            step,
        }
    }

    /// Grid cell of a position, clamped to the grid.
    fn cell(&self, x: f32, y: f32) -> (usize, usize) {
        let column = ((x / self.cell_width) as usize).min(self.columns - 1);
        let row = ((y / self.cell_height) as usize).min(self.rows - 1);
        (column, row)
    }

    /// One centre per cell at its middle, moved to the lowest-gradient pixel of its 3×3
    /// neighbourhood so it does not start on an edge or a noisy pixel.
    fn initial_centers(&self, lab: &Lab) -> Vec<Center> {
        let (w, h) = (self.width as isize, self.height as isize);
        let at = |x: isize, y: isize| lab.at((y.clamp(0, h - 1) * w + x.clamp(0, w - 1)) as usize);
        let distance = |a: [f32; 3], b: [f32; 3]| (0..3).map(|c| (a[c] - b[c]).powi(2)).sum::<f32>();
        let gradient =
            |x: isize, y: isize| distance(at(x + 1, y), at(x - 1, y)) + distance(at(x, y + 1), at(x, y - 1));
        (0..self.rows * self.columns)
            .map(|i| {
                let cx = ((i % self.columns) as f32 + 0.5) * self.cell_width;
                let cy = ((i / self.columns) as f32 + 0.5) * self.cell_height;
                let (x, y) = (cx as isize, cy as isize);
                let (bx, by) = (-1..=1)
                    .flat_map(|dy| (-1..=1).map(move |dx| (x + dx, y + dy)))
                    .filter(|&(px, py)| (0..w).contains(&px) && (0..h).contains(&py))
                    .min_by(|a, b| gradient(a.0, a.1).total_cmp(&gradient(b.0, b.1)))
                    .unwrap_or((x.clamp(0, w - 1), y.clamp(0, h - 1)));
                Center { lab: at(bx, by), x: bx as f32 + 0.5, y: by as f32 + 0.5 }
            })
            .collect()
    }
}
