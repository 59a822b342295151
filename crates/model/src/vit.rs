//! The ViT encoder shared by both stages.

use burn::module::{Module, Param};
use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::nn::transformer::{TransformerEncoder, TransformerEncoderConfig};
use burn::nn::{Initializer, LayerNorm, LayerNormConfig};
use burn::tensor::{Device, Tensor};

use crate::config::ModelConfig;

/// A Vision Transformer: patch embedding (convolution with stride = patch), class token, learned
/// position embedding, pre-norm transformer blocks (multi-head self-attention and a GELU MLP),
/// final LayerNorm. Returns the patch tokens without the class token.
#[derive(Module, Debug)]
pub struct VitEncoder {
    patch_embedding: Conv2d,
    class_token: Param<Tensor<3>>,
    position_embedding: Param<Tensor<3>>,
    blocks: TransformerEncoder,
    norm: LayerNorm,
}

impl VitEncoder {
    /// A freshly initialized encoder (position and class embeddings ~ N(0, 0.02²), as in ViT).
    pub fn new(config: &ModelConfig, device: &Device) -> Self {
        let dim = config.embed_dim;
        let patch = config.patch_size;
        let embedding = Initializer::Normal { mean: 0.0, std: 0.02 };
        Self {
            patch_embedding: Conv2dConfig::new([3, dim], [patch, patch])
                .with_stride([patch, patch])
                .init(device),
            class_token: embedding.init([1, 1, dim], device),
            position_embedding: embedding.init([1, config.tokens() + 1, dim], device),
            blocks: TransformerEncoderConfig::new(dim, dim * config.mlp_ratio, config.heads, config.depth)
                .with_dropout(0.0)
                .with_norm_first(true)
                .init(device),
            norm: LayerNormConfig::new(dim).init(device),
        }
    }

    /// `[B, 3, S, S]` images to `[B, tokens, embed_dim]` features.
    pub fn forward(&self, images: Tensor<4>) -> Tensor<3> {
        let patches = self.patch_embedding.forward(images);
        let [batch, dim, rows, columns] = patches.dims();
        let tokens = patches.reshape([batch, dim, rows * columns]).swap_dims(1, 2);
        let class = self.class_token.val().expand([batch, 1, dim]);
        let x = Tensor::cat(vec![class, tokens], 1) + self.position_embedding.val();
        let x = self.norm.forward(crate::block::encode(&self.blocks, x));
        x.narrow(1, 1, rows * columns)
    }
}
