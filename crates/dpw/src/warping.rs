//! Dynamic Path Warping (DPW) and soft-DTW between path sequences.

use burn::tensor::Tensor;
use raster::{COORDS, PARAMS_OPAQUE, PathBatch};

use crate::scan::{BIG, affine_softmin_scan, shift_right, softmin};

/// Which path parameters the distance between two paths compares, and how much each counts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathDistance {
    /// Weight of the 24 control-point coordinates.
    pub coords: f32,
    /// Weight of the 3 colour channels.
    pub color: f32,
}

impl Default for PathDistance {
    /// Every parameter weighs the same, as in the reference implementation.
    fn default() -> Self {
        Self { coords: 1.0, color: 1.0 }
    }
}

impl PathDistance {
    /// `[B, P, 27]` features whose squared Euclidean distance is the weighted distance between
    /// paths: coordinates scaled by √coords, colours by √color (α is not compared).
    pub fn features(&self, paths: &PathBatch) -> Tensor<3> {
        let params = paths.shape_and_color();
        let coords = params.clone().narrow(2, 0, COORDS) * self.coords.sqrt();
        let color = params.narrow(2, COORDS, PARAMS_OPAQUE - COORDS) * self.color.sqrt();
        Tensor::cat(vec![coords, color], 2)
    }

    /// The `[B, m, n]` distances between every prediction and every target.
    pub fn between(&self, predictions: &PathBatch, targets: &PathBatch) -> Tensor<3> {
        pairwise_sq_distance(self.features(predictions), self.features(targets))
    }
}

/// Squared Euclidean distances `d[b, i, j] = ‖a[b, i] − b[b, j]‖²` of `[B, m, D]` and `[B, n, D]`.
pub fn pairwise_sq_distance(a: Tensor<3>, b: Tensor<3>) -> Tensor<3> {
    let difference = a.unsqueeze_dim::<4>(2) - b.unsqueeze_dim::<4>(1);
    difference.square().sum_dim(3).squeeze_dim(3)
}

/// Dynamic Path Warping of `[B, m, n]` distances between m predictions S' and n targets S; one
/// value per batch entry, `[B]`.
///
/// With i over predictions and j over targets, `P[0, j] = 0` for j = 0..n and every other initial
/// entry (`P[i, 0]` for i ≥ 1, `Q[i, 0]`, `Q[0, j]`) is +∞;
/// for i = 1..m, j = 1..n:
///
/// ```text
/// P[i, j] = d(i, j) + min^γ(Q[i−1, j], P[i−1, j])   prediction i matched to target j
/// Q[i, j] = min^γ(Q[i, j−1], P[i, j−1])             prediction i matched to a target before j
/// DPW     = min^γ(Q[m, n], P[m, n])
/// ```
///
/// with `min^γ(a, …) = −γ log Σ exp(−a/γ)` for γ > 0 and the hard minimum for γ = 0. This is the
/// paper's Algorithm 1 with its indices written consistently (its initialization puts the zero
/// row on the other index, which would make every cell infinite).
///
/// Admissible alignments (what the γ = 0 value minimizes over): every prediction is matched to
/// exactly one target; matches are monotone non-decreasing; targets may be skipped; consecutive
/// predictions may share a target. Unlike DTW, a prediction is never asked to match several
/// targets at once, so its optimum is one of the targets rather than their average.
///
/// Distances may be +∞ (a pair that must not match, e.g. padding of shorter target sequences);
/// values and gradients stay finite as long as each prediction can match some target in order.
///
/// Vectorized over the batch and the targets: each of the m rows costs one soft-min and a
/// ⌈log₂ n⌉-step prefix scan (`Q` is the exclusive prefix soft-min of the row of `P`), so the
/// graph has O(m log n) operations rather than m·n scalar ones.
pub fn dpw(distance: Tensor<3>, gamma: f32) -> Tensor<1> {
    let [batch, m, n] = distance.dims();
    let distance = distance.clamp_max(BIG);
    let device = distance.device();
    let mut p = Tensor::<2>::zeros([batch, n], &device);
    let mut q = Tensor::<2>::full([batch, n], BIG, &device);
    let zeros = Tensor::<2>::zeros([batch, n], &device);
    let mut prefix = p.clone();
    for i in 0..m {
        let row = distance.clone().narrow(1, i, 1).reshape([batch, n]);
        p = row + softmin(q, p, gamma);
        (_, prefix) = affine_softmin_scan(zeros.clone(), p.clone(), gamma);
        q = shift_right(prefix.clone(), 1, BIG);
    }
    // min^γ(Q[m, n], P[m, n]) is the inclusive prefix soft-min of the last row at n.
    prefix.narrow(1, n - 1, 1).reshape([batch])
}

/// Soft-DTW (Cuturi & Blondel, 2017) of `[B, m, n]` distances, `[B]`: every prediction and every
/// target is matched, `R[i, j] = d(i, j) + min^γ(R[i−1, j−1], R[i−1, j], R[i, j−1])`,
/// `R[0, 0] = 0`, other borders +∞, result `R[m, n]`.
///
/// Here for comparison with [`dpw`]: DTW must cover every target, so one prediction facing two
/// targets is pulled to their average.
///
/// Each row is one scan: `R[i, ·]` is the composition of the maps `x ↦ d(i, j) + min^γ(A_j, x)`
/// with `A_j = min^γ(R[i−1, j−1], R[i−1, j])`, applied to `R[i, 0] = +∞`.
pub fn soft_dtw(distance: Tensor<3>, gamma: f32) -> Tensor<1> {
    let [batch, m, n] = distance.dims();
    let distance = distance.clamp_max(BIG);
    let device = distance.device();
    let mut previous = Tensor::<2>::full([batch, n], BIG, &device);
    for i in 0..m {
        let corner = if i == 0 { 0.0 } else { BIG }; // R[i−1, 0]
        let diagonal = shift_right(previous.clone(), 1, corner);
        let above = softmin(diagonal, previous, gamma);
        let row = distance.clone().narrow(1, i, 1).reshape([batch, n]);
        let (offset, value) = affine_softmin_scan(row, above, gamma);
        previous = offset + value; // D_j + min^γ(E_j, R[i, 0] = +∞)
    }
    previous.narrow(1, n - 1, 1).reshape([batch])
}

#[cfg(test)]
mod tests {
    use burn::tensor::{Device, TensorData};
    use rand::{Rng, SeedableRng};

    use super::*;

    fn tensor3(values: Vec<f32>, dims: [usize; 3], device: &Device) -> Tensor<3> {
        Tensor::from_data(TensorData::new(values, dims), device)
    }

    /// Minimum over all admissible DPW alignments: non-decreasing maps predictions → targets.
    fn brute_force_dpw(d: &[f32], m: usize, n: usize) -> f32 {
        fn best(d: &[f32], n: usize, i: usize, from: usize, m: usize) -> f32 {
            if i == m {
                return 0.0;
            }
            (from..n).map(|j| d[i * n + j] + best(d, n, i + 1, j, m)).fold(f32::INFINITY, f32::min)
        }
        best(d, n, 0, 0, m)
    }

    #[test]
    fn hard_dpw_equals_brute_force_minimum() {
        let device = Device::flex();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for _ in 0..200 {
            let n = rng.random_range(1..=6);
            let m = rng.random_range(1..=4.min(n));
            let batch = 3;
            let values: Vec<f32> = (0..batch * m * n).map(|_| rng.random_range(0.0..5.0)).collect();
            let got: Vec<f32> =
                dpw(tensor3(values.clone(), [batch, m, n], &device), 0.0).try_to_vec_as().unwrap();
            for b in 0..batch {
                let expected = brute_force_dpw(&values[b * m * n..(b + 1) * m * n], m, n);
                assert!((got[b] - expected).abs() < 1e-4, "m={m} n={n}: {} vs {expected}", got[b]);
            }
        }
    }

    #[test]
    fn soft_dpw_converges_to_hard_as_gamma_shrinks() {
        let device = Device::flex();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        let values: Vec<f32> = (0..4 * 9).map(|_| rng.random_range(0.0..3.0)).collect();
        let d = tensor3(values, [1, 4, 9], &device);
        let hard: f32 = dpw(d.clone(), 0.0).into_scalar();
        let mut last_gap = f32::INFINITY;
        for gamma in [1.0, 0.1, 0.01, 0.001] {
            let soft: f32 = dpw(d.clone(), gamma).into_scalar();
            let gap = hard - soft; // soft-min lies below the min
            assert!(gap >= -1e-5 && gap <= last_gap, "γ={gamma}: gap {gap}");
            last_gap = gap;
        }
        assert!(last_gap < 0.02, "{last_gap}");
    }

    #[test]
    fn infinite_targets_are_skipped_without_nan() {
        let device = Device::flex().autodiff();
        let inf = f32::INFINITY;
        let values = vec![1.0, inf, 3.0, inf, 2.0, 0.5, inf, inf];
        let d = tensor3(values, [1, 2, 4], &device).require_grad();
        let value = dpw(d.clone(), 0.01);
        let got: f32 = value.clone().into_scalar();
        assert!((got - 1.5).abs() < 0.02, "{got}");
        let grad: Vec<f32> = d.grad(&value.backward()).unwrap().try_to_vec_as().unwrap();
        assert!(grad.iter().all(|g| g.is_finite()), "{grad:?}");
        assert!(grad[0] > 0.9 && grad[5] > 0.9, "{grad:?}");
    }

    #[test]
    fn soft_dtw_equals_recurrence() {
        let device = Device::flex();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let (m, n, gamma) = (3, 5, 0.5f32);
        let values: Vec<f32> = (0..m * n).map(|_| rng.random_range(0.0..2.0)).collect();
        let got: f32 = soft_dtw(tensor3(values.clone(), [1, m, n], &device), gamma).into_scalar();
        let softmin3 = |xs: [f64; 3]| {
            let lo = xs.iter().copied().fold(f64::INFINITY, f64::min);
            lo - gamma as f64 * xs.iter().map(|x| (-(x - lo) / gamma as f64).exp()).sum::<f64>().ln()
        };
        let mut r = vec![vec![f64::INFINITY; n + 1]; m + 1];
        r[0][0] = 0.0;
        for i in 1..=m {
            for j in 1..=n {
                r[i][j] = values[(i - 1) * n + j - 1] as f64
                    + softmin3([r[i - 1][j - 1], r[i - 1][j], r[i][j - 1]]);
            }
        }
        assert!((got as f64 - r[m][n]).abs() < 1e-4, "{got} vs {}", r[m][n]);
    }

    #[test]
    fn gradient_matches_finite_differences() {
        let device = Device::flex().autodiff();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(6);
        let (batch, m, n, dim) = (2, 3, 5, 4);
        let pred: Vec<f32> = (0..batch * m * dim).map(|_| rng.random()).collect();
        let target = tensor3((0..batch * n * dim).map(|_| rng.random()).collect(), [batch, n, dim], &device);
        let loss = |p: Tensor<3>| dpw(pairwise_sq_distance(p, target.clone()), 0.1).sum();
        let p = tensor3(pred.clone(), [batch, m, dim], &device).require_grad();
        let analytic: Vec<f32> = p.grad(&loss(p.clone()).backward()).unwrap().try_to_vec_as().unwrap();
        let h = 1e-2;
        for index in 0..pred.len() {
            let shifted = |delta: f32| {
                let mut v = pred.clone();
                v[index] += delta;
                loss(tensor3(v, [batch, m, dim], &device)).into_scalar::<f32>()
            };
            let numeric = (shifted(h) - shifted(-h)) / (2.0 * h);
            assert!(
                (numeric - analytic[index]).abs() < 0.05 * analytic[index].abs().max(0.1),
                "param {index}: autodiff {}, finite differences {numeric}",
                analytic[index]
            );
        }
    }

    /// The paper's averaging example: one prediction facing two distinct targets. Gradient descent
    /// on DPW lands on a target; on soft-DTW it lands on their average.
    #[test]
    fn dpw_picks_a_target_where_dtw_averages() {
        let device = Device::flex().autodiff();
        let targets = tensor3(vec![0.0, 0.0, 1.0, 1.0], [1, 2, 2], &device);
        let descend = |loss: fn(Tensor<3>, f32) -> Tensor<1>| {
            let mut s = vec![0.3f32, 0.35];
            for _ in 0..200 {
                let p = tensor3(s.clone(), [1, 1, 2], &device).require_grad();
                let value = loss(pairwise_sq_distance(p.clone(), targets.clone()), 0.01);
                let grad: Vec<f32> = p.grad(&value.backward()).unwrap().try_to_vec_as().unwrap();
                for (v, g) in s.iter_mut().zip(grad) {
                    *v -= 0.1 * g;
                }
            }
            s
        };
        let with_dpw = descend(dpw);
        assert!(with_dpw.iter().all(|v| v.abs() < 1e-3), "DPW ended at {with_dpw:?}");
        let with_dtw = descend(soft_dtw);
        assert!(with_dtw.iter().all(|v| (v - 0.5).abs() < 1e-3), "soft-DTW ended at {with_dtw:?}");
    }
}
