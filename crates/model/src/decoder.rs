//! From image tokens to one feature vector per path.

use burn::module::{Module, Param};
use burn::nn::attention::{MhaInput, MultiHeadAttention, MultiHeadAttentionConfig};
use burn::nn::transformer::{
    PositionWiseFeedForward, PositionWiseFeedForwardConfig, TransformerEncoder, TransformerEncoderConfig,
    TransformerEncoderInput,
};
use burn::nn::{Initializer, LayerNorm, LayerNormConfig, Linear, LinearConfig};
use burn::tensor::{Device, Tensor};

use crate::config::ModelConfig;

/// Learnable path queries that read the image: a cross-attention block (queries attend to the
/// image tokens, `softmax(W_Q T_l (W_K T_f)ᵀ / √d) W_V T_f`, then a GELU MLP, both pre-norm with
/// residuals), then one self-attention block among the queries (pre-norm, GELU MLP), then a
/// LayerNorm. One query per path; the query width is `query_dim`.
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
        let [batch, _, _] = tokens.dims();
        let [paths, dim] = self.queries.dims();
        let memory = self.memory_norm.forward(self.memory.forward(tokens));
        let queries = self.queries.val().unsqueeze::<3>().expand([batch, paths, dim]);
        let attended = self
            .cross_attention
            .forward(MhaInput::new(self.query_norm.forward(queries.clone()), memory.clone(), memory))
            .context;
        let x = queries + attended;
        let x = x.clone() + self.mlp.forward(self.mlp_norm.forward(x));
        let x = self.self_attention.forward(TransformerEncoderInput::new(x));
        self.norm.forward(x)
    }
}
