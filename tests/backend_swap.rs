//! One coarse and one refinement training step, from the same weights and batch, give the same
//! losses, gradients and updated weights on every backend.

use std::path::Path;

use burn::module::{Module, ModuleVisitor, Param};
use burn::optim::{GradientsParams, SgdConfig};
use burn::tensor::{Device, Gradients, Tensor};
use supersvg::model::{CoarseModel, ModelConfig, RefineModel};
use supersvg::raster::Backend;
use supersvg::train::DataSource;
use supersvg::train::config::{self, CoarseConfig, RefineConfig};
use supersvg::train::{CoarseObjective, Objective, RefineObjective};

/// Every float parameter's values, and its gradient when `gradients` are given, in visit order.
struct Collect<'a> {
    gradients: Option<&'a Gradients>,
    values: Vec<f32>,
}

impl ModuleVisitor for Collect<'_> {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        let tensor = match self.gradients {
            Some(gradients) => param.val().grad(gradients).unwrap_or_else(|| param.val().zeros_like()),
            None => param.val(),
        };
        self.values.extend(tensor.try_to_vec_as::<f32>().unwrap());
    }
}

fn collect<M: Module>(module: &M, gradients: Option<&Gradients>) -> Vec<f32> {
    let mut visitor = Collect { gradients, values: Vec::new() };
    module.visit(&mut visitor);
    visitor.values
}

/// Loss terms, gradients and weights after one SGD step.
struct StepResult {
    losses: Vec<f32>,
    gradients: Vec<f32>,
    weights: Vec<f32>,
}

fn step<O: Objective>(
    objective: &O,
    model: O::Model,
    batch: &supersvg::train::Batch,
    device: &Device,
) -> StepResult {
    let output = objective.step(&model, &batch.tensors(device), 0);
    let mut losses = vec![output.total.clone().into_scalar::<f32>()];
    losses.extend(output.terms.iter().map(|(_, t)| t.clone().into_scalar::<f32>()));
    let raw = output.total.backward();
    let gradients = collect(&model, Some(&raw));
    let grads = GradientsParams::from_grads(raw, &model);
    let model = SgdConfig::new().init().step(0.1, model, grads);
    StepResult { losses, gradients, weights: collect(&model, None) }
}

fn assert_close(name: &str, backend: Backend, a: &[f32], b: &[f32]) {
    assert_eq!(a.len(), b.len());
    let scale = a.iter().fold(1e-6f32, |m, v| m.max(v.abs()));
    let gap = a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f32::max) / scale;
    assert!(gap <= 1e-3, "{backend}: {name} differ by {gap} relative to the largest value");
}

fn configs() -> (CoarseConfig, RefineConfig) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    (
        config::load(&root.join("configs/smoke-coarse.toml")).unwrap(),
        config::load(&root.join("configs/smoke-refine.toml")).unwrap(),
    )
}

#[test]
fn training_steps_agree_across_backends() {
    let (coarse_config, refine_config) = configs();
    let model_config: ModelConfig = coarse_config.model.0.clone();
    let flex = Device::flex();
    let coarse = CoarseModel::new(&model_config, &flex);
    let refine = RefineModel::new(&model_config, &flex);
    let source = DataSource::new(&coarse_config.data, &model_config, 2, 3).unwrap();
    let batch = source.batch(0).unwrap();

    let run = |backend: Backend| {
        let device = backend.autodiff_device().unwrap_or_else(|err| panic!("{err}"));
        let load_coarse =
            || CoarseModel::new(&model_config, &device).load_record(coarse.clone().into_record());
        let coarse_objective = CoarseObjective::new(&coarse_config);
        let coarse_step = step(&coarse_objective, load_coarse(), &batch, &device);
        let refine_objective = RefineObjective {
            seed: 5,
            ..RefineObjective::new(&refine_config, load_coarse(), model_config.input)
        };
        let student = RefineModel::new(&model_config, &device).load_record(refine.clone().into_record());
        let refine_step = step(&refine_objective, student, &batch, &device);
        (coarse_step, refine_step)
    };
    let (coarse_flex, refine_flex) = run(Backend::Flex);
    // The backends this build promises: ndarray always (through train), wgpu with the crate's
    // `wgpu` feature. None is skipped: one that cannot be created fails the test.
    let promised = [Backend::Ndarray].into_iter().chain(cfg!(feature = "wgpu").then_some(Backend::Wgpu));
    for backend in promised {
        let (coarse_other, refine_other) = run(backend);
        for (stage, a, b) in
            [("coarse", &coarse_flex, &coarse_other), ("refine", &refine_flex, &refine_other)]
        {
            assert_eq!(a.losses.len(), b.losses.len(), "{backend}: {stage} loss terms");
            for (x, y) in a.losses.iter().zip(&b.losses) {
                assert!((x - y).abs() <= 1e-3 * x.abs().max(1e-3), "{backend}: {stage} loss {x} vs {y}");
            }
            assert_close(&format!("{stage} gradients"), backend, &a.gradients, &b.gradients);
            assert_close(&format!("{stage} updated weights"), backend, &a.weights, &b.weights);
        }
    }
}
