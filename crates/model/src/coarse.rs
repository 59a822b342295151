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
