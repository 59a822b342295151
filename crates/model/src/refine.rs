//! E_r: the target and the current canvas to m more paths.

use burn::module::{Module, Param};
use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::nn::{Linear, LinearConfig, PaddingConfig2d, Relu};
use burn::tensor::activation::sigmoid;
use burn::tensor::{Device, Tensor};
use raster::{PARAMS_OPAQUE, PathBatch};

use crate::coarse::CoarseModel;
use crate::config::ModelConfig;
use crate::config::RefineAnchor;
use crate::decoder::PathDecoder;
use crate::prior::{error_anchors, grid_prior, small_head};
use crate::vit::VitEncoder;

/// The refinement model: three 3×3 convolutions fuse (target, canvas) into a 3-channel image of
/// the input size (ReLU between them; the last is linear so the fused image is signed like the
/// coarse model's −1-filled input), then the same ViT and decoder as E_c, then a linear head to
/// `refine_paths` paths of 27 parameters through a sigmoid, its logits added to where the paths
/// start (`model.refine_anchor`): the learned [`grid_prior`] offsets, or squares where the
/// canvas errs most ([`error_anchors`]) plus learned offsets from zero. Refinement paths are
/// always visible.
#[derive(Module, Debug)]
pub struct RefineModel {
    fusion: [Conv2d; 3],
    activation: Relu,
    encoder: VitEncoder,
    decoder: PathDecoder,
    head: Linear,
    prior: Param<Tensor<2>>,
    #[module(skip)]
    anchor: RefineAnchor,
}

impl RefineModel {
    /// A freshly initialized model of the given size.
    pub fn new(config: &ModelConfig, device: &Device) -> Self {
        let conv = |from: usize, to: usize| {
            Conv2dConfig::new([from, to], [3, 3]).with_padding(PaddingConfig2d::Same).init(device)
        };
        let hidden = config.fusion_channels;
        Self {
            fusion: [conv(6, hidden), conv(hidden, hidden), conv(hidden, 3)],
            activation: Relu::new(),
            encoder: VitEncoder::new(config, device),
            decoder: PathDecoder::new(config, config.refine_paths, device),
            head: LinearConfig::new(config.query_dim, PARAMS_OPAQUE)
                .with_initializer(small_head())
                .init(device),
            prior: match config.refine_anchor {
                RefineAnchor::Grid => grid_prior(config.refine_paths, PARAMS_OPAQUE, device),
                RefineAnchor::Errors => {
                    Param::from_tensor(Tensor::zeros([config.refine_paths, PARAMS_OPAQUE], device))
                }
            },
            anchor: config.refine_anchor,
        }
    }

    /// Replaces the ViT encoder's weights by a trained coarse model's (the method's
    /// initialization of E_r). Values are copied bit for bit; the parameters stay this model's
    /// own (its identities, its trainability), and the fusion, decoder and head are untouched.
    pub fn inherit_encoder(mut self, coarse: &CoarseModel) -> Self {
        self.encoder = self.encoder.load_record(coarse.encoder().clone().into_record());
        self
    }

    /// `[B, 3, S, S]` target crops and `[B, 3, S, S]` renders of the paths so far to `[B, m]`
    /// opaque paths in the crops' unit squares, to be painted over the canvas.
    pub fn forward(&self, targets: Tensor<4>, canvas: Tensor<4>) -> PathBatch {
        let [first, second, last] = &self.fusion;
        let start = match self.anchor {
            RefineAnchor::Grid => self.prior.val().unsqueeze(),
            RefineAnchor::Errors => {
                error_anchors(&targets, &canvas, self.refine_paths(), PARAMS_OPAQUE)
                    + self.prior.val().unsqueeze()
            }
        };
        let x = Tensor::cat(vec![targets, canvas], 1);
        let x = self.activation.forward(first.forward(x));
        let x = self.activation.forward(second.forward(x));
        let fused = last.forward(x);
        let features = self.decoder.forward(self.encoder.forward(fused));
        PathBatch::opaque(sigmoid(self.head.forward(features) + start))
    }

    /// Paths added per call (m).
    pub fn refine_paths(&self) -> usize {
        self.decoder.paths()
    }

    /// The ViT encoder.
    pub fn encoder(&self) -> &VitEncoder {
        &self.encoder
    }
}
