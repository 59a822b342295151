//! SuperSVG-F: optimizing every path of a result jointly against the image.
//!
//! All paths at once, as the reference does (Adam on plain L2 over the whole image), on the
//! exact rendering and its gradient from [`raster::Window`]: a step costs the pixels of each
//! path's own box (bands of rows in parallel), not paths × pixels. Coordinates stay in the
//! canvas and colours and opacity in [0, 1]; the best state seen is kept, judged as the SVG
//! shows it.

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

/// Every this many steps the best state so far is drawn as the SVG shows it. The window
/// composites in f32, the SVG's renderers in 8 bits a layer: where translucent paths stack
/// deep, at the PSNRs of flat art, the two part, and the window's best can draw worse than an
/// earlier state, even worse than B (measured in docs/eval/finetune.md). Checking by steps
/// keeps a given number of steps reproducible; a check costs one painting of the scene.
const CHECK_EVERY: usize = 100;

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
/// them. The scene ends in the state, of those checked (every [`CHECK_EVERY`] steps and the
/// last best), that the exact renderer draws best; if none beats the scene as it was, it keeps
/// its old shapes, as it does when no step is taken. Returns the number of optimizer steps
/// taken (0 when a polygon cannot be fitted).
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
    // The best state as the SVG shows it: its error and shapes (none: the scene as it was).
    let mut kept: (f64, Option<Vec<Shape>>) = (scene.total_error(), None);
    let mut trial = scene.clone();
    let mut check = |paths: &[Path], ramps: &[Option<Ramp>], kept: &mut (f64, Option<Vec<Shape>>)| {
        let shapes = shapes_of(paths, ramps);
        trial.set_shapes(&shapes);
        let error = trial.total_error();
        if error < kept.0 {
            *kept = (error, Some(shapes));
        }
    };
    let mut unchecked = false;
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
                (best.1, best.2, unchecked) = (paths, ramps, true);
            }
            break;
        }
        let (loss, gradients, ramp_gradients) = window.l2_gradient_ramped(&paths, &ramps);
        if loss < best.0 {
            (best, unchecked) = ((loss, paths, ramps), true);
        }
        if unchecked && steps % CHECK_EVERY == 0 && steps > 0 {
            check(&best.1, &best.2, &mut kept);
            unchecked = false;
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
    if steps > 0 && unchecked {
        check(&best.1, &best.2, &mut kept);
    }
    if let (_, Some(shapes)) = kept {
        scene.set_shapes(&shapes);
    }
    let values = 3.0 * f64::from(width) * f64::from(height);
    let psnr = psnr_of_mse(scene.total_error() / values);
    let _ = on_step(&Progress { seconds: started.elapsed().as_secs_f64(), steps, total_steps, psnr });
    steps
}

/// Paths and their ramps as the shapes of a scene: a ramped path as its outline in its ramp.
fn shapes_of(paths: &[Path], ramps: &[Option<Ramp>]) -> Vec<Shape> {
    paths
        .iter()
        .zip(ramps)
        .map(|(path, ramp)| match ramp.and_then(|ramp| Outline::from_path(path, ramp)) {
            Some(outline) => Shape::from(outline),
            None => Shape::from(*path),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use image::{Rgb, Rgb32FImage};
    use superpixel::{SlicOptions, slic};

    use super::*;
    use crate::fallback::{FallbackDrawing, Style};
    use crate::fills::Ramps;

    /// Flat discs on a flat ground, drawn by the fallback: flat art, where F's window and the
    /// SVG's 8-bit compositing part most.
    fn discs() -> Scene {
        let image = Arc::new(Rgb32FImage::from_fn(64, 48, |x, y| {
            let inside = |cx: f32, cy: f32, r: f32| (x as f32 - cx).hypot(y as f32 - cy) < r;
            if inside(20.0, 20.0, 11.0) {
                Rgb([0.9, 0.2, 0.1])
            } else if inside(44.0, 30.0, 9.0) {
                Rgb([0.1, 0.3, 0.8])
            } else {
                Rgb([0.95, 0.9, 0.6])
            }
        }));
        let segmentation =
            Arc::new(slic(&image, &SlicOptions { n_segments: 16, ..Default::default() }).unwrap());
        let drawing =
            FallbackDrawing::new(&image, &segmentation, Style { tolerance: None, ramps: Ramps::None });
        Scene::drawn(image, segmentation, drawing.placed(), drawing.canvas.clone())
    }

    /// More steps never end in a worse drawing than fewer, counted in checks: a run's check
    /// after `CHECK_EVERY · k` steps is the shorter run's last. Nor worse than B.
    #[test]
    fn more_steps_never_draw_worse() {
        let b = discs();
        let errors: Vec<f64> = [1, 2, 4]
            .map(|checks| {
                let mut scene = b.clone();
                let limit = Limit::Steps(checks * CHECK_EVERY);
                finetune(&mut scene, &FinetuneOptions { limit, ..FinetuneOptions::default() });
                scene.total_error()
            })
            .to_vec();
        assert!(errors[0] <= b.total_error(), "{errors:?} against B's {}", b.total_error());
        assert!(errors.windows(2).all(|pair| pair[1] <= pair[0]), "{errors:?}");
        assert!(errors[2] < b.total_error(), "F moved nothing: {errors:?}");
    }
}
