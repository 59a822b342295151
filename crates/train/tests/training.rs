//! Short real trainings on the smoke configs: the loss falls, resuming is exact, refinement
//! learns its DPW term.

use std::path::{Path, PathBuf};

use burn::tensor::Device;
use model::{CoarseModel, RefineModel, load_coarse};
use train::RefineCheck;
use train::config::{self, CoarseConfig, Guidance, Rasterizer, RefineConfig};
use train::{CoarseObjective, Objective, RefineObjective};
use train::{Run, checkpoint_path, model_from, resume_from, train};
use train::{Validation, config::ValidationConfig};

/// Model initialization draws from the device's random generator, which is shared by the whole
/// process: tests that compare initializations must not run at the same time.
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("supersvg-train-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// The `(step, value)` pairs of `key` in a run's metrics.jsonl; a key no line holds fails, so a
/// renamed metric cannot pass an assertion over an empty list.
fn metric(dir: &Path, key: &str) -> Vec<(usize, f64)> {
    let values: Vec<_> = std::fs::read_to_string(dir.join("metrics.jsonl"))
        .unwrap()
        .lines()
        .filter_map(|line| {
            let json: serde_json::Value = serde_json::from_str(line).unwrap();
            Some((json["step"].as_u64().unwrap() as usize, json[key].as_f64()?))
        })
        .collect();
    assert!(!values.is_empty(), "no line of {}/metrics.jsonl holds {key:?}", dir.display());
    values
}

/// A renamed metric fails the reader instead of passing `.all(..)` over nothing.
#[test]
#[should_panic(expected = "holds \"l2\"")]
fn a_metric_no_line_holds_fails() {
    let dir = scratch("renamed-metric");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("metrics.jsonl"), "{\"step\": 1, \"loss\": 0.5}\n").unwrap();
    metric(&dir, "l2");
}

fn smoke_coarse() -> CoarseConfig {
    let mut config: CoarseConfig = config::load(&workspace().join("configs/smoke-coarse.toml")).unwrap();
    config.data.fixed_batch = true;
    config
}

/// Trains the coarse smoke config into `dir` for `steps` steps, resuming if asked.
fn coarse(dir: &Path, steps: usize, resume: bool) -> f32 {
    coarse_on(Rasterizer::Soft, dir, steps, resume)
}

/// [`coarse`] with the losses on `rasterizer`.
fn coarse_on(rasterizer: Rasterizer, dir: &Path, steps: usize, resume: bool) -> f32 {
    let mut config = smoke_coarse();
    config.train.steps = steps;
    config.raster.rasterizer = rasterizer;
    let device = Device::flex().autodiff();
    let objective = CoarseObjective::new(&config);
    let resumed = resume.then(|| resume_from::<CoarseObjective>(dir).unwrap());
    let path = checkpoint_path::<CoarseObjective>(dir);
    let start = model_from(
        |c| CoarseModel::new(c, &device),
        &config.model.0,
        resumed,
        &path,
        (&device, config.train.seed),
    )
    .unwrap();
    let run = Run { dir: dir.to_path_buf(), device, validation: None, overwrite: false };
    let json = serde_json::to_value(&config).unwrap();
    train(&objective, start, &config.train, &config.data, json, &run).unwrap().final_loss
}

/// Trains a fresh E_r on `teacher`'s encoder with `config` in a scratch folder named `name`,
/// without validation; the folder.
fn train_refine(
    config: &RefineConfig,
    teacher: &CoarseModel,
    model_config: &model::ModelConfig,
    name: &str,
    device: Device,
) -> PathBuf {
    let dir = scratch(name);
    let path = checkpoint_path::<RefineObjective>(&dir);
    let fresh = |c: &model::ModelConfig| RefineModel::new(c, &device).inherit_encoder(teacher);
    let start = model_from(fresh, model_config, None, &path, (&device, config.train.seed)).unwrap();
    let objective = RefineObjective::new(config, teacher.clone(), model_config.input);
    let run = Run { dir: dir.clone(), device, validation: None, overwrite: false };
    let json = serde_json::to_value(config).unwrap();
    train(&objective, start, &config.train, &config.data, json, &run).unwrap();
    dir
}

#[test]
fn coarse_loss_falls_and_resuming_reproduces_the_uninterrupted_run() {
    let _serial = SERIAL.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    let straight = scratch("straight");
    let final_loss = coarse(&straight, 30, false);
    let losses = metric(&straight, "loss");
    let first = losses.first().unwrap().1;
    assert!((final_loss as f64) < 0.7 * first, "loss {first} → {final_loss}");

    let interrupted = scratch("interrupted");
    coarse(&interrupted, 15, false);
    let resumed = coarse(&interrupted, 30, true);
    assert_eq!(resumed, final_loss, "resuming at step 15 must give the 30-step run's loss exactly");
    assert_eq!(metric(&interrupted, "loss"), losses, "the whole loss curve is reproduced");
    for dir in [straight, interrupted] {
        std::fs::remove_dir_all(dir).unwrap();
    }
}

/// The exact rasterizer's gradient (edge sampling, carried into autodiff) trains too, and
/// keeps paths visible (hidden paths still get an opacity gradient).
#[test]
fn coarse_loss_falls_on_the_exact_rasterizer() {
    let _serial = SERIAL.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    let dir = scratch("exact");
    let final_loss = coarse_on(Rasterizer::Exact, &dir, 30, false);
    let first = metric(&dir, "loss").first().unwrap().1;
    assert!((final_loss as f64) < 0.7 * first, "loss {first} → {final_loss}");
    let visible = metric(&dir, "visible_paths").last().unwrap().1;
    assert!(visible >= 1.0, "{visible} visible paths per crop at the end");
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn refinement_from_the_smoke_coarse_model_learns_its_dpw_term() {
    let _serial = SERIAL.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    let coarse_dir = scratch("teacher");
    coarse(&coarse_dir, 30, false);
    let mut config: RefineConfig = config::load(&workspace().join("configs/smoke-refine.toml")).unwrap();
    config.data.fixed_batch = true;
    assert_eq!(config.loss.guidance, Guidance::Dpw);

    // On both rasterizers: the exact one also paints the canvas E_r reads.
    for rasterizer in [Rasterizer::Soft, Rasterizer::Exact] {
        config.raster.rasterizer = rasterizer;
        let device = Device::flex().autodiff();
        let (teacher, model_config) =
            load_coarse(&checkpoint_path::<CoarseObjective>(&coarse_dir), &device).unwrap();
        let dir = train_refine(&config, &teacher, &model_config, &format!("refine-{rasterizer:?}"), device);

        let dpw: Vec<f64> = metric(&dir, "guidance").into_iter().map(|(_, v)| v).collect();
        assert!(dpw.iter().all(|v| v.is_finite()), "{rasterizer:?}: {dpw:?}");
        let half = dpw.len() / 2;
        let (early, late) = (
            dpw[..half].iter().sum::<f64>() / half as f64,
            dpw[half..].iter().sum::<f64>() / (dpw.len() - half) as f64,
        );
        assert!(late < early, "{rasterizer:?}: DPW did not decrease: {dpw:?}");
        std::fs::remove_dir_all(dir).unwrap();
    }
    std::fs::remove_dir_all(coarse_dir).unwrap();
}

#[test]
fn validation_scores_and_previews_are_written() {
    let _serial = SERIAL.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    let held_out = scratch("held-out");
    std::fs::create_dir_all(&held_out).unwrap();
    image::RgbImage::from_fn(64, 48, |x, y| {
        image::Rgb([(x * 4) as u8, (y * 5) as u8, if x < 30 { 200 } else { 30 }])
    })
    .save(held_out.join("photo.png"))
    .unwrap();
    let mut config = smoke_coarse();
    config.train.steps = 10;
    config.loss.canvas = train::config::Canvas::MeanColour;
    config.validation = ValidationConfig {
        images: Some(held_out.clone()),
        crops: 6,
        segments: [8, 16],
        every: 5,
        image_size: 64,
        refine_share: 0.1,
        coarse_share: 0.2,
    };
    let device = Device::flex().autodiff();
    let objective = CoarseObjective::new(&config);
    let dir = scratch("validated");
    let path = checkpoint_path::<CoarseObjective>(&dir);
    let start = model_from(
        |c| CoarseModel::new(c, &device),
        &config.model.0,
        None,
        &path,
        (&device, config.train.seed),
    )
    .unwrap();
    let set = Validation::build(&config.validation, &config.data, &start.model_config, 2).unwrap().unwrap();
    assert_eq!(set.crops().len(), 6);
    let run =
        Run { dir: dir.clone(), device, validation: Some((set, config.validation.every)), overwrite: false };
    let json = serde_json::to_value(&config).unwrap();
    train(&objective, start, &config.train, &config.data, json, &run).unwrap();

    let flat = metric(&dir, "val_psnr_flat");
    assert_eq!(flat.iter().map(|(step, _)| *step).collect::<Vec<_>>(), [5, 10]);
    for key in ["val_psnr_kept", "val_psnr_drawn", "val_spill", "val_kept", "val_visible"] {
        assert_eq!(metric(&dir, key).len(), 2, "{key}");
    }
    // Kept paths never make a crop worse than its flat fill.
    for ((_, kept), (_, flat)) in metric(&dir, "val_psnr_kept").iter().zip(&flat) {
        assert!(kept >= flat, "{kept} < {flat}");
    }
    assert!(dir.join("preview-000005.png").exists() && dir.join("preview-000010.png").exists());
    // Training lines are still there for the loss curve.
    assert_eq!(metric(&dir, "loss").len(), 2);
    for dir in [held_out, dir] {
        std::fs::remove_dir_all(dir).unwrap();
    }
}

/// E_r on the drawing inference hands it (`data.canvas = "fallback"`): its loss is the box's
/// whole error (no boundary term, nothing lies outside), it falls, and the run is scored the
/// way inference uses E_r, against as many more regions.
#[test]
fn refinement_on_the_fallback_drawing_trains_and_is_scored_at_inference() {
    let _serial = SERIAL.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    let held_out = scratch("held-out-refine");
    std::fs::create_dir_all(&held_out).unwrap();
    image::RgbImage::from_fn(64, 48, |x, y| {
        image::Rgb([(x * 4) as u8, (y * 5) as u8, if (x / 8 + y / 8) % 2 == 0 { 200 } else { 30 }])
    })
    .save(held_out.join("photo.png"))
    .unwrap();
    let mut config: RefineConfig = config::load(&workspace().join("configs/smoke-refine.toml")).unwrap();
    config.data.fixed_batch = true;
    config.data.canvas = train::config::SampleCanvas::Fallback;
    config.data.pick = train::config::RegionPick::Worst;
    config.train.steps = 20;
    config.raster.rasterizer = Rasterizer::Exact;
    config.validation = ValidationConfig {
        images: Some(held_out.clone()),
        crops: 4,
        segments: [6, 12],
        every: 10,
        image_size: 64,
        refine_share: 0.5,
        coarse_share: 0.2,
    };
    let device = Device::flex().autodiff();
    let teacher = CoarseModel::new(&smoke_coarse().model.0, &device);
    let model_config = smoke_coarse().model.0;
    let dir = scratch("refine-fallback");
    let path = checkpoint_path::<RefineObjective>(&dir);
    let fresh = |c: &model::ModelConfig| RefineModel::new(c, &device).inherit_encoder(&teacher);
    let start = model_from(fresh, &model_config, None, &path, (&device, config.train.seed)).unwrap();
    let mut objective = RefineObjective::new(&config, teacher.clone(), model_config.input);
    objective.check = RefineCheck::build(&config.validation, config.data.compactness, &model_config).unwrap();
    assert!(objective.check.is_some());
    let set = Validation::build(&config.validation, &config.data, &model_config, 2).unwrap();
    let run = Run { dir: dir.clone(), device, validation: set.map(|s| (s, 10)), overwrite: false };
    let json = serde_json::to_value(&config).unwrap();
    train(&objective, start, &config.train, &config.data, json, &run).unwrap();

    assert!(metric(&dir, "bound").iter().all(|&(_, b)| b == 0.0), "the whole box is the region");
    let l2 = metric(&dir, "l2");
    assert!(l2.last().unwrap().1 < l2.first().unwrap().1, "{l2:?}");
    let (proposed, kept) = (metric(&dir, "val_refine_proposed"), metric(&dir, "val_refine_kept"));
    assert_eq!(proposed.iter().map(|(step, _)| *step).collect::<Vec<_>>(), [10, 20]);
    for ((_, proposed), (_, kept)) in proposed.iter().zip(&kept) {
        assert!(kept <= proposed && *proposed > 0.0, "{kept} of {proposed}");
    }
    // Kept paths only lower the error; more regions lower it too, on a picture of ramps.
    assert!(metric(&dir, "val_refine_gain_db").iter().all(|&(_, db)| db >= 0.0));
    assert!(metric(&dir, "val_refine_regions_db").iter().all(|&(_, db)| db > 0.0));
    // The optimizer in E_r's place finds paths that lower the error too (the same figure at
    // every step: it does not depend on the model).
    let optimizer = metric(&dir, "val_refine_optimizer_db");
    assert!(optimizer.iter().all(|&(_, db)| db > 0.0 && db == optimizer[0].1), "{optimizer:?}");
    for dir in [held_out, dir] {
        std::fs::remove_dir_all(dir).unwrap();
    }
}

/// `loss.colours = "fitted"` scores E_r's paths as inference keeps them: the same shapes and
/// opacities in the colours that fit the image best over the canvas, so on one batch of the
/// fallback drawing the fitted L2 is below the L2 in an untrained E_r's own colours, for both
/// rasterizers.
#[test]
fn fitted_colours_score_the_shapes_inference_keeps() {
    // It initializes models from the device's shared generator (see SERIAL).
    let _serial = SERIAL.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    let device = Device::flex().autodiff();
    let model_config = smoke_coarse().model.0;
    let teacher = CoarseModel::new(&model_config, &device);
    let student = RefineModel::new(&model_config, &device).inherit_encoder(&teacher);
    let mut config: RefineConfig = config::load(&workspace().join("configs/smoke-refine.toml")).unwrap();
    config.data.canvas = train::config::SampleCanvas::Fallback;
    let samples =
        train::DataSource::new(&config.data, &model_config, 4, 7).unwrap().batch(0).unwrap().tensors(&device);
    for rasterizer in [Rasterizer::Soft, Rasterizer::Exact] {
        config.raster.rasterizer = rasterizer;
        let mut step = |colours| {
            config.loss.colours = colours;
            let objective = RefineObjective::new(&config, teacher.clone(), model_config.input);
            let output = objective.step(&student, &samples, 0);
            let l2 = output.terms.iter().find(|(name, _)| *name == "l2").unwrap().1.clone();
            (l2.into_scalar::<f32>(), output.paths)
        };
        let (own, predicted) = step(train::config::PathColours::Predicted);
        let (fitted, refitted) = step(train::config::PathColours::Fitted);
        assert!(fitted < own, "{rasterizer:?}: fitted {fitted} against {own}");
        let values = |t: burn::tensor::Tensor<4>| t.try_to_vec_as::<f32>().unwrap();
        assert_eq!(values(predicted.points()), values(refitted.points()));
        assert_ne!(
            predicted.colors().try_to_vec_as::<f32>().unwrap(),
            refitted.colors().try_to_vec_as::<f32>().unwrap()
        );
    }
}

/// `loss.teacher = "optimizer"`: on inference's drawing, E_r's guidance pulls its paths
/// towards the paths the exact optimizer places there, and 30 steps on one batch bring them
/// closer.
#[test]
fn refinement_learns_the_optimizers_paths() {
    let _serial = SERIAL.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    let mut config: RefineConfig = config::load(&workspace().join("configs/smoke-refine.toml")).unwrap();
    config.data.fixed_batch = true;
    config.data.canvas = train::config::SampleCanvas::Fallback;
    config.raster.rasterizer = Rasterizer::Exact;
    config.loss.teacher = train::config::Teacher::Optimizer;
    config.loss.teacher_steps = 30;
    let device = Device::flex().autodiff();
    let model_config = smoke_coarse().model.0;
    let teacher = CoarseModel::new(&model_config, &device);
    let dir = train_refine(&config, &teacher, &model_config, "refine-optimizer-teacher", device);

    let dpw: Vec<f64> = metric(&dir, "guidance").into_iter().map(|(_, v)| v).collect();
    assert!(dpw.iter().all(|v| v.is_finite() && *v > 0.0), "{dpw:?}");
    assert!(dpw.last().unwrap() < &(0.8 * dpw[0]), "DPW to the optimizer's paths did not fall: {dpw:?}");
    std::fs::remove_dir_all(dir).unwrap();
}
