//! SLIC properties on synthetic images: coverage, connectivity, count, boundary adherence,
//! compactness, and bad input.

use std::collections::HashMap;

use image::{Rgb, Rgb32FImage};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use superpixel::{CropOptions, Hierarchy, SlicError, SlicOptions, slic};

/// A flat-colour picture of random convex polygons over a background, plus Gaussian-ish noise,
/// with its ground-truth label map.
fn polygons(width: u32, height: u32, count: usize, noise: f32, seed: u64) -> (Rgb32FImage, Vec<u32>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let shapes: Vec<(Vec<[f32; 2]>, [f32; 3])> = (0..count)
        .map(|_| {
            let center =
                [rng.random_range(0.15..0.85) * width as f32, rng.random_range(0.15..0.85) * height as f32];
            let radius = rng.random_range(0.1..0.3) * width.min(height) as f32;
            let sides = rng.random_range(3..7);
            let start = rng.random_range(0.0..std::f32::consts::TAU);
            let corners = (0..sides)
                .map(|i| {
                    let angle = start + i as f32 * std::f32::consts::TAU / sides as f32;
                    [center[0] + radius * angle.cos(), center[1] + radius * angle.sin()]
                })
                .collect();
            (corners, [rng.random(), rng.random(), rng.random()])
        })
        .collect();
    let inside = |corners: &[[f32; 2]], [x, y]: [f32; 2]| {
        (0..corners.len()).all(|i| {
            let (a, b) = (corners[i], corners[(i + 1) % corners.len()]);
            (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]) >= 0.0
        })
    };
    let mut labels = vec![0u32; (width * height) as usize];
    let image = Rgb32FImage::from_fn(width, height, |x, y| {
        let point = [x as f32 + 0.5, y as f32 + 0.5];
        let mut color = [0.5, 0.5, 0.5];
        for (index, (corners, shape_color)) in shapes.iter().enumerate() {
            if inside(corners, point) {
                color = *shape_color;
                labels[(y * width + x) as usize] = index as u32 + 1;
            }
        }
        let mut noisy = || (rng.random::<f32>() + rng.random::<f32>() - 1.0) * noise;
        Rgb(color.map(|c| (c + noisy()).clamp(0.0, 1.0)))
    });
    (image, labels)
}

/// A natural-like image: smooth colour gradients, shapes, fine texture.
fn natural_like(width: u32, height: u32, seed: u64) -> Rgb32FImage {
    let (shapes, _) = polygons(width, height, 12, 0.05, seed);
    Rgb32FImage::from_fn(width, height, |x, y| {
        let (u, v) = (x as f32 / width as f32, y as f32 / height as f32);
        let p = shapes.get_pixel(x, y).0;
        let wave = 0.15 * ((u * 9.0).sin() * (v * 7.0).cos());
        Rgb([
            (p[0] * 0.7 + 0.3 * u + wave).clamp(0.0, 1.0),
            (p[1] * 0.7 + 0.3 * v).clamp(0.0, 1.0),
            (p[2] * 0.8 - wave).clamp(0.0, 1.0),
        ])
    })
}

fn is_four_connected(labels: &[u32], width: usize, label: u32) -> bool {
    let members: Vec<usize> = (0..labels.len()).filter(|&i| labels[i] == label).collect();
    let mut seen = vec![false; labels.len()];
    let mut stack = vec![members[0]];
    seen[members[0]] = true;
    let mut reached = 0;
    while let Some(i) = stack.pop() {
        reached += 1;
        let (x, y) = (i % width, i / width);
        let neighbours = [
            (x > 0).then(|| i - 1),
            (x + 1 < width).then(|| i + 1),
            (y > 0).then(|| i - width),
            (i + width < labels.len()).then(|| i + width),
        ];
        for n in neighbours.into_iter().flatten() {
            if !seen[n] && labels[n] == label {
                seen[n] = true;
                stack.push(n);
            }
        }
    }
    reached == members.len()
}

#[test]
fn labels_cover_are_contiguous_connected_and_about_as_many_as_asked() {
    for (seed, (width, height), n_segments) in
        [(1, (200, 150), 100), (2, (320, 240), 256), (3, (97, 211), 40)]
    {
        let image = natural_like(width, height, seed);
        let seg = slic(&image, &SlicOptions { n_segments, ..Default::default() }).unwrap();
        assert_eq!(seg.labels.len(), (width * height) as usize);
        let count = seg.regions.len();
        assert!(seg.labels.iter().all(|&l| (l as usize) < count));
        assert!(seg.regions.iter().all(|r| r.pixels > 0), "every label is used");
        assert_eq!(seg.regions.iter().map(|r| r.pixels).sum::<usize>(), seg.labels.len());
        let ratio = count as f32 / n_segments as f32;
        assert!((0.75..=1.25).contains(&ratio), "{count} regions for {n_segments} asked");
        for label in 0..count as u32 {
            assert!(is_four_connected(&seg.labels, width as usize, label), "region {label} is split");
        }
        // Statistics agree with the label map.
        let r = seg.regions[count / 2];
        let (x, y) = (r.bbox.columns(), r.bbox.rows());
        let label = (count / 2) as u32;
        let inside = y
            .clone()
            .flat_map(|y| x.clone().map(move |x| (x, y)))
            .filter(|&(x, y)| seg.label(x, y) == label)
            .count();
        assert_eq!(inside, r.pixels);
    }
}

/// Fraction of ground-truth boundary pixels with a superpixel boundary within `tolerance`.
fn boundary_recall(truth: &[u32], labels: &[u32], width: usize, tolerance: isize) -> f32 {
    let height = truth.len() / width;
    let boundary = |map: &[u32], x: usize, y: usize| {
        (x + 1 < width && map[y * width + x] != map[y * width + x + 1])
            || (y + 1 < height && map[y * width + x] != map[(y + 1) * width + x])
    };
    let (mut found, mut total) = (0, 0);
    for y in 0..height {
        for x in 0..width {
            if !boundary(truth, x, y) {
                continue;
            }
            total += 1;
            let near = (-tolerance..=tolerance).any(|dy| {
                (-tolerance..=tolerance).any(|dx| {
                    let (nx, ny) = (x as isize + dx, y as isize + dy);
                    (0..width as isize).contains(&nx)
                        && (0..height as isize).contains(&ny)
                        && boundary(labels, nx as usize, ny as usize)
                })
            });
            found += usize::from(near);
        }
    }
    found as f32 / total as f32
}

/// Undersegmentation error (Neubert & Protzel): superpixel area leaking across ground-truth
/// segments, `Σ_G Σ_{S ∩ G ≠ ∅} min(|S ∩ G|, |S \ G|) / N`.
fn undersegmentation_error(truth: &[u32], labels: &[u32]) -> f32 {
    let mut overlap: HashMap<(u32, u32), usize> = HashMap::new();
    let mut size: HashMap<u32, usize> = HashMap::new();
    for (&t, &s) in truth.iter().zip(labels) {
        *overlap.entry((t, s)).or_default() += 1;
        *size.entry(s).or_default() += 1;
    }
    let leak: usize = overlap.iter().map(|(&(_, s), &inside)| inside.min(size[&s] - inside)).sum();
    leak as f32 / truth.len() as f32
}

#[test]
fn boundaries_follow_flat_colour_polygons() {
    for seed in 0..4 {
        let (image, truth) = polygons(256, 256, 5, 0.05, seed);
        let seg = slic(&image, &SlicOptions { n_segments: 200, ..Default::default() }).unwrap();
        let recall = boundary_recall(&truth, &seg.labels, 256, 2);
        let error = undersegmentation_error(&truth, &seg.labels);
        assert!(recall >= 0.9, "seed {seed}: boundary recall {recall}");
        assert!(error <= 0.1, "seed {seed}: undersegmentation error {error}");
    }
}

/// Mean isoperimetric quotient 4πA/P² of the regions (1 for a disc, π/4 for a square).
fn mean_isoperimetric_quotient(labels: &[u32], width: usize, count: usize) -> f32 {
    let height = labels.len() / width;
    let (mut area, mut perimeter) = (vec![0.0f32; count], vec![0.0f32; count]);
    for y in 0..height {
        for x in 0..width {
            let label = labels[y * width + x];
            area[label as usize] += 1.0;
            let edges = [
                (x == 0) || labels[y * width + x - 1] != label,
                (x + 1 == width) || labels[y * width + x + 1] != label,
                (y == 0) || labels[(y - 1) * width + x] != label,
                (y + 1 == height) || labels[(y + 1) * width + x] != label,
            ];
            perimeter[label as usize] += edges.iter().filter(|&&e| e).count() as f32;
        }
    }
    area.iter().zip(&perimeter).map(|(a, p)| 4.0 * std::f32::consts::PI * a / (p * p)).sum::<f32>()
        / count as f32
}

#[test]
fn higher_compactness_gives_more_regular_regions() {
    let image = natural_like(240, 240, 9);
    let quotient = |compactness| {
        let seg = slic(&image, &SlicOptions { n_segments: 150, compactness, ..Default::default() }).unwrap();
        mean_isoperimetric_quotient(&seg.labels, 240, seg.regions.len())
    };
    let (loose, regular) = (quotient(2.0), quotient(40.0));
    assert!(regular > loose + 0.05, "compactness 40: {regular}, compactness 2: {loose}");
}

#[test]
fn deterministic() {
    let image = natural_like(120, 90, 4);
    let options = SlicOptions { n_segments: 30, ..Default::default() };
    assert_eq!(slic(&image, &options).unwrap(), slic(&image, &options).unwrap());
}

#[test]
fn bad_inputs_are_errors_not_panics() {
    let empty = Rgb32FImage::new(0, 0);
    assert!(matches!(slic(&empty, &SlicOptions::default()), Err(SlicError::EmptyImage { .. })));
    let one = Rgb32FImage::from_pixel(1, 1, Rgb([0.3, 0.2, 0.1]));
    let seg = slic(&one, &SlicOptions { n_segments: 1, ..Default::default() }).unwrap();
    assert_eq!((seg.labels.clone(), seg.regions.len()), (vec![0], 1));
    let crop = seg.crop(&one, 0, &CropOptions { size: 4, ..Default::default() });
    assert!(crop.mask.iter().all(|&m| m == 1.0));
    assert!((crop.pixels[0] - 0.3).abs() < 1e-6);
    for n_segments in [0, 2] {
        let err = slic(&one, &SlicOptions { n_segments, ..Default::default() }).unwrap_err();
        assert_eq!(err, SlicError::BadSegmentCount { n_segments, pixels: 1 });
    }
    let bad = SlicOptions { compactness: f32::NAN, ..Default::default() };
    assert!(matches!(slic(&one, &SlicOptions { n_segments: 1, ..bad }), Err(SlicError::BadOption(_))));
    // A thin strip and a tall one.
    for (w, h) in [(500, 2), (1, 300)] {
        let strip = natural_like(w, h, 5);
        let seg = slic(&strip, &SlicOptions { n_segments: 10, ..Default::default() }).unwrap();
        // A valid segmentation: every pixel labelled, every region used. Its grid cannot be
        // wider than the strip, so thin strips get more regions than asked (50 and 55 of 10
        // here), but never fewer than two or more than one per 4 pixels.
        assert_eq!(seg.labels.len(), (w * h) as usize);
        assert!(seg.labels.iter().all(|&l| (l as usize) < seg.regions.len()));
        assert!(seg.regions.iter().all(|r| r.pixels > 0));
        assert_eq!(seg.regions.iter().map(|r| r.pixels).sum::<usize>(), (w * h) as usize);
        assert!((2..=(w * h / 4) as usize).contains(&seg.regions.len()), "{w}×{h}: {}", seg.regions.len());
    }
}

#[test]
fn crop_of_a_region_holds_its_colour_and_mask() {
    // A red square on grey: the square is one region; its crop at its own size is all red and
    // all mask, with the grey padding masked out and filled.
    let image = Rgb32FImage::from_fn(60, 60, |x, y| {
        if (20..40).contains(&x) && (20..40).contains(&y) {
            Rgb([1.0, 0.0, 0.0])
        } else {
            Rgb([0.5, 0.5, 0.5])
        }
    });
    let seg = slic(&image, &SlicOptions { n_segments: 9, sigma: 0.0, ..Default::default() }).unwrap();
    let red = seg.label(30, 30);
    let region = seg.regions[red as usize];
    assert_eq!(region.bbox, common::PixelBox::new(20, 20, 40, 40).unwrap());
    let crop = seg.crop(&image, red, &CropOptions { size: 24, padding: 2, fill: -1.0 });
    assert_eq!((crop.transform.x, crop.transform.width), (18.0, 24.0));
    for v in 0..24 {
        for u in 0..24 {
            let inside = (2..22).contains(&u) && (2..22).contains(&v);
            assert_eq!(crop.mask[v * 24 + u], if inside { 1.0 } else { 0.0 }, "cell ({u}, {v})");
            let expected = if inside { 1.0 } else { -1.0 };
            assert_eq!(crop.pixels[v * 24 + u], expected);
        }
    }
}

#[test]
fn flat_errors_are_what_a_mean_colour_fill_leaves() {
    // Left half flat, right half a ramp: only regions on the ramp leave anything to draw.
    let image = Rgb32FImage::from_fn(64, 32, |x, _| {
        if x < 32 { image::Rgb([0.2, 0.4, 0.6]) } else { image::Rgb([(x - 32) as f32 / 31.0, 0.5, 0.5]) }
    });
    let segmentation = slic(&image, &SlicOptions { n_segments: 8, ..Default::default() }).unwrap();
    let errors = segmentation.flat_errors(&image);
    assert_eq!(errors.len(), segmentation.regions.len());
    // Σ‖p − mean‖² = Σ‖p‖² − n‖mean‖², from the pixels alone.
    let (mut sums, mut squares, mut counts) =
        (vec![[0.0f64; 3]; errors.len()], vec![0.0f64; errors.len()], vec![0.0f64; errors.len()]);
    for (index, pixel) in image.pixels().enumerate() {
        let label = segmentation.labels[index] as usize;
        counts[label] += 1.0;
        for c in 0..3 {
            sums[label][c] += pixel.0[c] as f64;
            squares[label] += (pixel.0[c] as f64).powi(2);
        }
    }
    let want: Vec<f64> = (0..errors.len())
        .map(|r| squares[r] - sums[r].iter().map(|s| s * s).sum::<f64>() / counts[r])
        .collect();
    for (region, (got, want)) in errors.iter().zip(&want).enumerate() {
        assert!((got - want).abs() <= 1e-4, "region {region}: {got} vs {want}");
        let bbox = segmentation.regions[region].bbox;
        if bbox.x1() <= 32 {
            assert!(*got < 1e-6, "a flat region leaves {got}");
        }
    }
    assert!(errors.iter().any(|&e| e > 0.1), "the ramp's regions leave error: {errors:?}");
}

#[test]
fn a_hierarchy_cut_is_the_merge_down_to_its_count_and_knows_its_error() {
    let image = natural_like(72, 48, 9);
    let base = slic(&image, &SlicOptions { n_segments: 120, ..Default::default() }).unwrap();
    let hierarchy = Hierarchy::new(&image, base.clone());
    assert_eq!(hierarchy.most_regions(), base.regions.len());
    assert_eq!(hierarchy.fewest_regions(), 1, "an image in one piece merges down to one region");
    let mut last = -1.0;
    for regions in [base.regions.len(), 90, 40, 7, 1] {
        let cut = hierarchy.cut(&image, regions);
        assert_eq!(cut.regions.len(), regions);
        assert_eq!(cut, base.clone().limit_regions(&image, regions, 0.0), "cut at {regions}");
        let error = cut.flat_error(&image);
        let known = hierarchy.fill_error(regions);
        assert!((error - known).abs() <= 1e-3 * error.max(1.0), "{regions}: {known} known, {error} drawn");
        assert!(known >= last, "fewer regions never fit better: {known} after {last}");
        last = known;
    }
}
