//! What a shape is filled with: one colour, or a linear ramp between two colours (SVG's
//! `linearGradient` with two stops, padded beyond its ends), which draws a smooth shading in one
//! shape where one colour would need many shapes to band it.

use common::Ramp;

use crate::decimals::Decimals;
use tiny_skia::{Color, GradientStop, LinearGradient, Point, Shader, SpreadMode, Transform};

/// Parameters of a [`Ramp`] as fine-tuning moves it: `start`, `end` (unit square), then the two
/// stops' RGB.
pub const RAMP_PARAMS: usize = 10;
/// The first [`RAMP_PARAMS`] that are coordinates (`start`, `end`); the rest are colours.
pub const RAMP_COORDS: usize = 4;

/// `ramp` in the [`RAMP_PARAMS`] layout.
pub fn ramp_params(ramp: &Ramp) -> [f32; RAMP_PARAMS] {
    let [[x0, y0], [x1, y1]] = [ramp.start, ramp.end];
    let [[r0, g0, b0], [r1, g1, b1]] = ramp.stops;
    [x0, y0, x1, y1, r0, g0, b0, r1, g1, b1]
}

/// The ramp of [`ramp_params`]' layout.
pub fn ramp_from_params(p: &[f32; RAMP_PARAMS]) -> Ramp {
    Ramp { start: [p[0], p[1]], end: [p[2], p[3]], stops: [[p[4], p[5], p[6]], [p[7], p[8], p[9]]] }
}

/// A shape's paint, in the frame of its outline (the unit square of a canvas). A ramp's end
/// points are in that square too, and its lines of one colour are perpendicular to it on the
/// canvas, in pixels, as SVG draws a gradient in user space: the square is stretched to the
/// canvas first.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Fill {
    /// One colour, RGB in [0, 1].
    Solid([f32; 3]),
    /// A colour ramp.
    Linear(Ramp),
}

impl Fill {
    /// The one colour that stands for the fill: its colour, or the ramp's middle.
    pub fn color(&self) -> [f32; 3] {
        match self {
            Fill::Solid(color) => *color,
            Fill::Linear(ramp) => ramp.middle(),
        }
    }

    /// The fill as an SVG of a canvas of `size` = (width, height) pixels writes it with
    /// `decimals` ([`crate::to_svg_with`]): colours in 8 bits, a ramp's ends rounded. A ramp
    /// whose ends round to one point, which SVG would paint in its last stop alone, is written
    /// flat, in its middle colour.
    pub fn as_written(&self, [sx, sy]: [f32; 2], decimals: Decimals) -> Fill {
        match self {
            Fill::Solid(color) => Fill::Solid(color.map(in_8_bits)),
            Fill::Linear(ramp) => {
                let ticks = |[x, y]: [f32; 2]| [decimals.ticks(x * sx), decimals.ticks(y * sy)];
                if ticks(ramp.start) == ticks(ramp.end) {
                    return Fill::Solid(ramp.middle().map(in_8_bits));
                }
                let point = |[x, y]: [f32; 2]| [decimals.rounded(x * sx) / sx, decimals.rounded(y * sy) / sy];
                Fill::Linear(Ramp {
                    start: point(ramp.start),
                    end: point(ramp.end),
                    stops: ramp.stops.map(|stop| stop.map(in_8_bits)),
                })
            }
        }
    }

    /// Whether every number is finite.
    pub fn is_finite(&self) -> bool {
        match self {
            Fill::Solid(color) => color.iter().all(|v| v.is_finite()),
            Fill::Linear(ramp) => ramp.is_finite(),
        }
    }

    /// The tiny-skia paint of the fill at opacity `alpha` (colours and α clamped to [0, 1]) for
    /// a path in the unit square of a `canvas` = (width, height), drawn with the canvas's scale
    /// (which tiny-skia applies to the paint too); `None` for a number that is not finite. A
    /// ramp whose ends coincide paints its last stop, as SVG's renderers do.
    pub(crate) fn shader(&self, alpha: f32, (width, height): (u32, u32)) -> Option<Shader<'static>> {
        let color = |[r, g, b]: [f32; 3]| {
            Color::from_rgba(r.clamp(0.0, 1.0), g.clamp(0.0, 1.0), b.clamp(0.0, 1.0), alpha.clamp(0.0, 1.0))
        };
        match self {
            Fill::Solid(rgb) => Some(Shader::SolidColor(color(*rgb)?)),
            Fill::Linear(ramp) => {
                let stops = vec![
                    GradientStop::new(0.0, color(ramp.stops[0])?),
                    GradientStop::new(1.0, color(ramp.stops[1])?),
                ];
                // Laid out in pixels and scaled back to the square, so that the canvas's scale
                // brings it to pixels unskewed.
                let (width, height) = (width as f32, height as f32);
                let point = |[x, y]: [f32; 2]| Point::from_xy(x * width, y * height);
                let to_square = Transform::from_scale(1.0 / width, 1.0 / height);
                let shader = LinearGradient::new(
                    point(ramp.start),
                    point(ramp.end),
                    stops,
                    SpreadMode::Pad,
                    to_square,
                );
                shader.or_else(|| Some(Shader::SolidColor(color(ramp.stops[1])?)))
            }
        }
    }
}

/// A colour channel in [0, 1] as `#rrggbb` writes it: clamped, in 255ths.
pub(crate) fn in_8_bits(channel: f32) -> f32 {
    f32::from(to_8_bits(channel)) / 255.0
}

/// A colour channel in [0, 1] as one byte of `#rrggbb` (clamped, rounded).
pub(crate) fn to_8_bits(channel: f32) -> u8 {
    (channel.clamp(0.0, 1.0) * 255.0).round() as u8
}

impl From<[f32; 3]> for Fill {
    fn from(color: [f32; 3]) -> Self {
        Fill::Solid(color)
    }
}

impl From<Ramp> for Fill {
    fn from(ramp: Ramp) -> Self {
        Fill::Linear(ramp)
    }
}
