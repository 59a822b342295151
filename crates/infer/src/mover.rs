//! The mover's stage (E_m), after SuperSVG-B's: every point of every drawn outline moved along
//! its normal in one batched pass ([`model::Mover`]), the moved points rounded to a grid of
//! about [`MOVE_GRID`] of a working pixel and each moved outline's straight runs simplified within
//! [`SIMPLIFY_PIXELS`], so that the edges it finds do not cost more bytes than they draw. The
//! background stays under everything, as drawn. Then every fill is refitted by least squares
//! to what its shape shows once moved (`recolour`): a region's mean colour is no longer the
//! best colour of an outline that covers other pixels. The pass is kept only where the whole
//! drawing is better for it.

use burn::tensor::Device;
use model::{Frame, Mover, PROFILE_LEN, frames, profile};
use rayon::prelude::*;
use serde::Serialize;
use web_time::Instant;

use raster::{Outline, Shape};

use crate::recolour::refitted;
use crate::scene::{Origin, Scene};

/// Moved points are rounded to the power of ten of output pixels nearest (in ratio) to this
/// fraction of a working pixel: a tenth of a pixel where the SVG is at the working size, whole
/// pixels where it is 1.6 times larger or more. A moved point costs the SVG one decimal at most.
pub const MOVE_GRID: f32 = 0.2;
/// Moved outlines' straight runs are simplified within this many working pixels.
pub const SIMPLIFY_PIXELS: f32 = 0.4;

/// What the mover did to one drawing: the schema of `infer --metrics`' `moves`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct MoveTally {
    /// Points it read and moved.
    pub points: usize,
    /// Whether the moved drawing was kept (it drew better than B's).
    pub kept: bool,
    /// The drawing's PSNR gain over B's, dB (zero when not kept).
    pub gain_db: f64,
    /// Seconds of the network's forward pass, profiles read included.
    pub network_seconds: f64,
}

/// Moves every outline of `scene` but the background with `mover` on `device`, the SVG being
/// written at `original` size, and refits every fill to the moved drawing: kept when the
/// drawing's error falls, else `scene` stays as it was.
pub fn move_outlines(mover: &Mover, scene: &mut Scene, original: (u32, u32), device: &Device) -> MoveTally {
    let target = scene.target().clone();
    let size = target.dimensions();
    let canvas = scene.canvas_image();
    let outlines: Vec<Option<Outline>> = (scene.paths().iter())
        .map(|placed| (placed.origin != Origin::Background).then(|| placed.shape.to_outline()).flatten())
        .collect();
    let clock = Instant::now();
    let frames: Vec<Vec<Frame>> = outlines
        .par_iter()
        .map(|outline| outline.as_ref().map_or_else(Vec::new, |o| frames(o, size)))
        .collect();
    let every: Vec<&Frame> = frames.iter().flatten().collect();
    let mut profiles = vec![0.0; every.len() * PROFILE_LEN];
    (profiles.par_chunks_mut(PROFILE_LEN).zip(&every))
        .for_each(|(values, frame)| values.copy_from_slice(&profile(&target, &canvas, frame)));
    let moves = mover.moves(profiles, device);
    let network_seconds = clock.elapsed().as_secs_f64();
    let points = moves.len();
    let step = 10f32.powf((MOVE_GRID * original.0 as f32 / size.0 as f32).log10().round());
    let grid = |value: f32, scale: u32| (value * scale as f32 / step).round() * step / scale as f32;
    let mut at = 0;
    let shapes: Vec<Shape> = (scene.paths().iter().zip(&outlines).zip(&frames))
        .map(|((placed, outline), frames)| {
            let Some(outline) = outline else { return placed.shape.clone() };
            let moved: Vec<[f32; 2]> =
                (frames.iter().zip(&moves[at..at + frames.len()]).zip(outline.points()))
                    .map(|((frame, &distance), point)| match distance == 0.0 || frame.normal == [0.0; 2] {
                        true => point,
                        false => {
                            let [x, y] = frame.moved(distance, size);
                            [grid(x, original.0), grid(y, original.1)]
                        }
                    })
                    .collect();
            at += frames.len();
            Shape::from(outline.with_points(&moved).simplified(SIMPLIFY_PIXELS, size))
        })
        .collect();
    let shapes = refitted(&target, &shapes);
    // The drawing as B left it, canvas and all, to go back to without painting it again.
    let (drawn, error) = (scene.clone(), scene.total_error());
    scene.set_shapes(&shapes);
    let after = scene.total_error();
    if after < error {
        MoveTally { points, kept: true, gain_db: 10.0 * (error / after).log10(), network_seconds }
    } else {
        *scene = drawn;
        MoveTally { points, kept: false, gain_db: 0.0, network_seconds }
    }
}
