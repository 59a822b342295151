//! Every way of drawing an image that a report has rows for — SuperSVG's variants and its peers —
//! behind one trait, [`Vectorizer`]: adding a method is one type and one line where `eval`
//! lists them.

use std::ops::ControlFlow;
use std::path::Path;

use burn::tensor::Device;
use common::Loaded;
use common::write::write_png;
use image::{Rgb32FImage, RgbImage};
use infer::{FinetuneOptions, Job, Models, Outcome, PathBudget, RefineTally, StageCounts, VectorizeError};

use crate::peers::{
    PeerError, VtracerSettings, count_shapes, mean_color_superpixels, potrace_colors, render_svg, vtracer,
    vtracer_with,
};
use crate::spill::spill;

/// Dilation (pixels) of a region's mask before its paths' spill is measured: the margin the
/// training's boundary loss allows (`dpw::BOUNDARY_DILATION`).
pub const SPILL_DILATION: u32 = dpw::BOUNDARY_DILATION as u32;

/// A way of drawing an image that the report has rows for; the order is the report's.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Method {
    /// SuperSVG-B at the budget.
    OursB,
    /// SuperSVG-F: B's drawing fine-tuned, as `infer --finetune-secs` draws it.
    OursF,
    /// SuperSVG-F as it was before it started from B's drawing: from B with flat fills and no
    /// mover, the outlines fitted with one path where that writes less, opacity moved too.
    OursFWas,
    /// SuperSVG-B with `--paths auto`.
    OursAuto,
    /// SuperSVG-B without its refinement networks (E_r and the mover).
    OursNoRefine,
    /// SuperSVG-B without the mover.
    OursNoMoves,
    /// SuperSVG-B at the paper's operating point.
    OursPaper,
    /// SuperSVG-B with the exact optimizer in E_r's place.
    OursOptimizer,
    /// SuperSVG-B with every region a ramp fits filled with it (`--fills linear`).
    OursLinear,
    /// SuperSVG-B with every region in its mean colour (`--fills flat`), where the default
    /// puts ramps that pay for their bytes.
    OursFlat,
    /// The fallback drawing alone.
    Fallback,
    /// vtracer with one knob searched to the budget.
    Vtracer,
    /// vtracer's default settings.
    VtracerDefault,
    /// potrace on colour layers.
    Potrace,
    /// The SLIC mosaic.
    Slic,
}

impl Method {
    /// The row's name in the report.
    pub fn name(self) -> &'static str {
        match self {
            Method::OursB => "SuperSVG-B (ours)",
            Method::OursF => "SuperSVG-F (ours)",
            Method::OursFWas => "SuperSVG-F as it was (flat start, fitted outlines)",
            Method::OursAuto => "SuperSVG-B (ours), --paths auto",
            Method::OursNoRefine => "SuperSVG-B without E_r and the mover (--no-refine)",
            Method::OursNoMoves => "SuperSVG-B without the mover (--moves off)",
            Method::OursPaper => "SuperSVG-B, the paper's inference (--operating-point paper)",
            Method::OursOptimizer => "SuperSVG-B, the exact optimizer in E_r's place (--refiner optimizer)",
            Method::OursLinear => "SuperSVG-B, regions filled with ramps (--fills linear)",
            Method::OursFlat => "SuperSVG-B, regions filled flat (--fills flat)",
            Method::Fallback => "fallback alone (traced regions in their fills)",
            Method::Vtracer => "vtracer",
            Method::VtracerDefault => "vtracer (default settings)",
            Method::Potrace => "potrace, 16 colour layers",
            Method::Slic => "SLIC regions, mean colour",
        }
    }

    /// Whether this is a drawing of SuperSVG's (the file `infer` writes), not a peer's.
    pub fn is_ours(self) -> bool {
        matches!(
            self,
            Method::OursB
                | Method::OursF
                | Method::OursFWas
                | Method::OursAuto
                | Method::OursNoRefine
                | Method::OursNoMoves
                | Method::OursPaper
                | Method::OursOptimizer
                | Method::OursLinear
                | Method::OursFlat
                | Method::Fallback
        )
    }

    /// The name `eval --svgs` gives this method's SVG of `stem` at `budget` (SuperSVG's own
    /// drawings only: they are the files `infer` writes with the same settings).
    pub fn svg_name(self, stem: &str, budget: Budget) -> String {
        let prefix = match self {
            Method::OursF => "f",
            Method::OursFWas => "f-was",
            Method::Fallback => "fallback",
            Method::OursNoRefine => "no-refine",
            Method::OursNoMoves => "no-moves",
            Method::OursPaper => "paper",
            Method::OursOptimizer => "optimizer",
            Method::OursLinear => "linear",
            Method::OursFlat => "flat",
            _ => "b",
        };
        match (self, budget) {
            (Method::OursAuto, _) => format!("{stem}-auto.svg"),
            (_, Budget::Paths(paths)) => format!("{stem}-{prefix}-{paths}.svg"),
            (_, Budget::Own | Budget::Vtracer(_)) => format!("{stem}-own.svg"),
        }
    }
}

/// What a method is asked to draw at.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Budget {
    /// This many paths (or shapes, for the peers).
    Paths(usize),
    /// The method's own choice: `--paths auto`, vtracer's defaults.
    Own,
    /// One of vtracer's settings (the rate–distortion sweep).
    Vtracer(VtracerSettings),
}

impl Budget {
    /// How the report names it.
    pub fn title(self) -> String {
        match self {
            Budget::Paths(paths) => format!("{paths} paths"),
            Budget::Own => "each method's own budget".to_string(),
            Budget::Vtracer(settings) => settings.label(),
        }
    }
}

/// One image as every method reads it: decoded at the working size, and as a PNG file for the
/// programs that read files.
pub struct Input<'a> {
    /// The image at the working size.
    pub loaded: &'a Loaded,
    /// The same pixels as an 8-bit PNG.
    pub png: &'a Path,
    /// A folder of this run's own for the programs' files.
    pub scratch: &'a Path,
}

impl<'a> Input<'a> {
    /// `loaded`, also written as an 8-bit PNG at `png` (in `scratch`) for the programs.
    pub fn new(loaded: &'a Loaded, png: &'a Path, scratch: &'a Path) -> std::io::Result<Self> {
        write_png(png, &to_rgb8(&loaded.image))?;
        Ok(Self { loaded, png, scratch })
    }
}

/// An image at 8 bits a channel.
pub(crate) fn to_rgb8(image: &Rgb32FImage) -> RgbImage {
    image::DynamicImage::ImageRgb32F(image.clone()).to_rgb8()
}

/// A method's picture of one image.
pub struct Drawing {
    /// Its rendering at the working size (resvg's, for every SVG).
    pub image: Rgb32FImage,
    /// Closed subpaths (or regions, for the mosaic): the same unit for every method.
    pub shapes: usize,
    /// The SVG (none for the pixel-exact mosaic, which is no SVG).
    pub svg: Option<String>,
    /// Wall time of the method.
    pub seconds: f64,
    /// Paths per stage and spill, for SuperSVG's own drawings.
    pub anatomy: Option<Anatomy>,
}

/// What a SuperSVG drawing is made of.
#[derive(Clone, Copy, Debug)]
pub struct Anatomy {
    /// Paths per stage.
    pub stages: StageCounts,
    /// Share of region paths' area outside their region dilated by [`SPILL_DILATION`].
    pub spill: f64,
    /// What E_r proposed and kept.
    pub refinement: RefineTally,
}

/// Why a method drew nothing: a peer's failure leaves its row out (and is printed); ours ends
/// the evaluation, since it is what is evaluated.
#[derive(Debug, thiserror::Error)]
pub enum DrawError {
    /// A peer (or rendering an SVG) failed.
    #[error(transparent)]
    Peer(#[from] PeerError),
    /// SuperSVG failed.
    #[error(transparent)]
    Ours(#[from] VectorizeError),
}

/// A way of drawing an image, scored by `eval`.
pub trait Vectorizer {
    /// The report's row.
    fn method(&self) -> Method;
    /// Whether the method is drawn at the `--sweep` budgets too (it has a curve by path budget).
    fn sweeps(&self) -> bool {
        false
    }
    /// The drawing of `input` at `budget`, or `None` where the method has none at that budget.
    fn draw(&self, input: &Input, budget: Budget) -> Result<Option<Drawing>, DrawError>;
}

/// An SVG rendered by resvg like every other method's.
fn rendered(
    svg: String,
    input: &Input,
    seconds: f64,
    anatomy: Option<Anatomy>,
) -> Result<Drawing, PeerError> {
    let (width, height) = input.loaded.image.dimensions();
    let image = render_svg(&svg, width, height)?;
    Ok(Drawing { image, shapes: count_shapes(&svg), svg: Some(svg), seconds, anatomy })
}

/// SuperSVG's own drawing, as `infer` writes it.
fn ours(outcome: Outcome, input: &Input) -> Result<Drawing, DrawError> {
    let anatomy = Anatomy {
        stages: outcome.report.paths_by_stage,
        spill: spill(outcome.scene.paths(), outcome.scene.segmentation(), SPILL_DILATION),
        refinement: outcome.report.refinement,
    };
    Ok(rendered(outcome.svg, input, outcome.report.seconds.total, Some(anatomy))?)
}

/// SuperSVG-B (or a variant: other models, another split, the fallback alone): `infer::run`
/// with `job` at the budget.
pub struct Ours<'a> {
    /// The row.
    pub method: Method,
    /// The models it draws with.
    pub models: &'a Models,
    /// The job at every budget but its paths (and, for the fallback, its regions).
    pub job: Job,
    /// The device.
    pub device: &'a Device,
}

impl Vectorizer for Ours<'_> {
    fn method(&self) -> Method {
        self.method
    }

    fn sweeps(&self) -> bool {
        matches!(
            self.method,
            Method::OursB | Method::Fallback | Method::OursLinear | Method::OursFlat | Method::OursNoMoves
        )
    }

    fn draw(&self, input: &Input, budget: Budget) -> Result<Option<Drawing>, DrawError> {
        let job = match (self.method, budget) {
            (Method::OursAuto, Budget::Own) => self.job.clone(),
            (Method::OursAuto, _) | (_, Budget::Own | Budget::Vtracer(_)) => return Ok(None),
            (Method::Fallback, Budget::Paths(paths)) => {
                Job { paths: PathBudget::Count(paths), regions: Some(paths - 1), ..self.job.clone() }
            }
            (_, Budget::Paths(paths)) => Job { paths: PathBudget::Count(paths), ..self.job.clone() },
        };
        ours(infer::run(self.models, input.loaded, &job, self.device)?, input).map(Some)
    }
}

/// SuperSVG-F: SuperSVG-B at the budget (as its job says: with or without the mover), then
/// every path fine-tuned.
pub struct Finetuned<'a> {
    /// B, which F starts from; its method is the row's ([`Method::OursF`] or
    /// [`Method::OursFWas`]).
    pub base: Ours<'a>,
    /// How long F runs.
    pub options: FinetuneOptions,
}

impl Vectorizer for Finetuned<'_> {
    fn method(&self) -> Method {
        self.base.method
    }

    fn draw(&self, input: &Input, budget: Budget) -> Result<Option<Drawing>, DrawError> {
        let Budget::Paths(paths) = budget else { return Ok(None) };
        let job = Job { paths: PathBudget::Count(paths), ..self.base.job.clone() };
        let outcome = infer::run(self.base.models, input.loaded, &job, self.base.device)?;
        let tuned =
            outcome.finetuned(input.loaded, &job, &self.options, &mut |_| ControlFlow::Continue(()))?;
        ours(tuned, input).map(Some)
    }
}

/// vtracer (colour, stacked, spline), run as a program: one knob searched to the budget's
/// shapes, its defaults, or one setting of the sweep.
pub struct Vtracer {
    /// [`Method::Vtracer`] (searched, and the sweep) or [`Method::VtracerDefault`].
    pub method: Method,
}

impl Vectorizer for Vtracer {
    fn method(&self) -> Method {
        self.method
    }

    fn draw(&self, input: &Input, budget: Budget) -> Result<Option<Drawing>, DrawError> {
        let traced = match (self.method, budget) {
            (Method::VtracerDefault, Budget::Own) => vtracer(input.png, None, input.scratch),
            (Method::Vtracer, Budget::Paths(paths)) => vtracer(input.png, Some(paths), input.scratch),
            (Method::Vtracer, Budget::Vtracer(settings)) => vtracer_with(input.png, settings, input.scratch),
            _ => return Ok(None),
        }?;
        Ok(Some(rendered(traced.svg, input, traced.seconds, None)?))
    }
}

/// potrace on 16 colour layers, run as a program, searched to the budget's shapes.
pub struct Potrace;

impl Vectorizer for Potrace {
    fn method(&self) -> Method {
        Method::Potrace
    }

    fn draw(&self, input: &Input, budget: Budget) -> Result<Option<Drawing>, DrawError> {
        let Budget::Paths(paths) = budget else { return Ok(None) };
        let traced = potrace_colors(&input.loaded.image, 16, Some(paths), input.scratch)?;
        Ok(Some(rendered(traced.svg, input, traced.seconds, None)?))
    }
}

/// SLIC regions in their mean colour, pixel-exact: the baseline a region-based vectorizer must
/// beat.
pub struct SlicMosaic;

impl Vectorizer for SlicMosaic {
    fn method(&self) -> Method {
        Method::Slic
    }

    fn draw(&self, input: &Input, budget: Budget) -> Result<Option<Drawing>, DrawError> {
        let Budget::Paths(paths) = budget else { return Ok(None) };
        let mosaic = mean_color_superpixels(&input.loaded.image, paths)?;
        Ok(Some(Drawing {
            image: mosaic.image,
            shapes: mosaic.regions,
            svg: None,
            seconds: mosaic.seconds,
            anatomy: None,
        }))
    }
}
