//! SuperSVG-F: optimizing every path of a result jointly against the image.
//!
//! All paths at once, as the reference does (Adam on plain L2 over the whole image), on the
//! exact rendering and its gradient from [`raster::Window`]: a step costs the pixels of each
//! path's own box (bands of rows in parallel), not paths × pixels. Coordinates stay in the
//! canvas and colours and opacity in [0, 1]; the best state seen is kept.

use std::ops::ControlFlow;
use web_time::Instant;

use common::psnr_of_mse;
use raster::{
    Fill, Filled, Outline, PARAMS, Path, PathAdam, RAMP_PARAMS, Ramp, RampAdam, Shape, Window,
    ramp_from_params, ramp_params,
};

use crate::fallback::fitted_path;
use crate::scene::Scene;

/// When fine-tuning stops.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Limit {
    /// This many optimizer steps (each moves every path).
    Steps(usize),
    /// Steps until this many seconds have passed.
    Seconds(f64),
}

/// Settings of the fine-tuning.
#[derive(Clone, Debug)]
pub struct FinetuneOptions {
    /// When to stop.
    pub limit: Limit,
    /// Adam learning rate of the control points (in the unit square of the image).
    pub lr_points: f32,
    /// Adam learning rate of colours and opacity.
    pub lr_colors: f32,
}

/// What the scene is painted over (as [`Scene`] scores it).
const WHITE: [f32; 3] = [1.0; 3];

impl Default for FinetuneOptions {
    /// 100 steps; points at 1e-3 (about half a pixel a step at 512 px, the reference's rate)
    /// and colours at 3e-2, the best of the sweep in docs/method.md.
    fn default() -> Self {
        Self { limit: Limit::Steps(100), lr_points: 1e-3, lr_colors: 3e-2 }
    }
}

/// How far fine-tuning has come, reported after every step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Progress {
    /// Seconds since fine-tuning started.
    pub seconds: f64,
    /// Optimizer steps taken.
    pub steps: usize,
    /// Steps the limit allows in all (`None` for a limit in seconds).
    pub total_steps: Option<usize>,
    /// PSNR (dB) of the exact drawing of the best state so far.
    pub psnr: f64,
}

/// Fine-tunes every path of `scene` against its image. Outlines (the fallback's regions)
/// start as their outlines fitted with one path ([`fitted_path`]), which only approximates
/// them: if the best state found is worse than the scene was, the scene keeps its old shapes,
/// as it does when no step is taken. Returns the number of optimizer steps taken (0 when a
/// polygon cannot be fitted).
pub fn finetune(scene: &mut Scene, options: &FinetuneOptions) -> usize {
    finetune_with_progress(scene, options, &mut |_| ControlFlow::Continue(()))
}

/// [`finetune`], calling `on_step` after every step (for a progress bar); when it breaks,
/// fine-tuning stops there, keeping the best state seen so far.
pub fn finetune_with_progress(
    scene: &mut Scene,
    options: &FinetuneOptions,
    on_step: &mut dyn FnMut(&Progress) -> ControlFlow<()>,
) -> usize {
    let started = Instant::now();
    let image = scene.target();
    let (width, height) = image.dimensions();
    let target: Vec<f32> = (0..3).flat_map(|c| image.pixels().map(move |p| p.0[c])).collect();
    let canvas: Vec<f32> = WHITE.iter().flat_map(|&v| std::iter::repeat_n(v, target.len() / 3)).collect();
    let Some(window) = Window::new(width, height, canvas, target) else { return 0 };
    let original = scene.scene();
    let as_path = |shape: &Shape| match shape {
        Shape::Path(path) => Some(*path),
        Shape::Outline(outline) => fitted_path(outline, (width, height)),
    };
    let Some(start) = original.iter().map(as_path).collect::<Option<Vec<Path>>>() else { return 0 };
    // Ramps move with their outlines; a flat path's slot stays empty and still.
    let start_ramps: Vec<Option<Ramp>> = original
        .iter()
        .map(|shape| match shape.fill() {
            Fill::Linear(ramp) => Some(ramp),
            Fill::Solid(_) => None,
        })
        .collect();
    let mut params: Vec<[f32; PARAMS]> = start.iter().map(|path| path.to_params()).collect();
    let mut ramp_values: Vec<[f32; RAMP_PARAMS]> =
        start_ramps.iter().map(|ramp| ramp.as_ref().map_or([0.0; RAMP_PARAMS], ramp_params)).collect();
    let mut adam = PathAdam::new(params.len());
    let ramped: Vec<bool> = start_ramps.iter().map(Option::is_some).collect();
    let any_ramp = ramped.contains(&true);
    let mut ramp_adam = RampAdam::new(ramp_values.len());
    let mut best = (f64::INFINITY, start, start_ramps);
    let total_steps = match options.limit {
        Limit::Steps(steps) => Some(steps),
        Limit::Seconds(_) => None,
    };
    let mut steps = 0;
    let mut stopped = false;
    loop {
        let done = stopped
            || match options.limit {
                Limit::Steps(total) => steps >= total,
                Limit::Seconds(limit) => started.elapsed().as_secs_f64() >= limit,
            };
        let paths: Vec<Path> = params.iter().map(Path::from_params).collect();
        let ramps: Vec<Option<Ramp>> = ramp_values
            .iter()
            .zip(&ramped)
            .map(|(values, &ramped)| ramped.then(|| ramp_from_params(values)))
            .collect();
        if done {
            if window.l2_ramped(&paths, &ramps) < best.0 {
                (best.1, best.2) = (paths, ramps);
            }
            break;
        }
        let (loss, gradients, ramp_gradients) = window.l2_gradient_ramped(&paths, &ramps);
        if loss < best.0 {
            best = (loss, paths, ramps);
        }
        let rates = (options.lr_points, options.lr_colors);
        adam.step(rates, &mut params, &gradients);
        if any_ramp {
            ramp_adam.step(rates, &mut ramp_values, &ramp_gradients);
        }
        steps += 1;
        let progress = Progress {
            seconds: started.elapsed().as_secs_f64(),
            steps,
            total_steps,
            psnr: psnr_of_mse(best.0),
        };
        stopped = on_step(&progress).is_break();
    }
    if steps > 0 {
        let before = scene.total_error();
        let shapes: Vec<Shape> = best
            .1
            .into_iter()
            .zip(best.2)
            .map(|(path, ramp)| match ramp.and_then(|ramp| Outline::from_path(&path, ramp)) {
                Some(outline) => Shape::from(outline),
                None => Shape::from(path),
            })
            .collect();
        scene.set_shapes(&shapes);
        if scene.total_error() > before {
            scene.set_shapes(&original);
        }
    }
    let values = 3.0 * f64::from(width) * f64::from(height);
    let psnr = psnr_of_mse(scene.total_error() / values);
    let _ = on_step(&Progress { seconds: started.elapsed().as_secs_f64(), steps, total_steps, psnr });
    steps
}
