//! The learning-rate schedule: linear warm-up, then cosine decay.

use crate::config::OptimConfig;

/// Learning rate before step `step` (0-based): rises linearly over `warmup_steps` to `lr`, then
/// follows a half cosine down to `min_lr` at `steps`.
pub fn learning_rate(config: &OptimConfig, step: usize) -> f64 {
    if step < config.warmup_steps {
        return config.lr * (step + 1) as f64 / config.warmup_steps as f64;
    }
    let span = config.steps.saturating_sub(config.warmup_steps).max(1) as f64;
    let progress = ((step - config.warmup_steps) as f64 / span).min(1.0);
    config.min_lr + 0.5 * (config.lr - config.min_lr) * (1.0 + (std::f64::consts::PI * progress).cos())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn warms_up_then_decays_to_the_floor() {
        let config =
            OptimConfig { lr: 1e-3, min_lr: 1e-5, warmup_steps: 10, steps: 110, ..Default::default() };
        assert!((learning_rate(&config, 0) - 1e-4).abs() < 1e-12);
        assert!((learning_rate(&config, 9) - 1e-3).abs() < 1e-12);
        assert!((learning_rate(&config, 10) - 1e-3).abs() < 1e-12);
        assert!((learning_rate(&config, 60) - (1e-5 + 0.5 * (1e-3 - 1e-5))).abs() < 1e-12);
        assert!((learning_rate(&config, 110) - 1e-5).abs() < 1e-12);
        let mut last = f64::INFINITY;
        for step in 10..=110 {
            let lr = learning_rate(&config, step);
            assert!(lr <= last);
            last = lr;
        }
    }
}
