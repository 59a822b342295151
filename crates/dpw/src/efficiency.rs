//! Visibility and the path-efficiency loss.

use burn::tensor::Tensor;
use burn::tensor::activation::sigmoid;

/// The visibility β of each path from its probability `p = σ(z)` (`[B, P, 1]`).
///
/// Forward: `β = step(p − 0.5)`, exactly 0 or 1. Backward: the straight-through surrogate
/// `∂β/∂p = σ(s)(1 − σ(s))` with `s = p − 0.5` (the paper's approximation of the sign
/// function's derivative), written `β = step + (σ(s) − σ(s).detach())` so the forward value is
/// the step to the bit.
pub fn visibility(probability: Tensor<3>) -> Tensor<3> {
    let shifted = probability - 0.5;
    let hard = shifted.clone().detach().greater_equal_elem(0.0).float();
    let soft = sigmoid(shifted);
    hard + (soft.clone() - soft.detach())
}

/// `L_PE = Σ_i β_i`: the number of visible paths per sample, averaged over the batch.
///
/// `visibility` is `[B, P, 1]`, as returned by [`visibility`]; the gradient reaching each β is 1,
/// which the surrogate turns into a push of every probability towards invisible.
pub fn path_efficiency_loss(visibility: Tensor<3>) -> Tensor<1> {
    let [batch, _, _] = visibility.dims();
    visibility.sum() / batch as f32
}

#[cfg(test)]
mod tests {
    use burn::tensor::{Device, TensorData};

    use super::*;

    #[test]
    fn counts_visible_paths_exactly_with_the_sigmoid_surrogate_gradient() {
        let device = Device::flex().autodiff();
        let probabilities = [0.1f32, 0.5, 0.49, 0.93, 0.7, 0.2];
        let p = Tensor::<3>::from_data(TensorData::new(probabilities.to_vec(), [2, 3, 1]), &device)
            .require_grad();
        let beta = visibility(p.clone());
        let values: Vec<f32> = beta.clone().try_to_vec_as().unwrap();
        assert_eq!(values, [0.0, 1.0, 0.0, 1.0, 1.0, 0.0]);

        let loss = path_efficiency_loss(beta);
        assert_eq!(loss.clone().into_scalar::<f32>(), 1.5);
        let grad: Vec<f32> = p.grad(&loss.backward()).unwrap().try_to_vec_as().unwrap();
        for (g, p) in grad.iter().zip(probabilities) {
            let s = 1.0 / (1.0 + (-(p - 0.5f32)).exp());
            let expected = s * (1.0 - s) / 2.0; // mean over a batch of 2
            assert!((g - expected).abs() < 1e-6, "{g} vs {expected}");
        }
    }
}
