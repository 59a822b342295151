//! Where a path budget goes at inference: measured for a pair of models, stored with them.

use serde::de::IgnoredAny;
use serde::{Deserialize, Serialize};

use crate::config::InvalidSetting;

/// How inference splits a path budget between superpixel regions, the coarse model's paths and
/// the refinement model's paths. Which split draws best depends
/// on how well each model draws, so it is found by measurement (`tune`) and stored in the
/// coarse checkpoint.
///
/// With a budget of N paths, one path is the background, every region gets one fallback path
/// (its outline in its mean colour), and `refine_share` · N paths are kept for E_r. Inference
/// fills the rest with regions and lets E_c buy at most `coarse_share` · N paths with regions,
/// each only where it draws better than the region it replaces (`infer::coarse::Trade`): the
/// regions start at [`OperatingPoint::filling_regions`], N − ⌊N·refine_share⌋ − 1.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(from = "Stored")]
pub struct OperatingPoint {
    /// Share of the budget E_c's paths may take, in [0, 1) (0: E_c is not run).
    pub coarse_share: f32,
    /// Share of the budget kept for E_r, in [0, 1) (0: no refinement).
    pub refine_share: f32,
}

impl Default for OperatingPoint {
    /// For models nothing was measured for: every path a region of its own, the drawing that
    /// does not depend on how well the models draw.
    fn default() -> Self {
        Self { coarse_share: 0.0, refine_share: 0.0 }
    }
}

/// An operating point as checkpoints store it. Those written before every drawing's regions
/// were made one way (`superpixel::SegmentOptions::ward`) also say how to make them
/// (`oversegment`, `min_compactness`): read, and no longer used. Any other key is refused.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Stored {
    coarse_share: f32,
    refine_share: f32,
    #[serde(default, rename = "oversegment")]
    _oversegment: Option<IgnoredAny>,
    #[serde(default, rename = "min_compactness")]
    _min_compactness: Option<IgnoredAny>,
}

impl From<Stored> for OperatingPoint {
    fn from(stored: Stored) -> Self {
        Self { coarse_share: stored.coarse_share, refine_share: stored.refine_share }
    }
}

impl OperatingPoint {
    /// Checks the values; the message names the field.
    pub fn validate(&self) -> Result<(), InvalidSetting> {
        let invalid = |message: String| Err(InvalidSetting(message));
        if !(0.0..1.0).contains(&self.coarse_share) {
            return invalid(format!("coarse_share must be within [0, 1), got {}", self.coarse_share));
        }
        if !(0.0..1.0).contains(&self.refine_share) {
            return invalid(format!("refine_share must be within [0, 1), got {}", self.refine_share));
        }
        if self.coarse_share + self.refine_share >= 1.0 {
            return invalid(format!(
                "coarse_share + refine_share must leave paths for the regions, got {} + {}",
                self.coarse_share, self.refine_share
            ));
        }
        Ok(())
    }

    /// Number of regions for a budget of `paths` when they fill it beside E_r's share and E_c
    /// buys its paths from them (`infer::coarse::Trade`): N − ⌊N·refine_share⌋ − 1, at least
    /// one.
    pub fn filling_regions(&self, paths: usize) -> usize {
        paths.saturating_sub(self.reserved_for_refine(paths) + 1).max(1)
    }

    /// The most E_c paths for a budget of `paths`.
    pub fn coarse_paths(&self, paths: usize) -> usize {
        (paths as f64 * self.coarse_share as f64).floor() as usize
    }

    /// The paths kept for E_r out of a budget of `paths`.
    pub fn reserved_for_refine(&self, paths: usize) -> usize {
        (paths as f64 * self.refine_share as f64).floor() as usize
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regions_leave_room_for_every_stage() {
        let mosaic = OperatingPoint::default();
        assert_eq!(mosaic.filling_regions(500), 499);
        let split = OperatingPoint { coarse_share: 0.1, refine_share: 0.2 };
        // 1 + 399 + 100 = 500; E_c's 50 are bought from the 399.
        assert_eq!(split.filling_regions(500), 399);
        assert_eq!((split.coarse_paths(500), split.reserved_for_refine(500)), (50, 100));
        assert_eq!(split.filling_regions(2), 1);
        assert!(OperatingPoint { refine_share: 1.0, ..mosaic }.validate().is_err());
        assert!(OperatingPoint { coarse_share: -0.1, ..mosaic }.validate().is_err());
        assert!(OperatingPoint { coarse_share: 0.5, refine_share: 0.5, ..mosaic }.validate().is_err());
    }

    #[test]
    fn points_stored_with_how_regions_were_once_made_still_read() {
        let old = r#"{"coarse_share":0.2,"refine_share":0.0,"oversegment":3.0,"min_compactness":0.3}"#;
        let point: OperatingPoint = serde_json::from_str(old).unwrap();
        assert_eq!(point, OperatingPoint { coarse_share: 0.2, refine_share: 0.0 });
        let written = serde_json::to_string(&point).unwrap();
        assert_eq!(written, r#"{"coarse_share":0.2,"refine_share":0.0}"#);
        assert_eq!(serde_json::from_str::<OperatingPoint>(&written).unwrap(), point);
        let typo = r#"{"coarse_share":0.2,"refine_shares":0.0}"#;
        assert!(serde_json::from_str::<OperatingPoint>(typo).is_err(), "unknown keys are refused");
    }
}
