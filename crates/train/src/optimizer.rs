//! AdamW as the method trains with it.

use burn::grad_clipping::GradientClippingConfig;
use burn::module::ParamGroup;
use burn::optim::{AdamWConfig, ModuleOptimizer};

use crate::config::OptimConfig;

/// AdamW with the configured β and weight decay, except on norms and biases (no decay there),
/// with per-parameter gradient-norm clipping when `grad_clip > 0`.
pub fn adamw(config: &OptimConfig) -> ModuleOptimizer {
    let [beta_1, beta_2] = config.betas;
    let decayed = AdamWConfig::new().with_beta_1(beta_1).with_beta_2(beta_2).with_epsilon(1e-8);
    let clipping = (config.grad_clip > 0.0).then(|| GradientClippingConfig::Norm(config.grad_clip).init());
    let mut optimizer = ModuleOptimizer::from(decayed.clone().with_weight_decay(config.weight_decay).build());
    if let Some(clipping) = clipping.clone() {
        optimizer = optimizer.with_grad_clipping(clipping);
    }
    let not_decayed = ParamGroup::from_any_predicates(vec!["norm", "bias"]);
    optimizer.with_group(not_decayed, decayed.with_weight_decay(0.0).build(), clipping)
}
