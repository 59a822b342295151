//! SuperSVG-F: optimizing every shape of a result jointly against the image.
//!
//! All shapes at once, as the reference does (Adam on plain L2 over the whole image), on the
//! exact rendering and its gradient from [`raster::Window`]: a step costs the pixels of each
//! shape's own box (bands of rows in parallel), not shapes × pixels. Coordinates stay in the
//! canvas and colours and opacity in [0, 1]; the best state seen is kept, judged as the SVG
//! shows it.

use std::ops::ControlFlow;
use web_time::Instant;

use common::psnr_of_mse;
use raster::{
    Decimals, Fill, Filled, FlatAdam, Outline, Path, RAMP_COORDS, RAMP_PARAMS, Shape, ShapeGradient, Window,
    ramp_from_params, ramp_params,
};

use model::LearnedOptimizer;

use crate::fallback::fitted_path;
use crate::learned::LearnedSteps;
use crate::scene::{Origin, Scene};

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
    /// Adam learning rate of a path's control points (in the unit square of the image).
    pub lr_points: f32,
    /// Adam learning rate of the points of an outline moved as drawn ([`starting_outlines`]):
    /// finer than a path's, whose four cubics span a region, since a traced outline has a
    /// point every pixel or few, which a path's step would throw back and forth.
    pub lr_outline_points: f32,
    /// Adam learning rate of colours and opacity.
    pub lr_colors: f32,
    /// The outlines move as B drew them (the default), never fitted with one path: a fitted
    /// path starts from a drawing worse than B's, which the first second of F spends undoing
    /// (docs/eval/finetune.md).
    pub as_drawn: bool,
    /// Opacity is left as drawn (the default): B's shapes are opaque but for the few it made
    /// translucent, and a step of opacity trades the fill against what lies under it.
    pub fixed_alpha: bool,
    /// The learned optimizer's steps, taken first (none: Adam alone).
    pub learned: Option<Learned>,
}

/// The learned optimizer's part of SuperSVG-F ([`crate::learned`]): the network, how many of
/// F's steps it takes before Adam goes on, and where it runs.
#[derive(Clone, Debug)]
pub struct Learned {
    /// E_o.
    pub network: std::sync::Arc<LearnedOptimizer>,
    /// Its steps, first.
    pub steps: usize,
    /// Where it runs.
    pub device: burn::tensor::Device,
}

/// What the scene is painted over (as [`Scene`] scores it).
const WHITE: [f32; 3] = [1.0; 3];

/// [`FinetuneOptions::lr_outline_points`]' default: about a tenth of a pixel a step at 512 px
/// (the best of 1e-4, 2e-4 and 3e-4 on the emoji in docs/eval/finetune.md).
const LR_OUTLINE: f32 = 2e-4;

/// Every this many steps the best state so far is drawn as the SVG shows it, once the window
/// says it is past [`PARTING_PSNR`]. The window composites in f32, the SVG's renderers in 8
/// bits a layer: where translucent paths stack deep, at the PSNRs of flat art, the two part,
/// and the window's best can draw worse than an earlier state, even worse than B (measured in
/// docs/eval/finetune.md). Checking by steps keeps a given number of steps reproducible.
const CHECK_EVERY: usize = 10;

/// The window's PSNR (dB) from which F's best state is also checked along the way, not only
/// at its end: below it the window and the SVG agree (to 54 dB on the photos), so a check
/// would only cost its painting of the scene, at 2000 paths two steps' time of the twenty a
/// second takes (0.04–0.08 dB of a second's gain on the photos, docs/eval/finetune.md).
const PARTING_PSNR: f64 = 48.0;

impl Default for FinetuneOptions {
    /// 100 steps; a path's points at 1e-3 (about half a pixel a step at 512 px, the
    /// reference's rate) and colours at 3e-2, the best of the sweep in docs/method.md; an
    /// outline's points at [`LR_OUTLINE`].
    fn default() -> Self {
        Self {
            limit: Limit::Steps(100),
            lr_points: 1e-3,
            lr_outline_points: LR_OUTLINE,
            lr_colors: 3e-2,
            as_drawn: true,
            fixed_alpha: true,
            learned: None,
        }
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

/// Fine-tunes every shape of `scene` against its image: every point, colour (or ramp) and
/// opacity. The regions' outlines move as drawn ([`FinetuneOptions::as_drawn`]) or each fitted
/// with one path, whichever writes less ([`starting_outlines`]). The scene ends in the state, of those checked (every
/// [`CHECK_EVERY`] steps past [`PARTING_PSNR`], and the last best), that the exact renderer draws best; if none beats
/// the scene as it was, it keeps its old shapes, as it does when no step is taken. Returns the
/// number of optimizer steps taken (0 when the scene has nothing to move).
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
    let Some((start, was_path)) = starting_outlines(&original, (width, height), options.as_drawn) else {
        return 0;
    };
    let mut best = (f64::INFINITY, start);
    // The best state as the SVG shows it: its error and shapes (none: the scene as it was).
    let mut kept: (f64, Option<Vec<Shape>>) = (scene.total_error(), None);
    let mut trial = scene.clone();
    let mut check = |outlines: &[Outline], kept: &mut (f64, Option<Vec<Shape>>)| {
        let shapes = shapes_of(outlines, &was_path);
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
    let out_of_time = |steps: usize| match options.limit {
        Limit::Steps(total) => steps >= total,
        Limit::Seconds(limit) => started.elapsed().as_secs_f64() >= limit,
    };
    // How far F has come after `steps` steps, its best state's error in the window `mse`.
    let progress = |steps: usize, mse: f64| Progress {
        seconds: started.elapsed().as_secs_f64(),
        steps,
        total_steps,
        psnr: psnr_of_mse(mse),
    };
    // E_o's steps first, each from the last; Adam goes on from the best state they reached.
    if let Some(learned) = &options.learned {
        let movable = scene.paths().iter().map(|placed| placed.origin != Origin::Background).collect();
        let mut runner = LearnedSteps::new(movable, learned.steps);
        let mut outlines = best.1.clone();
        while steps < learned.steps && !stopped && !out_of_time(steps) {
            let (next, loss) = runner.step(&learned.network, &outlines, &window, image, &learned.device);
            if loss < best.0 {
                (best, unchecked) = ((loss, outlines), true);
            }
            outlines = next;
            steps += 1;
            stopped = on_step(&progress(steps, best.0)).is_break();
        }
        let loss = window.l2_outlines(&outlines);
        if loss < best.0 {
            (best, unchecked) = ((loss, outlines), true);
        }
    }
    let layout = Layout::of(&best.1);
    let mut params = layout.params(&best.1);
    let rates = layout.rates(options, &was_path);
    let mut adam = FlatAdam::new(params.len());
    loop {
        let done = stopped || out_of_time(steps);
        let outlines = layout.outlines(&best.1, &params);
        if done {
            let loss = window.l2_outlines(&outlines);
            if loss < best.0 {
                (best, unchecked) = ((loss, outlines), true);
            }
            break;
        }
        let (loss, gradients) = window.l2_gradient_outlines(&outlines);
        if loss < best.0 {
            (best, unchecked) = ((loss, outlines), true);
        }
        let parting = psnr_of_mse(best.0) >= PARTING_PSNR;
        if unchecked && parting && steps % CHECK_EVERY == 0 && steps > 0 {
            check(&best.1, &mut kept);
            unchecked = false;
        }
        adam.step(&rates, &mut params, &layout.gradient(&gradients));
        steps += 1;
        stopped = on_step(&progress(steps, best.0)).is_break();
    }
    if steps > 0 && unchecked {
        check(&best.1, &mut kept);
    }
    if let (_, Some(shapes)) = kept {
        scene.set_shapes(&shapes);
    }
    let values = 3.0 * f64::from(width) * f64::from(height);
    let psnr = psnr_of_mse(scene.total_error() / values);
    let _ = on_step(&Progress { seconds: started.elapsed().as_secs_f64(), steps, total_steps, psnr });
    steps
}

/// What F moves, as outlines, and whether each goes back as a path (unless it ends in a ramp):
/// the drawing's shapes as they are drawn, or each region's outline fitted with one path
/// ([`fitted_path`]), whichever writes fewer bytes of path data. A path moved costs what it
/// cost; an outline moved costs more than drawn (its points leave the grid), so F moves the
/// outlines where they are compact (flat art, small images), and fits them where one path
/// writes less (the long traced edges of photos), where moving them would spend bytes that
/// more regions use better (docs/eval/finetune.md). `None` when there is nothing to move.
fn starting_outlines(
    shapes: &[Shape],
    (width, height): (u32, u32),
    as_drawn: bool,
) -> Option<(Vec<Outline>, Vec<bool>)> {
    let size = [width as f32, height as f32];
    let fitted: Option<Vec<Path>> = shapes
        .iter()
        .map(|shape| match shape {
            Shape::Path(path) => Some(*path),
            Shape::Outline(outline) => fitted_path(outline, (width, height)),
        })
        .collect();
    let fitted = fitted.filter(|paths| !as_drawn && path_bytes(paths, size) < path_bytes(shapes, size));
    let pairs: Option<Vec<(Outline, bool)>> = match fitted {
        Some(paths) => (paths.iter().zip(shapes))
            .map(|(path, shape)| Some((Outline::from_path(path, shape.fill())?, true)))
            .collect(),
        None => shapes
            .iter()
            .map(|shape| match shape {
                Shape::Path(path) => Some((Outline::from_path(path, path.color)?, true)),
                Shape::Outline(outline) => Some(((**outline).clone(), false)),
            })
            .collect(),
    };
    pairs.map(|pairs| pairs.into_iter().unzip())
}

/// The bytes of `shapes`' SVG path data on a canvas of `size`, at two decimals.
fn path_bytes(shapes: &[impl Filled], size: [f32; 2]) -> usize {
    let mut data = String::new();
    for shape in shapes {
        shape.svg_data(size, Decimals::new(2), &mut data);
    }
    data.len()
}

/// Where each outline's parameters lie in the one list Adam moves: its points (x, y each),
/// then its paint (a colour's RGB, or a ramp's ends and stops in [`ramp_params`]' layout),
/// then its opacity.
struct Layout {
    /// Per outline: its number of points and whether it is filled with a ramp.
    shapes: Vec<(usize, bool)>,
}

impl Layout {
    /// The layout of `outlines`' parameters.
    fn of(outlines: &[Outline]) -> Self {
        let ramped = |outline: &Outline| matches!(outline.fill, Fill::Linear(_));
        Self { shapes: outlines.iter().map(|o| (o.points().len(), ramped(o))).collect() }
    }

    /// `outlines`' parameters.
    fn params(&self, outlines: &[Outline]) -> Vec<f32> {
        let mut params = Vec::new();
        for outline in outlines {
            params.extend(outline.points().into_iter().flatten());
            match outline.fill {
                Fill::Linear(ramp) => params.extend(ramp_params(&ramp)),
                Fill::Solid(color) => params.extend(color),
            }
            params.push(outline.alpha);
        }
        params
    }

    /// Each parameter's learning rate: `lr_points` for a path's points and a ramp's ends
    /// (`lr_outline_points` for an outline's), `lr_colors` for colours, stops and opacity.
    fn rates(&self, options: &FinetuneOptions, was_path: &[bool]) -> Vec<f32> {
        let mut rates = Vec::new();
        for (&(points, ramped), &path) in self.shapes.iter().zip(was_path) {
            let (coords, paint) = if ramped { (RAMP_COORDS, RAMP_PARAMS - RAMP_COORDS) } else { (0, 3) };
            let rate = if path { options.lr_points } else { options.lr_outline_points };
            rates.extend(std::iter::repeat_n(rate, 2 * points + coords));
            rates.extend(std::iter::repeat_n(options.lr_colors, paint));
            rates.push(if options.fixed_alpha { 0.0 } else { options.lr_colors });
        }
        rates
    }

    /// The outlines of `params`, shaped as `like`.
    fn outlines(&self, like: &[Outline], params: &[f32]) -> Vec<Outline> {
        let mut at = 0;
        like.iter()
            .zip(&self.shapes)
            .map(|(outline, &(points, ramped))| {
                let mut take = |len: usize| {
                    at += len;
                    &params[at - len..at]
                };
                let points: Vec<[f32; 2]> = take(2 * points).chunks_exact(2).map(|p| [p[0], p[1]]).collect();
                let mut moved = outline.with_points(&points);
                moved.fill = if ramped {
                    ramp_from_params(take(RAMP_PARAMS).try_into().expect("a ramp's parameters")).into()
                } else {
                    Fill::Solid(take(3).try_into().expect("RGB"))
                };
                moved.alpha = take(1)[0];
                moved
            })
            .collect()
    }

    /// `gradients` laid out as the parameters.
    fn gradient(&self, gradients: &[ShapeGradient]) -> Vec<f32> {
        let mut flat = Vec::new();
        for (gradient, &(_, ramped)) in gradients.iter().zip(&self.shapes) {
            flat.extend(gradient.points.iter().flatten());
            if ramped {
                flat.extend(gradient.ramp);
            } else {
                flat.extend(gradient.color);
            }
            flat.push(gradient.alpha);
        }
        flat
    }
}

/// Moved outlines as the shapes of a scene: one that was a path and is still filled with one
/// colour goes back as that path.
fn shapes_of(outlines: &[Outline], was_path: &[bool]) -> Vec<Shape> {
    outlines
        .iter()
        .zip(was_path)
        .map(|(outline, &was_path)| match (outline.fill, was_path) {
            (Fill::Solid(color), true) => {
                let points: [[f32; 2]; 12] = outline.points().try_into().expect("a path's twelve points");
                Shape::from(Path { points, color, alpha: outline.alpha })
            }
            _ => Shape::from(outline.clone()),
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

    /// More steps never end in a worse drawing than fewer, counted in checks: past
    /// [`PARTING_PSNR`] a run's check after `CHECK_EVERY · k` steps is the shorter run's last,
    /// below it the window's best is the SVG's. Nor worse than B.
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

    /// A compact outline (a square's four corners) moves as drawn; a long traced edge (a disc's
    /// staircase, a point every pixel) writes less as one fitted path and is fitted; a path
    /// stays itself either way.
    #[test]
    fn the_cheaper_start_is_moved() {
        let size = (64, 64);
        let square =
            Outline::polygon(&[[0.2, 0.2], [0.6, 0.2], [0.6, 0.6], [0.2, 0.6]], [0.1, 0.5, 0.9], 1.0)
                .unwrap();
        let path = Path::quadrilateral([[0.1, 0.1], [0.3, 0.1], [0.3, 0.3], [0.1, 0.3]], [0.9; 3], 1.0);
        let (outlines, was_path) =
            starting_outlines(&[Shape::from(square.clone()), Shape::from(path)], size, false).unwrap();
        assert_eq!(was_path, [false, true]);
        assert_eq!(outlines[0], square);
        assert_eq!(outlines[1].points(), path.points);

        let staircase: Vec<[f32; 2]> = (0..240)
            .map(|i| {
                let angle = i as f32 / 240.0 * std::f32::consts::TAU;
                [(32.0 + 25.0 * angle.cos()).round() / 64.0, (32.0 + 25.0 * angle.sin()).round() / 64.0]
            })
            .collect();
        let disc = Outline::polygon(&staircase, [0.3; 3], 1.0).unwrap();
        let (outlines, was_path) = starting_outlines(&[Shape::from(disc.clone())], size, false).unwrap();
        assert_eq!(was_path, [true]);
        assert_eq!(outlines[0].points().len(), 12);
        assert_ne!(outlines[0], disc);
    }

    /// On flat art the fallback's outlines move as drawn: F starts where B is, every outline
    /// stays an outline, and its points move.
    #[test]
    fn fine_tuning_moves_the_drawn_outlines() {
        let b = discs();
        let mut scene = b.clone();
        finetune(&mut scene, &FinetuneOptions { limit: Limit::Steps(100), ..FinetuneOptions::default() });
        assert!(
            scene.total_error() < b.total_error(),
            "{} against B's {}",
            scene.total_error(),
            b.total_error()
        );
        let outlines = |scene: &Scene| -> Vec<Vec<[f32; 2]>> {
            (scene.scene().iter())
                .filter_map(|shape| match shape {
                    Shape::Outline(outline) => Some(outline.points()),
                    Shape::Path(_) => None,
                })
                .collect()
        };
        let (before, after) = (outlines(&b), outlines(&scene));
        assert!(before.len() > 1, "{} outlines", before.len());
        assert_eq!(after.len(), before.len());
        assert!(before.iter().zip(&after).any(|(b, a)| b.len() == a.len() && b != a));
    }
}
