//! What a job asks for ([`Job`]) and the one place it is checked ([`Job::validate`]), against
//! limits named here; why a job fails ([`VectorizeError`]) or does less than asked ([`Warning`]).
//!
//! Every front end (the `infer` program, `eval`, `tune`, Python) builds a [`Job`] and reports
//! [`InvalidJob`] in its own words; none checks a value itself.

use model::{CheckpointError, OperatingPoint};
use raster::{MAX_DECIMALS, SvgError, SvgOptions};
use serde::Serialize;
use superpixel::SlicError;

use crate::finetune::{FinetuneOptions, Limit};
use crate::segmentation::PIXELS_PER_REGION;

/// The fewest paths a job draws: the background and one region.
pub const MIN_PATHS: usize = 2;

/// The most paths a job draws: more than that is more regions than an image at the default
/// working size has of [`PIXELS_PER_REGION`].
pub const MAX_PATHS: usize = 20_000;

/// The largest [`Job::tolerance`] (pixels): past it, curves cut across whole regions.
pub const MAX_TOLERANCE: f32 = 8.0;

/// The longest SuperSVG-F by time (seconds).
pub const MAX_FINETUNE_SECS: f64 = 3600.0;

/// The most SuperSVG-F steps: about as long as [`MAX_FINETUNE_SECS`] at the default budget.
pub const MAX_FINETUNE_STEPS: usize = 100_000;

/// The most Adam steps a crop for [`Refiner::Optimizer`].
pub const MAX_OPTIMIZER_STEPS: usize = 10_000;

/// How many paths a job may draw.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PathBudget {
    /// At most this many ([`MIN_PATHS`] to [`MAX_PATHS`]); fewer only when no further path
    /// lowers the error.
    Count(usize),
    /// As many as the image needs, by this rule ([`crate::budget`]).
    Auto(AutoRule),
}

impl std::str::FromStr for PathBudget {
    type Err = BudgetParseError;

    /// `auto`, or a number of paths from [`MIN_PATHS`] to [`MAX_PATHS`] (what `--paths` takes).
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        match text.parse::<usize>() {
            _ if text == "auto" => Ok(PathBudget::Auto(AutoRule::default())),
            Ok(paths) if (MIN_PATHS..=MAX_PATHS).contains(&paths) => Ok(PathBudget::Count(paths)),
            _ => Err(BudgetParseError(text.to_string())),
        }
    }
}

impl std::fmt::Display for PathBudget {
    /// As it is written on the command line: `500`, `auto`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PathBudget::Count(paths) => write!(f, "{paths}"),
            PathBudget::Auto(_) => f.write_str("auto"),
        }
    }
}

/// Text that is no [`PathBudget`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0:?} is not a path budget: a number from {MIN_PATHS} to {MAX_PATHS}, or auto")]
pub struct BudgetParseError(pub String);

/// How [`PathBudget::Auto`] picks a budget for an image: the fewest paths that are close
/// enough to the image, or past which more paths stop paying. docs/method.md says how each
/// default was chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AutoRule {
    /// Close enough: the PSNR (dB) at which no more paths are added.
    pub target_psnr: f64,
    /// Paying: the gain (dB) per doubling of the paths that more paths must bring, on average
    /// over every larger budget measured.
    pub min_gain: f64,
    /// The most paths.
    pub max_paths: usize,
    /// Flat art (a picture whose regions filled flat reach `target_psnr` within `flat_paths`)
    /// has its regions drawn along shared boundary curves fitted within this many pixels
    /// ([`Job::tolerance`]) when the job names no tolerance: at the few tens of paths such a
    /// picture gets, curves take fewer bytes than traced polygons and draw its edges better.
    pub flat_tolerance: f32,
    /// The most paths at which a picture that reaches `target_psnr` counts as flat art: past a
    /// few tens of paths traced polygons draw more than curves at their size.
    pub flat_paths: usize,
}

impl Default for AutoRule {
    /// 30 dB, where flat art looks drawn rather than approximated; 0.25 dB a doubling, which
    /// keeps a textured photo climbing while flat colours stop at the first rung; at most 2000
    /// paths; curves within a pixel for flat art of up to 64 paths.
    fn default() -> Self {
        Self { target_psnr: 30.0, min_gain: 0.25, max_paths: 2000, flat_tolerance: 1.0, flat_paths: 64 }
    }
}

/// How a job's path budget is split between regions, E_c and E_r (`infer --operating-point`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Split {
    /// The operating point stored with the models ([`crate::Models::operating_point`]).
    #[default]
    Stored,
    /// This operating point.
    Point(OperatingPoint),
    /// The paper's inference ([`crate::paper`]): for models trained with the paper preset, to
    /// be set beside the paper's tables. A fixed budget only; no region count.
    Paper,
}

impl std::str::FromStr for Split {
    type Err = SplitParseError;

    /// `stored`, `paper`, or `COARSE,REFINE`: the shares of [`OperatingPoint`] (`0.2,0.1`).
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let invalid = |why: String| SplitParseError(text.to_string(), why);
        match text {
            "stored" => Ok(Split::Stored),
            "paper" => Ok(Split::Paper),
            _ => {
                let Some((coarse, refine)) = text.split_once(',') else {
                    return Err(invalid("not stored, paper or two shares".into()));
                };
                let share = |value: &str| value.trim().parse::<f32>().map_err(|e| invalid(e.to_string()));
                let point = OperatingPoint { coarse_share: share(coarse)?, refine_share: share(refine)? };
                point.validate().map_err(|e| invalid(e.0))?;
                Ok(Split::Point(point))
            }
        }
    }
}

impl Serialize for Split {
    /// An operating point as its shares; the others by name (`"stored"`, `"paper"`).
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        match self {
            Split::Stored => serializer.serialize_str("stored"),
            Split::Point(point) => point.serialize(serializer),
            Split::Paper => serializer.serialize_str("paper"),
        }
    }
}

/// Text that is no [`Split`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0:?} is not an operating point ({1}): stored, paper, or COARSE,REFINE shares such as 0.2,0")]
pub struct SplitParseError(pub String, pub String);

/// Who proposes the refinement stage's paths (`infer --refiner`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Refiner {
    /// E_r, the bundled or given refinement model (none with `--no-refine`).
    #[default]
    Network,
    /// The exact optimizer in E_r's place ([`model::PathOptimizer`]) with this many Adam steps a
    /// crop ([`MAX_OPTIMIZER_STEPS`] at most), E_r's paths a crop; E_r is not run, and the
    /// budget is split as for E_r. What gradient descent finds in E_r's role: a yardstick for
    /// a trained E_r.
    Optimizer {
        /// Adam steps a crop.
        steps: usize,
    },
}

/// Adam steps a crop for `--refiner optimizer` without a count (docs/training.md has the
/// sweep it was chosen from).
pub const OPTIMIZER_STEPS: usize = 300;

impl std::str::FromStr for Refiner {
    type Err = RefinerParseError;

    /// `network`, `optimizer` ([`OPTIMIZER_STEPS`]) or `optimizer:STEPS`.
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        match text {
            "network" => Ok(Refiner::Network),
            "optimizer" => Ok(Refiner::Optimizer { steps: OPTIMIZER_STEPS }),
            _ => match text.strip_prefix("optimizer:").map(str::parse::<usize>) {
                Some(Ok(steps)) if (1..=MAX_OPTIMIZER_STEPS).contains(&steps) => {
                    Ok(Refiner::Optimizer { steps })
                }
                _ => Err(RefinerParseError(text.to_string())),
            },
        }
    }
}

/// Text that is no [`Refiner`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error(
    "{0:?} is not a refiner: network, optimizer, or optimizer:STEPS with STEPS from 1 to {MAX_OPTIMIZER_STEPS}"
)]
pub struct RefinerParseError(pub String);

/// What regions are filled with (`infer --fills`; [`Job::fills`] says which by default).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fills {
    /// Every region in its mean colour.
    Flat,
    /// Every region whose pixels a linear ramp fits better, with that ramp.
    Linear,
    /// A ramp where it takes away more error than its bytes would as regions
    /// ([`crate::stages::Ramps::Paying`]).
    Auto,
}

impl std::str::FromStr for Fills {
    type Err = FillsParseError;

    /// `flat`, `linear` or `auto`.
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        match text {
            "flat" => Ok(Fills::Flat),
            "linear" => Ok(Fills::Linear),
            "auto" => Ok(Fills::Auto),
            _ => Err(FillsParseError(text.to_string())),
        }
    }
}

/// Text that is no [`Fills`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0:?} is not a fill: flat, linear or auto")]
pub struct FillsParseError(pub String);

/// Where the mover (E_m) moves what SuperSVG-B drew ([`crate::stages::move_outlines`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Moves {
    /// Where B fills regions with ramps: photos, unless the job asks for flat fills or for
    /// SuperSVG-F (which moves every outline itself). Flat art is left as B drew it.
    #[default]
    Auto,
    /// On every drawing.
    On,
    /// Never.
    Off,
}

impl std::str::FromStr for Moves {
    type Err = MovesParseError;

    /// `auto`, `on` or `off`.
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        match text {
            "auto" => Ok(Moves::Auto),
            "on" => Ok(Moves::On),
            "off" => Ok(Moves::Off),
            _ => Err(MovesParseError(text.to_string())),
        }
    }
}

/// Text that is no [`Moves`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0:?} is not a choice of moves: auto, on or off")]
pub struct MovesParseError(pub String);

/// Everything that decides how an image becomes an SVG.
#[derive(Clone, Debug)]
pub struct Job {
    /// How many paths.
    pub paths: PathBudget,
    /// Number of superpixels, below the path count (a fixed budget only). By default as many
    /// as the budget holds beside E_r's share, and E_c's and E_r's paths take the place of
    /// regions where they draw better than the regions would ([`crate::budget::Market`]); a
    /// given count is kept, and E_c and E_r draw only with what it leaves. Lowered to one per
    /// [`PIXELS_PER_REGION`] pixels, with a [`Warning`].
    pub regions: Option<usize>,
    /// How the budget is split; by default the operating point stored with the models.
    pub operating_point: Split,
    /// SuperSVG-F: fine-tune every shape against the image after B.
    pub finetune: Option<FinetuneOptions>,
    /// How the SVG is written (decimals, at most [`MAX_DECIMALS`]).
    pub svg: SvgOptions,
    /// SLIC compactness (the method's 30).
    pub compactness: f32,
    /// Regions drawn along shared boundaries fitted with curves, straying at most this far
    /// (pixels of the working image, at most [`MAX_TOLERANCE`]) from the traced ones: larger
    /// draws with fewer curves and bytes, 0 keeps every traced corner. `None` (the default):
    /// each region's traced polygon, grown under its later neighbours, which draws photos
    /// better at equal paths, but for flat art under an automatic budget
    /// ([`AutoRule::flat_tolerance`]).
    pub tolerance: Option<f32>,
    /// What the regions are filled with. `None` (the default): ramps where they pay
    /// ([`Fills::Auto`]), which draw better than flat fills at equal file size, but flat fills
    /// for flat art (a picture whose regions filled flat reach [`AutoRule::default`]'s target
    /// within its `flat_paths`), which ramps drew worse with curves and gained little without.
    /// Measured in docs/eval/fills.md. SuperSVG-F starts from the drawing B makes with the
    /// same fills, and optimizes its ramps with its outlines.
    pub fills: Option<Fills>,
    /// Crops per network call (at least 1).
    pub batch: usize,
    /// Who proposes the refinement stage's paths: E_r, or the exact optimizer in its place.
    pub refiner: Refiner,
    /// Whether the report measures the drawing's SSIM beside its PSNR ([`crate::Report::ssim`]): a
    /// pass over the whole image in five moments, so only a caller that reads it asks
    /// (`infer --metrics`).
    pub ssim: bool,
    /// Where the mover moves B's outlines; it runs only with [`crate::Models::mover`].
    pub moves: Moves,
}

impl Default for Job {
    fn default() -> Self {
        Self {
            paths: PathBudget::Count(500),
            regions: None,
            operating_point: Split::Stored,
            finetune: None,
            svg: SvgOptions::default(),
            compactness: 30.0,
            tolerance: None,
            fills: None,
            batch: 32,
            refiner: Refiner::Network,
            ssim: false,
            moves: Moves::Auto,
        }
    }
}

impl Job {
    /// What the regions of an image are filled with ([`Job::fills`]): the job's fills, else
    /// the default, asking `flat_art` whether the image is flat art only where that decides.
    pub fn fills_for<E>(&self, flat_art: impl FnOnce() -> Result<bool, E>) -> Result<Fills, E> {
        Ok(match self.fills {
            Some(fills) => fills,
            None if flat_art()? => Fills::Flat,
            None => Fills::Auto,
        })
    }

    /// Whether the mover may run in this job, on some image: it runs where B fills regions with
    /// ramps ([`Moves::Auto`]), or everywhere ([`Moves::On`]), but never at the paper's
    /// operating point. A job it cannot run in needs no mover loaded.
    pub fn may_move(&self) -> bool {
        let ramps = || self.fills_for(|| Ok::<_, ()>(false)) != Ok(Fills::Flat);
        self.operating_point != Split::Paper
            && match self.moves {
                Moves::Off => false,
                Moves::On => true,
                Moves::Auto => ramps(),
            }
    }

    /// Checks every value against its limit and the values against each other; the error
    /// names the field ([`InvalidJob::field`]). [`crate::run`] calls it first.
    pub fn validate(&self) -> Result<(), InvalidJob> {
        match (self.paths, self.regions) {
            (PathBudget::Count(paths), _) if !(MIN_PATHS..=MAX_PATHS).contains(&paths) => {
                return Err(InvalidJob::Budget(paths));
            }
            (PathBudget::Count(paths), Some(regions)) if regions == 0 || regions >= paths => {
                return Err(InvalidJob::Regions { regions, paths });
            }
            (PathBudget::Auto(_), Some(_)) => return Err(InvalidJob::RegionsWithAuto),
            (PathBudget::Auto(rule), None) if !(MIN_PATHS..=MAX_PATHS).contains(&rule.max_paths) => {
                return Err(InvalidJob::Budget(rule.max_paths));
            }
            _ => {}
        }
        if self.operating_point == Split::Paper {
            if self.regions.is_some() || matches!(self.paths, PathBudget::Auto(_)) {
                return Err(InvalidJob::PaperNeedsCount);
            }
            if self.refiner != Refiner::Network {
                return Err(InvalidJob::PaperWithRefiner);
            }
        }
        if let Split::Point(point) = self.operating_point {
            point.validate().map_err(|err| InvalidJob::OperatingPoint(err.0))?;
        }
        if let Some(tolerance) = self.tolerance.filter(|t| !(0.0..=MAX_TOLERANCE).contains(t)) {
            return Err(InvalidJob::Tolerance(tolerance));
        }
        if let Some(finetune) = &self.finetune {
            match finetune.limit {
                Limit::Seconds(seconds) if !(0.0..=MAX_FINETUNE_SECS).contains(&seconds) => {
                    return Err(InvalidJob::FinetuneSeconds(seconds));
                }
                Limit::Steps(steps) if steps > MAX_FINETUNE_STEPS => {
                    return Err(InvalidJob::FinetuneSteps(steps));
                }
                _ => {}
            }
            let rates = [finetune.lr_points, finetune.lr_outline_points, finetune.lr_colors];
            if let Some(&rate) = rates.iter().find(|rate| !(rate.is_finite() && **rate > 0.0)) {
                return Err(InvalidJob::LearningRate(rate));
            }
        }
        if let Refiner::Optimizer { steps } = self.refiner
            && !(1..=MAX_OPTIMIZER_STEPS).contains(&steps)
        {
            return Err(InvalidJob::OptimizerSteps(steps));
        }
        if self.svg.decimals > MAX_DECIMALS {
            return Err(InvalidJob::Decimals(self.svg.decimals));
        }
        if !(self.compactness.is_finite() && self.compactness > 0.0) {
            return Err(InvalidJob::Compactness(self.compactness));
        }
        if self.batch == 0 {
            return Err(InvalidJob::Batch);
        }
        Ok(())
    }
}

/// A [`Job`] that cannot be done as it stands: the value and the limit it breaks.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InvalidJob {
    /// The budget (or an automatic budget's ceiling) is outside [`MIN_PATHS`]..=[`MAX_PATHS`].
    #[error(
        "a budget of {0} paths is out of range: at least {MIN_PATHS} (the background and one region), at most {MAX_PATHS}"
    )]
    Budget(usize),
    /// No region, or more regions than the budget has paths for (each takes one, and so does
    /// the background).
    #[error(
        "{regions} regions do not fit a budget of {paths} paths (each region takes a path, and so does the background)"
    )]
    Regions {
        /// Regions asked for.
        regions: usize,
        /// The budget.
        paths: usize,
    },
    /// A region count was given with an automatic budget, which chooses its own.
    #[error("a number of regions needs a number of paths, not an automatic budget")]
    RegionsWithAuto,
    /// The paper's inference was asked for with an automatic budget or a region count: it
    /// cuts its own regions for a number of paths.
    #[error("the paper's operating point takes a number of paths and cuts its own regions")]
    PaperNeedsCount,
    /// The paper's inference runs E_r as the paper does, with no other refiner.
    #[error("the paper's operating point runs E_r as the paper does: it takes no other refiner")]
    PaperWithRefiner,
    /// An operating point whose shares leave no room for the regions.
    #[error("{0}")]
    OperatingPoint(String),
    /// A tolerance outside 0..=[`MAX_TOLERANCE`].
    #[error("{0} is not a tolerance in pixels from 0 to {MAX_TOLERANCE}")]
    Tolerance(f32),
    /// A fine-tuning time outside 0..=[`MAX_FINETUNE_SECS`], or not a number.
    #[error("{0} is not a number of seconds from 0 to {MAX_FINETUNE_SECS}")]
    FinetuneSeconds(f64),
    /// More fine-tuning steps than [`MAX_FINETUNE_STEPS`].
    #[error("{0} steps: at most {MAX_FINETUNE_STEPS}")]
    FinetuneSteps(usize),
    /// A fine-tuning learning rate that is not a positive number.
    #[error("{0} is not a learning rate: a positive number")]
    LearningRate(f32),
    /// Optimizer steps a crop outside 1..=[`MAX_OPTIMIZER_STEPS`].
    #[error("{0} optimizer steps a crop: from 1 to {MAX_OPTIMIZER_STEPS}")]
    OptimizerSteps(usize),
    /// More decimals than [`MAX_DECIMALS`].
    #[error("{0} decimals: at most {MAX_DECIMALS} (an f32 coordinate holds about 7 digits)")]
    Decimals(usize),
    /// A SLIC compactness that is not a positive number.
    #[error("{0} is not a compactness: a positive number")]
    Compactness(f32),
    /// No crop per network call.
    #[error("a batch of 0 crops: at least 1")]
    Batch,
}

impl InvalidJob {
    /// The [`Job`] field the error is about (`paths`, `regions`, `operating_point`,
    /// `refiner`, `tolerance`, `finetune`, `svg`, `compactness`, `batch`): what a front end
    /// names in its own words.
    pub fn field(&self) -> &'static str {
        match self {
            InvalidJob::Budget(_) => "paths",
            InvalidJob::Regions { .. } | InvalidJob::RegionsWithAuto => "regions",
            InvalidJob::PaperNeedsCount | InvalidJob::OperatingPoint(_) => "operating_point",
            InvalidJob::PaperWithRefiner | InvalidJob::OptimizerSteps(_) => "refiner",
            InvalidJob::Tolerance(_) => "tolerance",
            InvalidJob::FinetuneSeconds(_) | InvalidJob::FinetuneSteps(_) | InvalidJob::LearningRate(_) => {
                "finetune"
            }
            InvalidJob::Decimals(_) => "svg",
            InvalidJob::Compactness(_) => "compactness",
            InvalidJob::Batch => "batch",
        }
    }
}

/// Why an image could not be vectorized.
#[derive(Debug, thiserror::Error)]
pub enum VectorizeError {
    /// The job breaks a limit ([`Job::validate`]).
    #[error(transparent)]
    Invalid(#[from] InvalidJob),
    /// The image could not be segmented.
    #[error(transparent)]
    Segmentation(#[from] SlicError),
    /// The drawing could not be written as SVG.
    #[error(transparent)]
    Svg(#[from] SvgError),
    /// A network's weights could not be read when a stage first used them.
    #[error(transparent)]
    Model(#[from] CheckpointError),
}

/// Something a job did differently from what it was asked, said to the user.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum Warning {
    /// Fewer paths than the budget: the rest lowered nothing (a flat picture needs one).
    #[error("{drawn} of {budget} paths drawn: no other path the stages tried lowered the error")]
    FewerPaths {
        /// Paths drawn.
        drawn: usize,
        /// The budget.
        budget: usize,
    },
    /// More regions were asked for than the working image has room for.
    #[error(
        "{asked} regions lowered to {used} (one region per {PIXELS_PER_REGION} pixels of the {width}×{height} working image)"
    )]
    RegionsLowered {
        /// Asked for.
        asked: usize,
        /// Drawn.
        used: usize,
        /// Working width.
        width: u32,
        /// Working height.
        height: u32,
    },
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn budgets_read_and_write_as_on_the_command_line() {
        assert_eq!("500".parse::<PathBudget>(), Ok(PathBudget::Count(500)));
        assert_eq!("auto".parse::<PathBudget>(), Ok(PathBudget::Auto(AutoRule::default())));
        for bad in ["1", "20001", "-3", "Auto", ""] {
            assert_eq!(bad.parse::<PathBudget>(), Err(BudgetParseError(bad.to_string())), "{bad}");
        }
        for text in ["2", "20000", "auto"] {
            assert_eq!(text.parse::<PathBudget>().unwrap().to_string(), text);
        }
    }

    #[test]
    fn ramps_are_the_default_but_for_flat_art_with_or_without_fine_tuning_and_a_given_fill_is_kept() {
        let b = Job::default();
        let f = Job { finetune: Some(FinetuneOptions::default()), ..Job::default() };
        let art = |flat: bool| move || Ok::<_, ()>(flat);
        for job in [&b, &f] {
            assert_eq!(
                (job.fills_for(art(false)), job.fills_for(art(true))),
                (Ok(Fills::Auto), Ok(Fills::Flat))
            );
        }
        // Where the answer cannot change the fills, the image is not asked about.
        let unasked = || -> Result<bool, ()> { panic!("asked whether the image is flat art") };
        for fills in [Fills::Flat, Fills::Linear, Fills::Auto] {
            for job in [&b, &f] {
                assert_eq!(Job { fills: Some(fills), ..job.clone() }.fills_for(unasked), Ok(fills));
            }
        }
        assert_eq!(b.fills_for(|| Err("no tree")), Err("no tree"));
    }

    #[test]
    fn operating_points_read_as_on_the_command_line() {
        assert_eq!("stored".parse::<Split>(), Ok(Split::Stored));
        assert_eq!("paper".parse::<Split>(), Ok(Split::Paper));
        let point = OperatingPoint { coarse_share: 0.2, refine_share: 0.1 };
        assert_eq!("0.2, 0.1".parse::<Split>(), Ok(Split::Point(point)));
        for bad in ["Paper", "0.2", "0.6,0.5", "1,0", "a,b", ""] {
            assert!(bad.parse::<Split>().is_err(), "{bad}");
        }
        let written = serde_json::to_string(&[Split::Paper, Split::Point(point)]).unwrap();
        assert_eq!(written, r#"["paper",{"coarse_share":0.2,"refine_share":0.1}]"#);
    }

    #[test]
    fn refiners_parse_as_the_command_line_writes_them() {
        assert_eq!("network".parse(), Ok(Refiner::Network));
        assert_eq!("optimizer".parse(), Ok(Refiner::Optimizer { steps: OPTIMIZER_STEPS }));
        assert_eq!("optimizer:40".parse(), Ok(Refiner::Optimizer { steps: 40 }));
        let too_many = format!("optimizer:{}", MAX_OPTIMIZER_STEPS + 1);
        for bad in ["optimizer:0", "optimizer:", "optimizer:x", "network:3", "e_r", "", &too_many] {
            assert_eq!(bad.parse::<Refiner>(), Err(RefinerParseError(bad.into())), "{bad}");
        }
    }

    /// Each limit refuses the first value past it and takes the value at it, naming its field.
    #[test]
    fn jobs_are_checked_against_their_limits_by_field() {
        let job = Job::default();
        assert_eq!(job.validate(), Ok(()));
        let finetune = |limit| Some(FinetuneOptions { limit, ..FinetuneOptions::default() });
        let refused = [
            (Job { paths: PathBudget::Count(MAX_PATHS + 1), ..job.clone() }, "paths"),
            (Job { paths: PathBudget::Count(1), ..job.clone() }, "paths"),
            (Job { regions: Some(500), ..job.clone() }, "regions"),
            (Job { regions: Some(0), ..job.clone() }, "regions"),
            (Job { paths: "auto".parse().unwrap(), regions: Some(5), ..job.clone() }, "regions"),
            (Job { operating_point: Split::Paper, regions: Some(5), ..job.clone() }, "operating_point"),
            (
                Job {
                    operating_point: Split::Paper,
                    refiner: Refiner::Optimizer { steps: 5 },
                    ..job.clone()
                },
                "refiner",
            ),
            (
                Job { refiner: Refiner::Optimizer { steps: MAX_OPTIMIZER_STEPS + 1 }, ..job.clone() },
                "refiner",
            ),
            (Job { tolerance: Some(MAX_TOLERANCE + 0.5), ..job.clone() }, "tolerance"),
            (Job { tolerance: Some(f32::NAN), ..job.clone() }, "tolerance"),
            (Job { finetune: finetune(Limit::Seconds(MAX_FINETUNE_SECS + 1.0)), ..job.clone() }, "finetune"),
            (Job { finetune: finetune(Limit::Seconds(f64::NAN)), ..job.clone() }, "finetune"),
            (Job { finetune: finetune(Limit::Steps(MAX_FINETUNE_STEPS + 1)), ..job.clone() }, "finetune"),
            (
                Job {
                    svg: SvgOptions { decimals: MAX_DECIMALS + 1, ..SvgOptions::default() },
                    ..job.clone()
                },
                "svg",
            ),
            (Job { compactness: f32::INFINITY, ..job.clone() }, "compactness"),
            (Job { batch: 0, ..job.clone() }, "batch"),
        ];
        for (bad, field) in refused {
            let err = bad.validate().expect_err(field);
            assert_eq!(err.field(), field, "{err}");
        }
        let at_the_limits = [
            Job { paths: PathBudget::Count(MAX_PATHS), regions: Some(MAX_PATHS - 1), ..job.clone() },
            Job { tolerance: Some(MAX_TOLERANCE), ..job.clone() },
            Job { finetune: finetune(Limit::Seconds(MAX_FINETUNE_SECS)), ..job.clone() },
            Job { finetune: finetune(Limit::Steps(MAX_FINETUNE_STEPS)), ..job.clone() },
            Job { refiner: Refiner::Optimizer { steps: MAX_OPTIMIZER_STEPS }, ..job.clone() },
            Job { svg: SvgOptions { decimals: MAX_DECIMALS, ..SvgOptions::default() }, ..job.clone() },
        ];
        for good in at_the_limits {
            assert_eq!(good.validate(), Ok(()), "{good:?}");
        }
    }
}
