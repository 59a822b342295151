//! From image tokens to one feature vector per path.

use burn::module::{Module, Param};
use burn::nn::attention::{MhaInput, MultiHeadAttention, MultiHeadAttentionConfig};
use burn::nn::transformer::{
    PositionWiseFeedForward, PositionWiseFeedForwardConfig, TransformerEncoder, TransformerEncoderConfig,
};
use burn::nn::{Initializer, LayerNorm, LayerNormConfig, Linear, LinearConfig};
use burn::tensor::{Device, Int, Tensor, TensorData};

use crate::prior::cell_center;

use crate::config::ModelConfig;

/// Learnable path queries that read the image: a cross-attention block (queries attend to the
/// image tokens, `softmax(W_Q T_l (W_K T_f)ᵀ / √d) W_V T_f`, then a GELU MLP, both pre-norm with
/// residuals), then one self-attention block among the queries (pre-norm, GELU MLP), then a
/// LayerNorm. One query per path; the query width is `query_dim`.
///
/// Each query is anchored: before attending, it is added the (projected) image token under its
/// path's starting cell ([`cell_center`], the cell [`crate::prior::grid_prior`] starts the
/// path in). Every path then sees its own part of the image from the first step, instead of
/// all queries reading the same near-uniform attention and predicting the same colour until
/// attention has learned to be spatial.
#[derive(Module, Debug)]
pub struct PathDecoder {
    queries: Param<Tensor<2>>,
    memory: Linear,
    query_norm: LayerNorm,
    memory_norm: LayerNorm,
    cross_attention: MultiHeadAttention,
    mlp_norm: LayerNorm,
    mlp: PositionWiseFeedForward,
    self_attention: TransformerEncoder,
    norm: LayerNorm,
}

impl PathDecoder {
    /// A decoder with `paths` learnable queries.
    pub fn new(config: &ModelConfig, paths: usize, device: &Device) -> Self {
        let dim = config.query_dim;
        let hidden = dim * config.mlp_ratio;
        Self {
            queries: Initializer::Normal { mean: 0.0, std: 0.02 }.init([paths, dim], device),
            memory: LinearConfig::new(config.embed_dim, dim).init(device),
            query_norm: LayerNormConfig::new(dim).init(device),
            memory_norm: LayerNormConfig::new(dim).init(device),
            cross_attention: MultiHeadAttentionConfig::new(dim, config.query_heads)
                .with_dropout(0.0)
                .init(device),
            mlp_norm: LayerNormConfig::new(dim).init(device),
            mlp: PositionWiseFeedForwardConfig::new(dim, hidden).with_dropout(0.0).init(device),
            self_attention: TransformerEncoderConfig::new(dim, hidden, config.query_heads, 1)
                .with_dropout(0.0)
                .with_norm_first(true)
                .init(device),
            norm: LayerNormConfig::new(dim).init(device),
        }
    }

    /// Number of paths (learnable queries).
    pub fn paths(&self) -> usize {
        self.queries.dims()[0]
    }

    /// `[B, tokens, embed_dim]` image features to `[B, paths, query_dim]` path features.
    pub fn forward(&self, tokens: Tensor<3>) -> Tensor<3> {
        let [batch, tokens_count, _] = tokens.dims();
        let [paths, dim] = self.queries.dims();
        let memory = self.memory_norm.forward(self.memory.forward(tokens));
        let anchors = anchor_tokens(paths, tokens_count, &memory.device());
        let queries = self.queries.val().unsqueeze::<3>().expand([batch, paths, dim])
            + memory.clone().select(1, anchors);
        let attended = self
            .cross_attention
            .forward(MhaInput::new(self.query_norm.forward(queries.clone()), memory.clone(), memory))
            .context;
        let x = queries + attended;
        let x = x.clone() + crate::block::mlp(&self.mlp, self.mlp_norm.forward(x));
        let x = crate::block::encode(&self.self_attention, x);
        self.norm.forward(x)
    }
}

/// The token under each path's starting cell, for a square grid of `tokens` patches.
fn anchor_tokens(paths: usize, tokens: usize, device: &Device) -> Tensor<1, Int> {
    let side = (tokens as f32).sqrt().round() as usize;
    let indices: Vec<i64> = (0..paths)
        .map(|path| {
            let [x, y] = cell_center(path, paths);
            let (column, row) = ((x * side as f32) as usize, (y * side as f32) as usize);
            (row.min(side - 1) * side + column.min(side - 1)) as i64
        })
        .collect();
    Tensor::from_data(TensorData::new(indices, [paths]), device)
}
