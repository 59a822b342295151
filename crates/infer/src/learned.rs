//! The learned optimizer's steps (E_o) in SuperSVG-F: every point of every outline but the
//! background moved along its normal by [`model::LearnedOptimizer`], from its profile and its
//! optimization state, then every fill refitted in closed form to the moved drawing. What a
//! step reads ([`LearnedSteps::features`]) and what it does ([`LearnedSteps::apply`]) are apart
//! so that training reads and does the same.

use burn::tensor::Device;
use image::{Rgb, Rgb32FImage};
use model::{Frame, LearnedOptimizer, PROFILE_LEN, STATE_LEN, STEP_FEATURES, frames, neighbours, profile};
use raster::{Outline, Shape, Window};
use rayon::prelude::*;

use crate::recolour::refitted;

/// β₁ and β₂ of the running mean and square of a point's gradient (short: E_o takes few steps).
const BETAS: (f32, f32) = (0.5, 0.9);

/// What one learned step reads: every movable point's frame and features, and the drawing's
/// error and gradient it read them at.
pub struct StepInput {
    /// Each outline's frames (empty for one that does not move: the background).
    pub frames: Vec<Vec<Frame>>,
    /// [`STEP_FEATURES`] values a point, the points in `frames`' order.
    pub features: Vec<f32>,
    /// The drawing's error (the window's mean squared error) before the step.
    pub loss: f64,
    /// The error's gradient by each point's move along its normal (per pixel moved).
    pub along: Vec<f32>,
    /// The error's gradient by each point, per pixel (`frames`' order).
    pub gradient: Vec<[f32; 2]>,
}

/// The optimization state E_o reads, point by point, across its steps: the running moments of
/// each point's gradient along its normal and its last move.
pub struct LearnedSteps {
    /// Whether each outline moves (all but the background).
    movable: Vec<bool>,
    /// Per point: running mean of the normalized gradient, running square, last move (px).
    state: Vec<[f32; 3]>,
    /// Steps taken, and planned.
    taken: usize,
    planned: usize,
    /// Whether every fill is refitted after each step.
    pub refit: bool,
}

impl LearnedSteps {
    /// The state of `planned` steps over outlines of which `movable` say which move.
    pub fn new(movable: Vec<bool>, planned: usize) -> Self {
        Self { movable, state: Vec::new(), taken: 0, planned: planned.max(1), refit: true }
    }

    /// What the next step reads of `outlines` against `window` (whose target is `target`): the
    /// render, the error's gradient, each point's profile and state. Advances the running
    /// moments.
    pub fn features(&mut self, outlines: &[Outline], window: &Window, target: &Rgb32FImage) -> StepInput {
        let size = target.dimensions();
        let canvas = interleaved(&window.render_outlines(outlines), size);
        let (loss, frames, gradient) = self.gradient(outlines, window, size);
        let along = along_normals(&frames, &gradient);
        if self.state.len() != along.len() {
            self.state = vec![[0.0; 3]; along.len()];
        }
        // Adam's normalization, with bias correction, over this run's steps.
        let (b1, b2) = BETAS;
        let step = (self.taken + 1) as i32;
        let (c1, c2) = (1.0 - b1.powi(step), 1.0 - b2.powi(step));
        let mut normalized = vec![0.0f32; along.len()];
        for ((state, &g), value) in self.state.iter_mut().zip(&along).zip(&mut normalized) {
            state[1] = b2 * state[1] + (1.0 - b2) * g * g;
            let scale = (state[1] / c2).sqrt();
            *value = if scale > 0.0 && g.is_finite() { g / scale } else { 0.0 };
            state[0] = b1 * state[0] + (1.0 - b1) * *value;
        }
        let fraction = self.taken as f32 / self.planned as f32;
        let mut around = Vec::with_capacity(along.len());
        let mut at = 0;
        for (outline, frames) in outlines.iter().zip(&frames) {
            if !frames.is_empty() {
                around.extend(neighbours(outline).into_iter().map(|(p, n)| (at + p, at + n)));
            }
            at += frames.len();
        }
        let every: Vec<&Frame> = frames.iter().flatten().collect();
        let mut features = vec![0.0; every.len() * STEP_FEATURES];
        (features.par_chunks_mut(STEP_FEATURES).enumerate()).for_each(|(i, row)| {
            row[..PROFILE_LEN].copy_from_slice(&profile(target, &canvas, every[i]));
            let (prev, next) = around[i];
            let state: [f32; STATE_LEN] = [
                normalized[i],
                self.state[i][0] / c1,
                self.state[i][2],
                fraction,
                normalized[prev],
                normalized[next],
                self.state[prev][2],
                self.state[next][2],
            ];
            row[PROFILE_LEN..].copy_from_slice(&state);
        });
        self.taken += 1;
        StepInput { frames, features, loss, along, gradient }
    }

    /// The error of `outlines` against `window` (a canvas of `size`), each movable point's frame
    /// and the error's gradient by each movable point, in pixels.
    pub fn gradient(
        &self,
        outlines: &[Outline],
        window: &Window,
        (width, height): (u32, u32),
    ) -> (f64, Vec<Vec<Frame>>, Vec<[f32; 2]>) {
        let (loss, gradients) = window.l2_gradient_outlines(outlines);
        let frames: Vec<Vec<Frame>> = (outlines.par_iter().zip(&self.movable))
            .map(|(outline, &movable)| if movable { frames(outline, (width, height)) } else { Vec::new() })
            .collect();
        let (w, h) = (width as f32, height as f32);
        let per_pixel = (frames.iter().zip(&gradients))
            .flat_map(|(frames, gradient)| {
                gradient.points[..frames.len()].iter().map(|g| [g[0] / w, g[1] / h])
            })
            .collect();
        (loss, frames, per_pixel)
    }

    /// `outlines` with every point moved along its normal by its move in `moves` (pixels, the
    /// points in `input.frames`' order) and every fill refitted to `target` over the moved
    /// drawing; remembers the moves. Outlines no move touches come back as they were, and
    /// nothing is refitted when nothing moved.
    pub fn apply(
        &mut self,
        outlines: &[Outline],
        input: &StepInput,
        moves: &[f32],
        target: &Rgb32FImage,
    ) -> Vec<Outline> {
        let size = target.dimensions();
        for (state, &moved) in self.state.iter_mut().zip(moves) {
            state[2] = moved;
        }
        if moves.iter().all(|&moved| moved == 0.0) {
            return outlines.to_vec();
        }
        let mut at = 0;
        let shapes: Vec<Shape> = (outlines.iter().zip(&input.frames))
            .map(|(outline, frames)| {
                let moves = &moves[at..at + frames.len()];
                at += frames.len();
                if frames.is_empty() {
                    return Shape::from(outline.clone());
                }
                let points: Vec<[f32; 2]> = (frames.iter().zip(moves).zip(outline.points()))
                    .map(|((frame, &distance), point)| match distance == 0.0 || frame.normal == [0.0; 2] {
                        true => point,
                        false => frame.moved(distance, size),
                    })
                    .collect();
                Shape::from(outline.with_points(&points))
            })
            .collect();
        let shapes = if self.refit { refitted(target, &shapes) } else { shapes };
        shapes.iter().map(|shape| shape.to_outline().expect("a moved outline is finite")).collect()
    }

    /// One whole step with `optimizer` on `device`: its features, its moves, the moved and
    /// refitted outlines, and the error before the step.
    pub fn step(
        &mut self,
        optimizer: &LearnedOptimizer,
        outlines: &[Outline],
        window: &Window,
        target: &Rgb32FImage,
        device: &Device,
    ) -> (Vec<Outline>, f64) {
        let input = self.features(outlines, window, target);
        let moves = optimizer.moves(input.features.clone(), device);
        (self.apply(outlines, &input, &moves, target), input.loss)
    }
}

/// Each point's gradient (per pixel) along its normal: per pixel moved along it.
pub fn along_normals(frames: &[Vec<Frame>], gradient: &[[f32; 2]]) -> Vec<f32> {
    (frames.iter().flatten().zip(gradient))
        .map(|(frame, g)| g[0] * frame.normal[0] + g[1] * frame.normal[1])
        .collect()
}

/// A planar RGB buffer (`[3][height][width]`, what a window renders) as an image.
fn interleaved(planar: &[f32], (width, height): (u32, u32)) -> Rgb32FImage {
    let plane = (width * height) as usize;
    Rgb32FImage::from_fn(width, height, |x, y| {
        let i = (y * width + x) as usize;
        Rgb([planar[i], planar[plane + i], planar[2 * plane + i]])
    })
}
