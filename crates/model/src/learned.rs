//! The learned optimizer (E_o): the network that takes SuperSVG-F's first steps. At each step it
//! reads, for every point of every drawn outline, what the mover reads (the target's and the
//! canvas's colours across the outline: [`profile`]) and what an optimizer reads (the error's
//! gradient along the point's normal, normalized as Adam normalizes it, its running mean, the
//! point's last move, and the same of its neighbours on the outline), and moves the point along
//! its normal. All points go through it in one batched pass.
//!
//! Its first two layers read the profile alone and have the mover's shape, so a run can start
//! from the mover's weights (what one pass already knows of edges); the rest reads their
//! output beside the optimizer's state.
//!
//! [`profile`]: crate::profile

use burn::module::{Module, Param};
use burn::nn::{Initializer, Linear, LinearConfig, Relu};
use burn::tensor::{Device, Tensor, TensorData};

use crate::mover::{MOVER_HIDDEN, Mover, PROFILE_LEN};

/// What E_o reads of a point's optimization besides its profile: its normalized gradient and
/// that gradient's running mean, its last move (pixels), the fraction of E_o's steps taken,
/// and the normalized gradient and last move of the point before and after it on its outline.
pub const STATE_LEN: usize = 8;
/// Values E_o reads a point: its profile, then its state.
pub const STEP_FEATURES: usize = PROFILE_LEN + STATE_LEN;
/// Units of E_o's hidden layers after the profile's.
pub const STEP_HIDDEN: usize = 32;
/// The farthest the network's own part of a step moves a point, in pixels.
pub const MAX_STEP: f32 = 1.0;
/// The pixels a point moves per unit of its gradient's running mean (Adam's direction, its
/// normalized sign) where E_o starts: none. A fixed step along Adam's direction throws a
/// drawing B left close to its image (flat art) far off, by many times its error; training
/// learns the length.
pub const BASE_STEP: f32 = 0.0;
/// Where the running mean of a point's normalized gradient lies in its state.
const MEAN_GRADIENT: usize = PROFILE_LEN + 1;
/// The stage E_o's file names.
pub const OPTIMIZER_STAGE: &str = "optimize";

/// E_o: a step along Adam's direction (the running mean of the point's normalized gradient,
/// times a learned length that starts at [`BASE_STEP`]), plus what the network adds: the
/// profile through two layers of the mover's shape, then with the point's state through two
/// more, to at most [`MAX_STEP`] pixels along the normal.
#[derive(Module, Debug)]
pub struct LearnedOptimizer {
    base: Param<Tensor<1>>,
    first: Linear,
    second: Linear,
    third: Linear,
    fourth: Linear,
    out: Linear,
    relu: Relu,
}

impl LearnedOptimizer {
    /// E_o with burn's initial weights.
    pub fn new(device: &Device) -> Self {
        Self {
            base: Param::from_tensor(Tensor::from_data(TensorData::new(vec![BASE_STEP], [1]), device)),
            first: LinearConfig::new(PROFILE_LEN, MOVER_HIDDEN).init(device),
            second: LinearConfig::new(MOVER_HIDDEN, MOVER_HIDDEN).init(device),
            third: LinearConfig::new(MOVER_HIDDEN + STATE_LEN, STEP_HIDDEN).init(device),
            fourth: LinearConfig::new(STEP_HIDDEN, STEP_HIDDEN).init(device),
            out: LinearConfig::new(STEP_HIDDEN, 1).init(device),
            relu: Relu::new(),
        }
    }

    /// E_o whose profile layers are `mover`'s first two: a run that starts from what the mover
    /// learned of edges.
    pub fn from_mover(mover: &Mover, device: &Device) -> Self {
        let (first, second) = mover.profile_layers();
        Self { first, second, ..Self::new(device) }
    }

    /// `[N, STEP_FEATURES]` features to `[N]` moves in pixels.
    pub fn forward(&self, features: Tensor<2>) -> Tensor<1> {
        let [rows, _] = features.dims();
        let profile = features.clone().slice([0..rows, 0..PROFILE_LEN]);
        let state = features.clone().slice([0..rows, PROFILE_LEN..STEP_FEATURES]);
        let mean = features.slice([0..rows, MEAN_GRADIENT..MEAN_GRADIENT + 1]).flatten(0, 1);
        let edges = self.relu.forward(self.first.forward(profile));
        let edges = self.relu.forward(self.second.forward(edges));
        let hidden = self.relu.forward(self.third.forward(Tensor::cat(vec![edges, state], 1)));
        let hidden = self.relu.forward(self.fourth.forward(hidden));
        let own = self.out.forward(hidden).flatten(0, 1).tanh().mul_scalar(MAX_STEP);
        own - mean * self.base.val()
    }

    /// The moves of `features` (row-major, [`STEP_FEATURES`] values a point) in pixels: what
    /// inference applies.
    ///
    /// # Panics
    /// If `features` is not a whole number of rows.
    pub fn moves(&self, features: Vec<f32>, device: &Device) -> Vec<f32> {
        assert!(features.len().is_multiple_of(STEP_FEATURES), "whole rows, {STEP_FEATURES} values each");
        let rows = features.len() / STEP_FEATURES;
        if rows == 0 {
            return Vec::new();
        }
        let input = Tensor::from_data(TensorData::new(features, [rows, STEP_FEATURES]), device);
        self.forward(input).into_data().try_into_vec().expect("moves are f32")
    }

    /// E_o whose own part is silent (its last layer's weights zero): what it moves is Adam's
    /// direction alone (where training starts).
    pub fn silenced(self) -> Self {
        let device = self.out.weight.device();
        let out = LinearConfig::new(STEP_HIDDEN, 1).with_initializer(Initializer::Zeros).init(&device);
        Self { out, ..self }
    }

    /// E_o that moves nothing, whatever it reads: its own part silent and Adam's direction of
    /// no length (what tests hold a step to).
    pub fn still(self) -> Self {
        let device = self.out.weight.device();
        let base = Param::from_tensor(Tensor::zeros([1], &device));
        Self { base, ..self.silenced() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A step is Adam's direction plus the network's own part, which stays within its reach;
    /// a still E_o moves nothing; one made from the mover reads profiles as the mover's first
    /// layers do.
    #[test]
    fn moves_are_bounded_and_a_still_optimizer_moves_nothing() {
        let device = Device::flex();
        let features: Vec<f32> = (0..3 * STEP_FEATURES).map(|i| (i as f32 * 0.37).sin() * 1000.0).collect();
        let moves = LearnedOptimizer::new(&device).silenced().moves(features.clone(), &device);
        assert_eq!(moves.len(), 3);
        // Silenced, it steps along Adam's direction, BASE_STEP pixels a unit of it.
        for (row, moved) in features.chunks(STEP_FEATURES).zip(&moves) {
            assert!(
                (moved + BASE_STEP * row[MEAN_GRADIENT]).abs() < 1e-3 * row[MEAN_GRADIENT].abs().max(1.0)
            );
        }
        let longer = LearnedOptimizer {
            base: Param::from_tensor(Tensor::from_data(TensorData::new(vec![0.5f32], [1]), &device)),
            ..LearnedOptimizer::new(&device).silenced()
        };
        for (row, moved) in features.chunks(STEP_FEATURES).zip(longer.moves(features.clone(), &device)) {
            assert!((moved + 0.5 * row[MEAN_GRADIENT]).abs() < 1e-3 * row[MEAN_GRADIENT].abs().max(1.0));
        }
        let moves = LearnedOptimizer::new(&device).moves(features.clone(), &device);
        assert!(
            moves
                .iter()
                .zip(features.chunks(STEP_FEATURES))
                .all(|(m, row)| (m + BASE_STEP * row[MEAN_GRADIENT]).abs() <= MAX_STEP + 1e-3),
            "{moves:?}"
        );
        assert!(LearnedOptimizer::new(&device).still().moves(features, &device).iter().all(|&m| m == 0.0));
        let mover = Mover::new(&device);
        let learned = LearnedOptimizer::from_mover(&mover, &device);
        let (first, _) = mover.profile_layers();
        assert_eq!(learned.first.weight.val().into_data(), first.weight.val().into_data());
    }
}
