//! The transformer blocks of the ViT and the path decoder (burn's modules, pre-norm), run with
//! a GELU that costs what a matrix product costs when inference runs on the CPU.
//!
//! burn-flex computes GELU through a scalar `erf` call per value: at inference on 2 cores it was
//! a fifth of E_c's time, as much as half its matrix products. On a flex device that records no
//! gradients, [`gelu`] computes it here in a loop the compiler vectorizes (a rational `erf`
//! within 5e-7 of the exact one); while training (autodiff) or on another backend, the blocks run
//! exactly as burn defines them.

use burn::nn::attention::MhaInput;
use burn::nn::transformer::{
    PositionWiseFeedForward, TransformerEncoder, TransformerEncoderInput, TransformerEncoderLayer,
};
use burn::tensor::{Device, Tensor, TensorData};

/// Whether `x` goes through burn's own blocks: it records gradients, or is not on flex.
fn burns_own<const D: usize>(x: &Tensor<D>) -> bool {
    x.is_autodiff() || x.device() != Device::flex()
}

/// `[B, N, d]` through `encoder`'s layers (pre-norm, no masks): burn's
/// `TransformerEncoder::forward`, with [`gelu`] in the MLPs.
pub(crate) fn encode(encoder: &TransformerEncoder, x: Tensor<3>) -> Tensor<3> {
    if burns_own(&x) {
        return encoder.forward(TransformerEncoderInput::new(x));
    }
    encoder.layers.iter().fold(x, layer)
}

/// One pre-norm layer: attention, then the MLP, each over a LayerNorm and added back (dropout
/// is the identity outside training).
fn layer(x: Tensor<3>, layer: &TransformerEncoderLayer) -> Tensor<3> {
    assert!(layer.norm_first, "the models' blocks are pre-norm");
    let attended = layer.mha.forward(MhaInput::self_attn(layer.norm_2.forward(x.clone()))).context;
    let x = x + attended;
    x.clone() + mlp(&layer.pwff, layer.norm_1.forward(x))
}

/// `[B, N, d]` through a position-wise MLP: `linear_outer(gelu(linear_inner(x)))`, burn's
/// `PositionWiseFeedForward::forward` (whose activation is GELU) with [`gelu`].
pub(crate) fn mlp(pwff: &PositionWiseFeedForward, x: Tensor<3>) -> Tensor<3> {
    if burns_own(&x) {
        return pwff.forward(x);
    }
    pwff.linear_outer.forward(gelu(pwff.linear_inner.forward(x)))
}

/// GELU, `x·Φ(x) = ½x(1 + erf(x/√2))`, computed on the host (see the module).
fn gelu(x: Tensor<3>) -> Tensor<3> {
    let (shape, device) = (x.shape(), x.device());
    let mut values: Vec<f32> = x.into_data().try_into_vec().expect("float activations are f32");
    for value in &mut values {
        *value *= 0.5 * (1.0 + erf(*value * std::f32::consts::FRAC_1_SQRT_2));
    }
    Tensor::from_data(TensorData::new(values, shape), &device)
}

/// The error function within 5e-7 (a few units in the last place) for every f32: a rational approximation on [−4, 4] (Eigen's,
/// as TensorFlow computes it), ±1 beyond, where erf is 1 to f32 precision. No branches, so
/// loops over it vectorize.
fn erf(x: f32) -> f32 {
    let x = x.clamp(-4.0, 4.0);
    let x2 = x * x;
    let mut p = -2.726_142_3e-10_f32;
    for c in
        [2.770_681_4e-8, -2.101_024_1e-6, -5.692_506_4e-5, -7.349_906_3e-4, -2.954_600_1e-3, -1.609_603_3e-2]
    {
        p = p * x2 + c;
    }
    let mut q = -1.456_607_2e-5_f32;
    for c in [-2.133_740_6e-4, -1.682_827e-3, -7.373_329_3e-3, -1.426_474e-2] {
        q = q * x2 + c;
    }
    x * p / q
}

#[cfg(test)]
mod tests {
    use burn::nn::transformer::TransformerEncoderConfig;
    use burn::tensor::Distribution;

    use super::*;

    #[test]
    fn erf_is_the_exact_one_to_f32_precision() {
        for i in -6000..=6000 {
            let x = i as f32 / 1000.0;
            let exact = libm_erf(x as f64);
            assert!((erf(x) as f64 - exact).abs() < 5e-7, "erf({x}) = {} against {exact}", erf(x));
        }
    }

    /// erf in f64 by its Taylor series (|x| ≤ 3) or its continued fraction for erfc (beyond).
    fn libm_erf(x: f64) -> f64 {
        if x.abs() <= 3.0 {
            let (mut term, mut sum, mut n) = (x, x, 0.0);
            while term.abs() > 1e-17 {
                n += 1.0;
                term *= -x * x / n;
                sum += term / (2.0 * n + 1.0);
            }
            sum * 2.0 / std::f64::consts::PI.sqrt()
        } else {
            let z = x.abs();
            let mut fraction = 0.0;
            for k in (1..60).rev() {
                fraction = (k as f64 / 2.0) / (z + fraction);
            }
            let erfc = (-z * z).exp() / std::f64::consts::PI.sqrt() / (z + fraction);
            (1.0 - erfc) * x.signum()
        }
    }

    #[test]
    fn the_blocks_compute_what_burns_compute() {
        let device = Device::flex();
        let encoder = TransformerEncoderConfig::new(48, 192, 3, 2)
            .with_dropout(0.0)
            .with_norm_first(true)
            .init(&device);
        let x = Tensor::<3>::random([3, 17, 48], Distribution::Normal(0.0, 1.5), &device);
        let ours = encode(&encoder, x.clone());
        let burns = encoder.forward(TransformerEncoderInput::new(x));
        let difference: f32 = (ours - burns).abs().max().into_scalar();
        assert!(difference < 1e-5, "{difference}");
    }
}
