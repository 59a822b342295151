//! The size of both networks, with the paper's preset and a CPU-sized one, and how their
//! inputs are cut ([`InputSpec`]): what every checkpoint stores.

use serde::{Deserialize, Serialize};

/// Named starting points for [`ModelConfig`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    /// The paper's scale: ViT-S/16 at 224 (embed 384, depth 12, 6 heads), 128 paths, queries of
    /// width 128 with 8 heads. For a GPU.
    Paper,
    /// A small ViT (embed 192, depth 4, 3 heads, patch 8) at 64 px with 32 paths: trains at a
    /// useful speed on two CPU cores and keeps both checkpoints small.
    Cpu,
}

/// Where E_r's paths start before its head moves them (`model.refine_anchor`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RefineAnchor {
    /// Each path in its cell of a grid over the crop, offsets learned
    /// ([`crate::prior::grid_prior`]): where they start does not depend on the input.
    #[default]
    Grid,
    /// Each path as a small square where the canvas errs most against the target, no two on
    /// the same pixels ([`crate::error_squares`]), learned offsets starting at zero: E_r adds
    /// its paths where the error is largest from the first step, and learns their shapes.
    Errors,
}

/// Architecture of E_c and E_r (they share the encoder and the decoder's shape).
///
/// Read from TOML with unknown keys rejected. Plain serde rather than `burn::Config`, whose
/// derive cannot refuse unknown keys.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelConfig {
    /// Side of the square input crop in pixels.
    pub input_size: usize,
    /// Side of a ViT patch; `input_size` must be a multiple of it.
    pub patch_size: usize,
    /// Width of the ViT tokens.
    pub embed_dim: usize,
    /// Number of ViT blocks.
    pub depth: usize,
    /// Attention heads in the ViT.
    pub heads: usize,
    /// Hidden width of every MLP relative to its input width.
    pub mlp_ratio: usize,
    /// Paths predicted by the coarse model E_c (n).
    pub paths: usize,
    /// Paths added per call of the refinement model E_r (m).
    pub refine_paths: usize,
    /// Width of the learnable path queries and the decoder.
    pub query_dim: usize,
    /// Attention heads in the decoder's cross- and self-attention.
    pub query_heads: usize,
    /// Hidden channels of E_r's fusion convolutions.
    pub fusion_channels: usize,
    /// How regions are cut into inputs (padding, fill): part of the model, since a model only
    /// works on inputs made the way it was trained on.
    #[serde(default)]
    pub input: InputSpec,
    /// Where E_r's paths start (E_c does not read it); checkpoints from before it was a setting
    /// read as [`RefineAnchor::Grid`].
    #[serde(default)]
    pub refine_anchor: RefineAnchor,
}

impl ModelConfig {
    /// The configuration a preset names.
    pub fn preset(preset: Preset) -> Self {
        match preset {
            Preset::Paper => Self {
                input_size: 224,
                patch_size: 16,
                embed_dim: 384,
                depth: 12,
                heads: 6,
                mlp_ratio: 4,
                paths: 128,
                refine_paths: 8,
                query_dim: 128,
                query_heads: 8,
                fusion_channels: 32,
                input: InputSpec::default(),
                refine_anchor: RefineAnchor::Grid,
            },
            Preset::Cpu => Self {
                input_size: 64,
                patch_size: 8,
                embed_dim: 192,
                depth: 4,
                heads: 3,
                mlp_ratio: 4,
                paths: 32,
                refine_paths: 8,
                query_dim: 128,
                query_heads: 4,
                fusion_channels: 16,
                input: InputSpec::default(),
                refine_anchor: RefineAnchor::Grid,
            },
        }
    }

    /// Checks the sizes fit together; the message names the offending field.
    pub fn validate(&self) -> Result<(), InvalidSetting> {
        // Each size from 1 to a bound far above any network that trains on this hardware, so a
        // typo (`paths = 1000000`) is refused by name instead of filling memory.
        let sizes = [
            ("input_size", self.input_size, MAX_INPUT_SIZE),
            ("patch_size", self.patch_size, MAX_INPUT_SIZE),
            ("embed_dim", self.embed_dim, MAX_WIDTH),
            ("depth", self.depth, MAX_DEPTH),
            ("heads", self.heads, MAX_DEPTH),
            ("mlp_ratio", self.mlp_ratio, MAX_DEPTH),
            ("paths", self.paths, MAX_MODEL_PATHS),
            ("refine_paths", self.refine_paths, MAX_MODEL_PATHS),
            ("query_dim", self.query_dim, MAX_WIDTH),
            ("query_heads", self.query_heads, MAX_DEPTH),
            ("fusion_channels", self.fusion_channels, MAX_WIDTH),
        ];
        if let Some((name, _, max)) = sizes.iter().find(|(_, value, max)| !(1..=*max).contains(value)) {
            return Err(InvalidSetting(format!("model.{name} must be from 1 to {max}")));
        }
        self.input.validate()?;
        if self.input_size % self.patch_size != 0 {
            return Err(InvalidSetting(format!(
                "model.input_size ({}) must be a multiple of model.patch_size ({})",
                self.input_size, self.patch_size
            )));
        }
        if self.embed_dim % self.heads != 0 {
            return Err(InvalidSetting(format!(
                "model.embed_dim ({}) must be divisible by model.heads ({})",
                self.embed_dim, self.heads
            )));
        }
        if self.query_dim % self.query_heads != 0 {
            return Err(InvalidSetting(format!(
                "model.query_dim ({}) must be divisible by model.query_heads ({})",
                self.query_dim, self.query_heads
            )));
        }
        Ok(())
    }

    /// Whether a checkpoint of E_r made with `refine` works with an E_c made with `self`: the
    /// same networks and input contract; only E_r's own settings may differ.
    pub fn serves_refine(&self, refine: &ModelConfig) -> bool {
        *self == ModelConfig { refine_anchor: self.refine_anchor, ..refine.clone() }
    }

    /// Number of ViT tokens (patches), without the class token.
    pub fn tokens(&self) -> usize {
        (self.input_size / self.patch_size).pow(2)
    }
}

/// How region crops are cut, stored with the architecture in every checkpoint.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct InputSpec {
    /// Pixels added around the region's bounding box (clamped to the image), so paths along the
    /// region's edge have room to anti-alias.
    pub padding: u32,
    /// Value of every channel outside the region's mask, in the crop and in E_r's canvas (the
    /// reference uses −1 for colours in [0, 1]: distinct from any colour).
    pub fill: f32,
}

impl Default for InputSpec {
    /// What every model before this setting existed was trained with.
    fn default() -> Self {
        Self { padding: 2, fill: -1.0 }
    }
}

impl InputSpec {
    /// Checks the values; the message names the field.
    pub fn validate(&self) -> Result<(), InvalidSetting> {
        if !self.fill.is_finite() {
            return Err(InvalidSetting("model.input.fill must be a finite number".into()));
        }
        Ok(())
    }
}

/// The largest `model.input_size` (and `patch_size`): a crop side in pixels.
const MAX_INPUT_SIZE: usize = 1024;
/// The largest `model.embed_dim`, `query_dim` and `fusion_channels`.
const MAX_WIDTH: usize = 4096;
/// The largest `model.depth`, `heads`, `query_heads` and `mlp_ratio`.
const MAX_DEPTH: usize = 64;
/// The largest `model.paths` and `refine_paths`: paths a network draws in one crop.
const MAX_MODEL_PATHS: usize = 1024;

/// A setting out of its range, in a config file or a checkpoint; the message names the field.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct InvalidSetting(pub String);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_are_valid_and_sizes_are_checked() {
        for preset in [Preset::Paper, Preset::Cpu] {
            ModelConfig::preset(preset).validate().unwrap();
        }
        let bad = ModelConfig { input_size: 60, ..ModelConfig::preset(Preset::Cpu) };
        assert!(bad.validate().unwrap_err().0.contains("model.input_size"));
        let bad = ModelConfig { query_heads: 0, ..ModelConfig::preset(Preset::Cpu) };
        assert_eq!(bad.validate().unwrap_err().0, "model.query_heads must be from 1 to 64");
        let bad = ModelConfig { paths: 1_000_000, ..ModelConfig::preset(Preset::Cpu) };
        assert_eq!(bad.validate().unwrap_err().0, "model.paths must be from 1 to 1024");
        let bad = ModelConfig { input_size: 65536, patch_size: 16, ..ModelConfig::preset(Preset::Cpu) };
        assert_eq!(bad.validate().unwrap_err().0, "model.input_size must be from 1 to 1024");
    }
}
