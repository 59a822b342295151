//! The simplest drawing of an image split into superpixels: one path under everything, then
//! every region in its mean colour: by default its outline traced along its pixel edges with
//! its staircases cut, grown a pixel under the regions painted after it; with a tolerance,
//! drawn along the boundaries it shares with its neighbours (traced once, fitted with lines and
//! cubics within the tolerance).
//!
//! Every result starts from it, so no pixel is left uncovered whatever the later stages keep,
//! and a region's learned paths are kept only where they beat it.

use std::sync::Arc;

use image::Rgb32FImage;
use raster::{Contour, Filled, Outline, Path, Segment, Shape, fit_curve, fit_outline, paint_exact};
use rayon::prelude::*;
use superpixel::{PlanarMap, Segmentation};
use tiny_skia::Pixmap;

use crate::fills::{Ramps, region_ramps};
use crate::scene::{Origin, Placed, Scene, Scope};

/// How the fallback draws its regions: their outlines and their fills.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Style {
    /// `None`: each region's traced polygon, grown under the regions painted after it; else its
    /// outline along the boundaries it shares, fitted within this many pixels.
    pub tolerance: Option<f32>,
    /// Which regions are filled with a ramp instead of their mean colour.
    pub ramps: Ramps,
}

/// How far (pixels) a region's outline is pushed outwards when it is fitted with one path
/// ([`fitted_path`]), so the paths of neighbouring regions overlap instead of leaving seams of
/// the background between them; the later region covers the overlap. Half a pixel measured
/// best on data/eval/photos (see docs/operating-point.md).
pub const GROW: f32 = 0.5;

/// A path covering the whole canvas, in the colour that is best where `above` (the paths to be
/// painted over it) leaves it showing: the mean of the image weighted by how little `above`
/// covers each pixel (the image's mean if `above` covers everything). On flat art the seams
/// between regions then show the page's colour, not a tint of everything in the picture.
pub fn background(image: &Rgb32FImage, above: &[Shape]) -> Path {
    let (width, height) = image.dimensions();
    let mut cover = Pixmap::new(width, height).expect("a non-empty image");
    for path in above {
        paint_exact(&mut cover, path, (width, height), (0, 0));
    }
    let (mut shown, mut sum, mut total) = (0.0f64, [0.0f64; 3], [0.0f64; 3]);
    for (pixel, rgba) in image.pixels().zip(cover.data().chunks_exact(4)) {
        let weight = (255 - rgba[3]) as f64 / 255.0;
        shown += weight;
        for c in 0..3 {
            sum[c] += weight * pixel.0[c] as f64;
            total[c] += pixel.0[c] as f64;
        }
    }
    let pixels = (width as f64 * height as f64).max(1.0);
    let color =
        if shown > 0.0 { sum.map(|s| (s / shown) as f32) } else { total.map(|s| (s / pixels) as f32) };
    Path::quadrilateral([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]], color, 1.0)
}

/// A tolerance for [`FallbackDrawing::new`] (pixels), for tests: half a pixel, the most a
/// staircase cut moves a boundary.
#[cfg(test)]
pub(crate) const TOLERANCE: f32 = 0.5;

/// Every boundary of a segmentation, fitted once, in the image's unit square: what the regions'
/// outlines are assembled from, so neighbours share the same curves.
struct Boundaries {
    map: PlanarMap,
    /// Per chain of `map`: where its curve starts and its pieces.
    curves: Vec<([f32; 2], Vec<Segment>)>,
}

impl Boundaries {
    /// The chains of `segmentation`, each fitted with lines and cubics within `tolerance`
    /// pixels ([`fit_curve`]; 0: the traced lines as they are), in parallel.
    fn new(segmentation: &Segmentation, tolerance: f32) -> Self {
        let map = PlanarMap::new(segmentation);
        let (width, height) = (segmentation.width as f32, segmentation.height as f32);
        let unit = |[x, y]: [f32; 2]| [x / width, y / height];
        let curves = map
            .chains()
            .par_iter()
            .map(|chain| {
                let (start, segments) = fit_curve(&chain.points, chain.closed, tolerance);
                (unit(start), segments.iter().map(|s| s.map(unit)).collect())
            })
            .collect();
        Self { map, curves }
    }

    /// The outline of the set `members`, filled with `color`: its boundary's chains, each
    /// curve as fitted (backwards where the set lies on its other side).
    fn outline(&self, members: &[u32], color: [f32; 3]) -> Option<Outline> {
        let contours = self.map.boundary(members).into_iter().map(|chains| {
            let mut contour = Contour { start: [0.0; 2], segments: Vec::new() };
            for (index, directed) in chains.iter().enumerate() {
                let (start, segments) = &self.curves[directed.chain as usize];
                let begins =
                    if directed.reversed { segments.last().map_or(*start, Segment::end) } else { *start };
                if index == 0 {
                    contour.start = begins;
                }
                if directed.reversed {
                    let starts = std::iter::once(*start).chain(segments.iter().map(Segment::end));
                    let pieces: Vec<Segment> =
                        segments.iter().zip(starts).map(|(segment, from)| segment.reversed(from)).collect();
                    contour.segments.extend(pieces.into_iter().rev());
                } else {
                    contour.segments.extend(segments.iter().copied());
                }
            }
            contour
        });
        Outline::new(contours.collect(), color, 1.0)
    }
}

/// Region `region` in its mean colour, drawn with the neighbours painted after it (`rank[r]` is
/// region `r`'s place in [`painter_order`]): the outline of their union, assembled from the
/// shared boundary curves. Painted in that order, every boundary shows as the curve the later
/// region draws it with, over the earlier one's colour, never over what lies under both (two
/// anti-aliased edges meeting on one line would let that show through: coverages of ½ and ½
/// leave ¼); a region's holes are regions painted after it. `None` for a region without pixels.
fn region_outline(
    segmentation: &Segmentation,
    boundaries: &Boundaries,
    region: u32,
    rank: &[usize],
) -> Option<Outline> {
    let mut members: Vec<u32> = boundaries
        .map
        .neighbours(region)
        .into_iter()
        .filter(|&other| rank[other as usize] > rank[region as usize])
        .collect();
    members.push(region);
    boundaries.outline(&members, segmentation.regions[region as usize].mean_color)
}

/// `outline` (unit square of a `width × height` canvas) as one path: its largest contour fitted
/// with four cubics, grown by `GROW` pixels. What fine-tuning, which moves paths, starts from;
/// `None` if the outline cannot be fitted.
pub fn fitted_path(outline: &Outline, (width, height): (u32, u32)) -> Option<Path> {
    let (width, height) = (width as f32, height as f32);
    let points: Vec<[f32; 2]> =
        outline.largest_contour(8).iter().map(|[x, y]| [x * width, y * height]).collect();
    let path = fit_outline(&points, GROW, outline.color(), outline.alpha)?;
    Some(path.map_points(|[x, y]| [x / width, y / height]))
}

/// The regions in the order they are painted: larger bounding boxes first, so a region that
/// encloses another (its box contains the other's) never covers it.
pub fn painter_order(segmentation: &Segmentation) -> Vec<u32> {
    let mut order: Vec<u32> = (0..segmentation.regions.len() as u32).collect();
    let area = |r: &u32| {
        let bbox = segmentation.regions[*r as usize].bbox;
        bbox.width() as u64 * bbox.height() as u64
    };
    order.sort_by_key(|r| (std::cmp::Reverse(area(r)), *r));
    order
}

/// Region `region`'s outline traced along its pixel edges, staircases cut and grown under the
/// regions painted after it ([`Segmentation::outline`]; the image's unit square), in its mean
/// colour; `None` for a region without pixels. Painted in painter's order, the regions'
/// polygons draw the segmentation without seams; a region's holes are regions painted after it.
fn region_polygon(segmentation: &Segmentation, region: u32, rank: &[usize]) -> Option<Outline> {
    let (width, height) = (segmentation.width as f32, segmentation.height as f32);
    let later = |other: u32| rank[other as usize] > rank[region as usize];
    let corners: Vec<[f32; 2]> =
        segmentation.outline(region, later).into_iter().map(|[x, y]| [x / width, y / height]).collect();
    Outline::polygon(&corners, segmentation.regions[region as usize].mean_color, 1.0)
}

/// Every region's outline in painter's order `order`, in parallel: its traced polygon
/// ([`region_polygon`]) without a tolerance, else its outline of shared boundaries fitted
/// within `tolerance` pixels ([`region_outline`]); each in its mean colour.
fn traced(segmentation: &Segmentation, order: &[u32], tolerance: Option<f32>) -> Vec<Option<Outline>> {
    let mut rank = vec![0; order.len()];
    for (place, &r) in order.iter().enumerate() {
        rank[r as usize] = place;
    }
    match tolerance {
        None => order.par_iter().map(|&r| region_polygon(segmentation, r, &rank)).collect(),
        Some(tolerance) => {
            let boundaries = Boundaries::new(segmentation, tolerance);
            let outline = |r: u32| region_outline(segmentation, &boundaries, r, &rank);
            order.par_iter().map(|&r| outline(r)).collect()
        }
    }
}

/// The fallback drawing of an image's segmentation: traced, rendered and scored once (for the
/// chosen segmentation), then drawn (the coarse stage starts from it, or takes its rendering as it
/// is when E_c draws nothing). A region's polygon is drawn only if it lowers the error of its
/// own pixels over what is under them (the background and the regions before it): on a flat
/// picture, whose every region has the background's colour, the drawing is the background alone.
#[derive(Clone, Debug)]
pub struct FallbackDrawing {
    /// The regions in painter's order (larger boxes first).
    pub order: Vec<u32>,
    /// Each region's polygon, in `order`; `None` where a region has no pixels or its polygon
    /// would lower nothing.
    pub regions: Vec<Option<Shape>>,
    /// The path under everything (in the colour of what the region paths leave showing).
    pub background: Path,
    /// The exact rendering of [`FallbackDrawing::paths`] (premultiplied RGBA).
    pub canvas: Pixmap,
    /// Its squared error against the image (RGB over white, summed over pixels).
    pub error: f64,
}

impl FallbackDrawing {
    /// Traces every region of `segmentation` (in parallel; with a tolerance, as shared
    /// boundaries fitted within it, as `traced` does), fills each as `style` says, fits the
    /// background of `image` under them, renders the drawing and scores it.
    pub fn new(image: &Arc<Rgb32FImage>, segmentation: &Arc<Segmentation>, style: Style) -> Self {
        let order = painter_order(segmentation);
        let mut outlines = traced(segmentation, &order, style.tolerance);
        let ramps = region_ramps(image, segmentation, &order, &outlines, style.ramps);
        for (outline, ramp) in outlines.iter_mut().zip(ramps) {
            if let (Some(outline), Some(ramp)) = (outline, ramp) {
                outline.fill = ramp.into();
            }
        }
        let regions: Vec<Option<Shape>> = outlines.into_iter().map(|o| o.map(Shape::from)).collect();
        let background = background(image, &regions.iter().flatten().cloned().collect::<Vec<_>>());
        let mut scene = Scene::new(image.clone(), segmentation.clone());
        scene.push(Placed { shape: background.into(), region: None, origin: Origin::Background });
        // Judged on its own pixels only: a polygon also covers its neighbours' (a region with
        // holes covers them whole), which the regions painted after it cover again.
        let mut own = vec![false; segmentation.regions.len()];
        let regions = order
            .iter()
            .zip(regions)
            .map(|(&region, shape)| {
                let placed = Placed { shape: shape?, region: Some(region), origin: Origin::Fallback };
                let shape = placed.shape.clone();
                own[region as usize] = true;
                let kept = scene.try_push(placed, Scope::Regions(&own)).map(|_| shape);
                own[region as usize] = false;
                kept
            })
            .collect();
        let error = scene.total_error();
        Self { order, regions, background, canvas: scene.into_canvas(), error }
    }

    /// The drawing alone: the background, then every region's polygon in painter's order.
    pub fn paths(&self) -> Vec<Shape> {
        self.placed().into_iter().map(|placed| placed.shape).collect()
    }

    /// [`FallbackDrawing::paths`] with their regions and stages, as a scene holds them.
    pub fn placed(&self) -> Vec<Placed> {
        let background = Placed { shape: self.background.into(), region: None, origin: Origin::Background };
        let regions = self.order.iter().zip(&self.regions).filter_map(|(&region, shape)| {
            shape.clone().map(|shape| Placed { shape, region: Some(region), origin: Origin::Fallback })
        });
        std::iter::once(background).chain(regions).collect()
    }

    /// The scene of this drawing alone, of `target` split into `segmentation` (the image and
    /// the regions it was made of): nothing is painted again.
    pub fn into_scene(self, target: &Arc<Rgb32FImage>, segmentation: &Arc<Segmentation>) -> Scene {
        let placed = self.placed();
        Scene::drawn(target.clone(), segmentation.clone(), placed, self.canvas)
    }

    /// Its mean squared error per value (the error over pixels × 3 channels).
    pub fn mse(&self) -> f64 {
        let values = 3.0 * self.canvas.width() as f64 * self.canvas.height() as f64;
        self.error / values
    }
}

#[cfg(test)]
mod tests {
    use image::Rgb;
    use superpixel::{SlicOptions, slic};

    use super::*;

    fn wavy_image() -> Rgb32FImage {
        Rgb32FImage::from_fn(96, 64, |x, y| {
            let wave = ((x as f32 / 9.0).sin() + (y as f32 / 7.0).cos()) * 0.25 + 0.5;
            Rgb([wave, (x as f32 / 96.0), if (x / 24 + y / 16) % 2 == 0 { 0.8 } else { 0.2 }])
        })
    }

    #[test]
    fn away_from_boundaries_the_drawing_is_the_mosaic() {
        let image = Arc::new(wavy_image());
        let segmentation =
            Arc::new(slic(&image, &SlicOptions { n_segments: 40, ..Default::default() }).unwrap());
        let drawn = raster::render_exact(
            &FallbackDrawing::new(&image, &segmentation, Style::default()).paths(),
            96,
            64,
            [1.0; 3],
        );
        let drawn = image::DynamicImage::ImageRgb8(drawn).to_rgb32f();
        let mut checked = 0;
        for (x, y, ours) in drawn.enumerate_pixels() {
            let label = segmentation.label(x, y);
            let interior = (x.saturating_sub(1)..(x + 2).min(96))
                .all(|u| (y.saturating_sub(1)..(y + 2).min(64)).all(|v| segmentation.label(u, v) == label));
            if !interior {
                continue;
            }
            checked += 1;
            // The region's colour, to the rounding of an 8-bit canvas.
            let mean = segmentation.regions[label as usize].mean_color;
            for c in 0..3 {
                assert!(
                    (ours.0[c] - mean[c]).abs() <= 0.5 / 255.0 + 1e-6,
                    "({x}, {y}): {ours:?} vs {mean:?}"
                );
            }
        }
        assert!(checked > 96 * 64 / 2, "{checked} interior pixels");
    }

    #[test]
    fn the_regions_leave_no_seams() {
        // Every region black over a white canvas: wherever two regions' anti-aliased edges
        // failed to cover a pixel together, white would show through (39/255 at worst here
        // when regions stop at their cut edges instead of growing under later ones). What may
        // remain: a cut corner of a grown region inside a pixel the later one's cut also
        // clips, an eighth of each: 1/64 ≈ 4/255. Shared curves, at any tolerance, leave none:
        // the earlier region passes under the later one whole.
        let image = wavy_image();
        let mut segmentation = slic(&image, &SlicOptions { n_segments: 60, ..Default::default() }).unwrap();
        for region in &mut segmentation.regions {
            region.mean_color = [0.0; 3];
        }
        for (tolerance, most) in [(None, 4), (Some(0.0), 0), (Some(TOLERANCE), 0), (Some(2.0), 0)] {
            let regions: Vec<Outline> = traced(&segmentation, &painter_order(&segmentation), tolerance)
                .into_iter()
                .flatten()
                .collect();
            assert_eq!(regions.len(), segmentation.regions.len());
            let drawn = raster::render_exact(&regions, 96, 64, [1.0; 3]);
            let brightest = drawn.pixels().map(|p| p.0[0]).max().unwrap();
            assert!(brightest <= most, "{tolerance:?}: a seam lets the canvas show through: {brightest}/255");
        }
    }

    #[test]
    fn a_later_region_draws_its_boundary_with_the_shared_curve() {
        let image = wavy_image();
        let segmentation = slic(&image, &SlicOptions { n_segments: 40, ..Default::default() }).unwrap();
        let order = painter_order(&segmentation);
        let mut rank = vec![0; order.len()];
        for (place, &r) in order.iter().enumerate() {
            rank[r as usize] = place;
        }
        let boundaries = Boundaries::new(&segmentation, TOLERANCE);
        let mut shared = 0;
        for region in 0..segmentation.regions.len() as u32 {
            let outline = region_outline(&segmentation, &boundaries, region, &rank).unwrap();
            let pieces: Vec<Segment> = outline.contours().iter().flat_map(|c| c.segments.clone()).collect();
            for &id in boundaries.map.chains_of(region) {
                let chain = &boundaries.map.chains()[id as usize];
                let other = if chain.right == region { chain.left } else { Some(chain.right) };
                // Against an earlier neighbour or the image's edge, this region draws the line.
                if other.is_some_and(|o| rank[o as usize] > rank[region as usize]) {
                    continue;
                }
                let (start, segments) = &boundaries.curves[id as usize];
                let starts = std::iter::once(*start).chain(segments.iter().map(Segment::end));
                for (segment, from) in segments.iter().zip(starts) {
                    let found = pieces.contains(segment) || pieces.contains(&segment.reversed(from));
                    assert!(found, "region {region}, chain {id}: {segment:?} is not in its outline");
                    shared += 1;
                }
            }
        }
        assert!(shared > 100, "{shared} pieces checked");
        // The curves are fitted: fewer pieces than the traced points.
        let traced: usize = boundaries.map.chains().iter().map(|c| c.points.len()).sum();
        let fitted: usize = boundaries.curves.iter().map(|c| c.1.len()).sum();
        assert!(fitted * 2 < traced, "{fitted} pieces for {traced} traced points");
    }

    #[test]
    fn a_flat_picture_is_its_background_alone_and_the_canvas_is_its_rendering() {
        let flat = Arc::new(Rgb32FImage::from_pixel(48, 32, Rgb([0.2, 0.6, 0.4])));
        let segmentation =
            Arc::new(slic(&flat, &SlicOptions { n_segments: 12, ..Default::default() }).unwrap());
        let drawing = FallbackDrawing::new(&flat, &segmentation, Style::default());
        assert!(drawing.regions.iter().all(Option::is_none), "a region drew nothing yet was kept");
        assert_eq!(drawing.paths().len(), 1);
        assert!(drawing.error < 1e-3, "{}", drawing.error);
        let image = Arc::new(wavy_image());
        let segmentation =
            Arc::new(slic(&image, &SlicOptions { n_segments: 40, ..Default::default() }).unwrap());
        let drawing = FallbackDrawing::new(&image, &segmentation, Style::default());
        assert!(drawing.regions.iter().filter(|r| r.is_some()).count() > 30, "regions that draw are kept");
        let rendered = raster::render_exact(&drawing.paths(), 96, 64, [1.0; 3]);
        let scene = Scene::drawn(image, segmentation, drawing.placed(), drawing.canvas.clone());
        assert_eq!(scene.canvas_rgb8(), rendered);
    }

    #[test]
    fn a_fitted_path_covers_its_polygon() {
        // A 10 × 10 pixel square at (5, 5) on a 20 × 20 canvas.
        let corners = vec![[0.25, 0.25], [0.75, 0.25], [0.75, 0.75], [0.25, 0.75]];
        let polygon = Outline::polygon(&corners, [0.2, 0.4, 0.6], 1.0).unwrap();
        let path = fitted_path(&polygon, (20, 20)).unwrap();
        assert_eq!((path.color, path.alpha), (polygon.color(), polygon.alpha));
        // The square's area (1/4 of the canvas) grown by half a pixel on each side.
        let grown = (11.0f32 / 20.0).powi(2);
        assert!((path.signed_area().abs() - grown).abs() < 0.02, "{}", path.signed_area());
    }

    /// A green dot in the corner (the first region read), the blue ground around a red square:
    /// the ground, whose box holds the square's, is painted first, the dot last, whatever
    /// their labels.
    #[test]
    fn enclosing_regions_are_painted_first() {
        let image = Rgb32FImage::from_fn(30, 30, |x, y| match (x, y) {
            (0, 0) => Rgb([0.0, 1.0, 0.0]),
            (10..20, 10..20) => Rgb([1.0, 0.0, 0.0]),
            _ => Rgb([0.0, 0.0, 1.0]),
        });
        let segmentation = Segmentation::flat_areas(&image, 10).expect("three flat areas");
        let colour = |r: u32| segmentation.regions[r as usize].mean_color.map(|c| c.round() as u8);
        let order: Vec<[u8; 3]> = painter_order(&segmentation).into_iter().map(colour).collect();
        assert_eq!(order, [[0, 0, 1], [1, 0, 0], [0, 1, 0]]);
    }
}
