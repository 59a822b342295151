//! E_c: a region crop to n paths with visibility.

use burn::module::{Module, Param};
use burn::nn::{Linear, LinearConfig};
use burn::tensor::activation::sigmoid;
use burn::tensor::{Device, Tensor};
use raster::{PARAMS, PARAMS_OPAQUE, PathBatch};

use crate::config::ModelConfig;
use crate::decoder::PathDecoder;
use crate::prior::{grid_prior, small_head};
use crate::vit::VitEncoder;

/// The coarse-stage model: ViT encoder → path decoder → a linear head to 28 parameters per path,
/// plus a learnable per-path offset ([`grid_prior`]) that starts the paths tiled over the crop.
///
/// Every output goes through a sigmoid: coordinates land in the crop's unit square, colours in
/// [0, 1], and the last value is the visibility probability σ(z), turned into β ∈ {0, 1} with
/// the straight-through surrogate of [`dpw::visibility`]. β is the path's α.
#[derive(Module, Debug)]
pub struct CoarseModel {
    encoder: VitEncoder,
    decoder: PathDecoder,
    head: Linear,
    prior: Param<Tensor<2>>,
}

impl CoarseModel {
    /// A freshly initialized model of the given size.
    pub fn new(config: &ModelConfig, device: &Device) -> Self {
        Self {
            encoder: VitEncoder::new(config, device),
            decoder: PathDecoder::new(config, config.paths, device),
            head: LinearConfig::new(config.query_dim, PARAMS).with_initializer(small_head()).init(device),
            prior: grid_prior(config.paths, PARAMS, device),
        }
    }

    /// `[B, 3, S, S]` crops (colours in [0, 1], −1 outside the mask) to `[B, n]` paths in the
    /// crops' unit squares, painter's order, α = β.
    pub fn forward(&self, crops: Tensor<4>) -> PathBatch {
        let features = self.decoder.forward(self.encoder.forward(crops));
        let params = sigmoid(self.head.forward(features) + self.prior.val().unsqueeze());
        let visible = dpw::visibility(params.clone().narrow(2, PARAMS_OPAQUE, 1));
        PathBatch::new(Tensor::cat(vec![params.narrow(2, 0, PARAMS_OPAQUE), visible], 2))
    }

    /// The ViT encoder, which the refinement model inherits.
    pub fn encoder(&self) -> &VitEncoder {
        &self.encoder
    }
}

#[cfg(test)]
mod tests {
    use burn::tensor::Distribution;

    use super::*;
    use crate::config::Preset;

    #[test]
    fn only_the_visibility_output_carries_the_surrogate_gradient_of_the_path_count() {
        let device = Device::flex().autodiff();
        let config = ModelConfig {
            input_size: 32,
            embed_dim: 48,
            depth: 1,
            heads: 2,
            paths: 6,
            query_dim: 32,
            query_heads: 2,
            ..ModelConfig::preset(Preset::Cpu)
        };
        let model = CoarseModel::new(&config, &device);
        let crops = Tensor::random([2, 3, 32, 32], Distribution::Uniform(-1.0, 1.0), &device);
        let grads = model.forward(crops.clone()).alpha().sum().backward();
        let bias = model.head.bias.as_ref().expect("the head has a bias");
        let gradient: Vec<f32> = bias.grad(&grads).expect("a gradient").try_to_vec_as().unwrap();
        // ∂Σβ/∂b for the visibility output: Σ over paths of σ'(p − 0.5) · p(1 − p), p = σ(z).
        let features = model.decoder.forward(model.encoder.forward(crops));
        let z = model.head.forward(features) + model.prior.val().unsqueeze();
        let p: Vec<f32> = sigmoid(z).narrow(2, PARAMS_OPAQUE, 1).try_to_vec_as().unwrap();
        let s = |p: f32| 1.0 / (1.0 + (0.5 - p).exp());
        let expected: f32 = p.iter().map(|&p| s(p) * (1.0 - s(p)) * p * (1.0 - p)).sum();
        let visibility = gradient[PARAMS_OPAQUE];
        assert!((visibility - expected).abs() <= 1e-4 * expected, "{visibility} vs {expected}");
        assert!(expected > 0.1, "12 paths give a gradient of {expected}");
        assert!(gradient[..PARAMS_OPAQUE].iter().all(|&g| g == 0.0), "shape and colour: {gradient:?}");
    }
}
