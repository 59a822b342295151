//! Soft-min and the parallel prefix scan both sequence losses are built on.
//!
//! Infinity is represented by [`BIG`], a large finite value, so that `∞ − ∞` never appears and
//! neither values nor gradients can become NaN.

use burn::tensor::Tensor;

/// Stands for +∞ in the dynamic programs (an impossible alignment).
pub(crate) const BIG: f32 = 1e10;

/// `min^γ(a, b) = −γ log(e^{−a/γ} + e^{−b/γ})`, the hard minimum for γ = 0.
///
/// Computed as `m − γ log(e^{(m−a)/γ} + e^{(m−b)/γ})` with `m = min(a, b)` held constant, so both
/// exponents are ≤ 0 and the gradient is exactly the softmax weight of each argument, ties
/// included.
pub(crate) fn softmin<const D: usize>(a: Tensor<D>, b: Tensor<D>, gamma: f32) -> Tensor<D> {
    if gamma <= 0.0 {
        return a.min_pair(b);
    }
    let m = a.clone().min_pair(b.clone()).detach();
    let weight = |x: Tensor<D>| ((m.clone() - x) / gamma).exp();
    m.clone() - (weight(a) + weight(b)).log() * gamma
}

/// Inclusive prefix scan of the maps `f_j(x) = offset_j + min^γ(value_j, x)` along dimension 1 of
/// `[batch, n]` tensors: returns `(D_j, E_j)` with `f_j ∘ … ∘ f_1 (x) = D_j + min^γ(E_j, x)`.
///
/// The family is closed under composition, `(D, E) ∘ (D', E') = (D + D', min^γ(E − D', E'))`
/// (shift invariance and associativity of min^γ), so a Hillis–Steele scan needs ⌈log₂ n⌉
/// vectorized steps instead of n sequential ones. With `offset = 0` the result `E_j` is the
/// prefix soft-min of `value`.
pub(crate) fn affine_softmin_scan(offset: Tensor<2>, value: Tensor<2>, gamma: f32) -> (Tensor<2>, Tensor<2>) {
    let [_, n] = value.dims();
    let (mut offset, mut value) = (offset, value);
    let mut shift = 1;
    while shift < n {
        let earlier_offset = shift_right(offset.clone(), shift, 0.0);
        let earlier_value = shift_right(value.clone(), shift, BIG);
        value = softmin(value - earlier_offset.clone(), earlier_value, gamma);
        offset = offset + earlier_offset;
        shift *= 2;
    }
    (offset, value)
}

/// Shifts `[batch, n]` right by `shift` along dimension 1, filling the first columns with `fill`
/// (the identity map `x ↦ 0 + min^γ(BIG, x)` for the scan).
pub(crate) fn shift_right(tensor: Tensor<2>, shift: usize, fill: f32) -> Tensor<2> {
    let [batch, n] = tensor.dims();
    let head = Tensor::full([batch, shift.min(n)], fill, &tensor.device());
    if shift >= n {
        return head;
    }
    Tensor::cat(vec![head, tensor.narrow(1, 0, n - shift)], 1)
}

#[cfg(test)]
mod tests {
    use burn::tensor::{Device, TensorData};

    use super::*;

    fn row(values: &[f32]) -> Tensor<2> {
        Tensor::from_data(TensorData::new(values.to_vec(), [1, values.len()]), &Device::flex())
    }

    fn reference_softmin(values: &[f32], gamma: f32) -> f32 {
        let m = values.iter().copied().fold(f32::INFINITY, f32::min);
        m - gamma * values.iter().map(|v| (-(v - m) / gamma).exp()).sum::<f32>().ln()
    }

    #[test]
    fn softmin_matches_definition_and_survives_infinity() {
        let (a, b) = (row(&[1.0, 0.0, BIG, BIG]), row(&[2.0, 0.0, 3.0, BIG]));
        let got: Vec<f32> = softmin(a, b, 0.5).try_to_vec_as().unwrap();
        assert!((got[0] - reference_softmin(&[1.0, 2.0], 0.5)).abs() < 1e-6);
        assert!((got[1] - (-0.5 * 2f32.ln())).abs() < 1e-6);
        assert_eq!(got[2], 3.0);
        assert!(got[3].is_finite() && got[3] >= BIG * 0.99);
    }

    #[test]
    fn scan_gives_prefix_softmins_and_affine_compositions() {
        let values = [3.0, 1.0, 4.0, 1.5, 5.0, 0.2, 2.0];
        let gamma = 0.3;
        let (_, prefix) = affine_softmin_scan(row(&[0.0; 7]), row(&values), gamma);
        let prefix: Vec<f32> = prefix.try_to_vec_as().unwrap();
        for j in 0..values.len() {
            let expected = reference_softmin(&values[..=j], gamma);
            assert!((prefix[j] - expected).abs() < 1e-5, "prefix {j}: {} vs {expected}", prefix[j]);
        }

        // Apply the maps one after another from x0 and compare with D_j + min^γ(E_j, x0).
        let offsets = [0.5, 0.1, 0.7, 0.2, 0.0, 0.3, 0.9];
        let (d, e) = affine_softmin_scan(row(&offsets), row(&values), gamma);
        let (d, e): (Vec<f32>, Vec<f32>) = (d.try_to_vec_as().unwrap(), e.try_to_vec_as().unwrap());
        let x0 = 2.5;
        let mut x = x0;
        for j in 0..values.len() {
            x = offsets[j] + reference_softmin(&[values[j], x], gamma);
            let composed = d[j] + reference_softmin(&[e[j], x0], gamma);
            assert!((x - composed).abs() < 1e-4, "step {j}: {x} vs {composed}");
        }
    }
}
