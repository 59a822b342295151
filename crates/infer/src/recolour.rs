//! Every shape's fill refitted to the image over what it shows once drawn: least squares over
//! its exact coverage times what the shapes above it leave visible, each shape against the
//! drawing as it is (all at once: shapes that tile meet only along their edges). A flat colour
//! is refitted; a ramp is shifted, both stops by the same amount, its slope kept (fitting its
//! two stops apart drew worse on some photos: models/README.md). The colours B picks are its
//! regions' means over their pixels; a traced or moved outline covers other pixels than its
//! region's, and its neighbours cover some of it, so the colour that draws it best is another:
//! the mover's stage refits the fills of what it moved. The refitted drawing writes the same
//! bytes.

use common::PixelBox;
use image::Rgb32FImage;
use rayon::prelude::*;

use raster::{Fill, Filled, Shape, coverage_exact_window};

/// `shapes` (in paint order, over white) with every fill refitted to `target` (see the
/// module); their geometry and opacity as they were.
pub(crate) fn refitted(target: &Rgb32FImage, shapes: &[Shape]) -> Vec<Shape> {
    let (width, height) = target.dimensions();
    // Each shape's box and its coverage there, opacity included.
    let covers: Vec<Option<(PixelBox, Vec<f32>)>> = shapes
        .par_iter()
        .map(|shape| {
            let bbox = shape.pixel_box(width, height)?;
            let size = (bbox.width(), bbox.height());
            let mask = coverage_exact_window(shape, (width, height), (bbox.x0(), bbox.y0()), size)?;
            let alpha = shape.alpha().clamp(0.0, 1.0);
            Some((bbox, mask.data().iter().map(|&m| alpha * f32::from(m) / 255.0).collect()))
        })
        .collect();
    // What each shape shows: its coverage times what the shapes above leave through.
    let mut through = vec![1.0f32; (width * height) as usize];
    let mut shown: Vec<Vec<f32>> = vec![Vec::new(); shapes.len()];
    for (cover, shown) in covers.iter().zip(&mut shown).rev() {
        let Some((bbox, cover)) = cover else { continue };
        *shown = (bbox.rows().flat_map(|y| bbox.columns().map(move |x| (y * width + x) as usize)))
            .zip(cover)
            .map(|(index, &a)| {
                let seen = a * through[index];
                through[index] *= 1.0 - a;
                seen
            })
            .collect();
    }
    // The drawing over white, as these weights compose it.
    let mut drawn: Vec<[f32; 3]> = through.iter().map(|&t| [t; 3]).collect();
    let cells = |bbox, shown| cells(bbox, shown, (width, height));
    for ((cover, shown), shape) in covers.iter().zip(&shown).zip(shapes) {
        if let Some((bbox, _)) = cover {
            let fill = shape.fill();
            for (index, point, w) in cells(bbox, shown) {
                let colour = colour_at(&fill, point);
                (0..3).for_each(|c| drawn[index][c] += w * colour[c]);
            }
        }
    }
    // Each fill shifted by the least-squares amount against the drawing as it is (the shapes
    // apart: they meet only along their edges).
    let fills: Vec<Fill> = (covers.par_iter().zip(&shown).zip(shapes))
        .map(|((cover, shown), shape)| {
            let fill = shape.fill();
            let Some((bbox, _)) = cover else { return fill };
            let (mut weight, mut moments) = (0.0f64, [0.0f64; 3]);
            for (index, _, w) in cells(bbox, shown) {
                let (image, drawn) = (&target.as_raw()[3 * index..3 * index + 3], drawn[index]);
                weight += f64::from(w * w);
                (0..3).for_each(|c| moments[c] += f64::from(w * (image[c] - drawn[c])));
            }
            if weight == 0.0 {
                return fill;
            }
            let shift = |colour: [f32; 3]| -> [f32; 3] {
                std::array::from_fn(|c| (colour[c] + (moments[c] / weight) as f32).clamp(0.0, 1.0))
            };
            match fill {
                Fill::Solid(colour) => Fill::Solid(shift(colour)),
                Fill::Linear(mut ramp) => {
                    ramp.stops = ramp.stops.map(shift);
                    Fill::Linear(ramp)
                }
            }
        })
        .collect();
    (shapes.iter().zip(fills))
        .map(|(shape, fill)| shape.with_fill(fill).unwrap_or_else(|| shape.clone()))
        .collect()
}

/// The pixels of `bbox` on a `width` × `height` canvas with their weights `shown` (row by
/// row): each one's index, its centre in the unit square and its weight.
fn cells<'a>(
    bbox: &'a PixelBox,
    shown: &'a [f32],
    (width, height): (u32, u32),
) -> impl Iterator<Item = (usize, [f32; 2], f32)> + 'a {
    let unit = move |x: u32, y: u32| [(x as f32 + 0.5) / width as f32, (y as f32 + 0.5) / height as f32];
    (bbox.rows().flat_map(|y| bbox.columns().map(move |x| (x, y))))
        .zip(shown)
        .map(move |((x, y), &w)| ((y * width + x) as usize, unit(x, y), w))
}

/// The colour `fill` paints at `point` (unit square).
fn colour_at(fill: &Fill, point: [f32; 2]) -> [f32; 3] {
    match fill {
        Fill::Solid(colour) => *colour,
        Fill::Linear(ramp) => ramp.color_at(point),
    }
}

#[cfg(test)]
mod tests {
    use image::Rgb;
    use raster::{Outline, Path, Ramp};

    use super::*;

    const SIZE: u32 = 64;

    fn square(lo: f32, hi: f32, fill: impl Into<Fill>) -> Shape {
        let (a, b) = (lo / SIZE as f32, hi / SIZE as f32);
        Outline::polygon(&[[a, a], [b, a], [b, b], [a, b]], fill, 1.0).unwrap().into()
    }

    fn white() -> Shape {
        Path::quadrilateral([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]], [1.0; 3], 1.0).into()
    }

    /// A square in a wrong colour, a quarter hidden by a red one over a red patch of the image: its
    /// colour is refitted to what it shows, the blue of the image, not mixed with the red the
    /// shape above hides.
    #[test]
    fn a_fill_is_refitted_over_what_it_shows() {
        let (blue, red) = ([0.2, 0.4, 0.6], [0.9, 0.1, 0.1]);
        let target = Rgb32FImage::from_fn(SIZE, SIZE, |x, y| {
            let inside = |v: u32| (16..48).contains(&v);
            match (inside(x) && inside(y), x >= 32 && y >= 32) {
                (true, true) => Rgb(red),
                (true, false) => Rgb(blue),
                _ => Rgb([1.0; 3]),
            }
        });
        let shapes = [white(), square(16.0, 48.0, [0.5; 3]), square(32.0, 48.0, red)];
        let fitted = refitted(&target, &shapes);
        let colour = fitted[1].color();
        assert!((0..3).all(|c| (colour[c] - blue[c]).abs() < 1e-3), "{colour:?}");
        assert!((0..3).all(|c| (fitted[2].color()[c] - red[c]).abs() < 1e-3), "{:?}", fitted[2].color());
    }

    /// A ramp drawn too dark by 0.1 is shifted back: both stops by the same amount, its ends
    /// where they were.
    #[test]
    fn a_ramp_is_shifted_by_least_squares() {
        let ramp = |shift: f32| Ramp {
            start: [0.25, 0.5],
            end: [0.75, 0.5],
            stops: [[0.2 + shift, 0.3 + shift, 0.4 + shift], [0.6 + shift, 0.5 + shift, 0.3 + shift]],
        };
        let target = Rgb32FImage::from_fn(SIZE, SIZE, |x, y| {
            let point = [(x as f32 + 0.5) / SIZE as f32, (y as f32 + 0.5) / SIZE as f32];
            Rgb(ramp(0.0).color_at(point))
        });
        let fitted = refitted(&target, &[square(0.0, 64.0, Fill::Linear(ramp(-0.1)))]);
        let Fill::Linear(got) = fitted[0].fill() else { panic!("still a ramp: {:?}", fitted[0].fill()) };
        assert_eq!((got.start, got.end), (ramp(0.0).start, ramp(0.0).end));
        for (got, want) in got.stops.iter().flatten().zip(ramp(0.0).stops.iter().flatten()) {
            assert!((got - want).abs() < 1e-3, "{:?} against {:?}", got, ramp(0.0).stops);
        }
    }
}
