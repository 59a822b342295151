//! Evaluating SuperSVG against other vectorizers, for the `eval` and `tune` programs: every way
//! of drawing an image behind one trait ([`Vectorizer`]: SuperSVG's variants, vtracer and
//! potrace as programs, the pixel-exact superpixel mosaic), every SVG rendered by resvg so each
//! is scored by the same renderer, LPIPS, and the report ([`report`], [`Results`]) with its
//! rate–distortion section and contact sheet. Kept out of the `infer` library users link.

mod cli;
mod lpips;
mod method;
mod peers;
mod rate;
mod report;
mod spill;

pub use cli::{MARK, command_line, finish, load_models};
pub use lpips::{LPIPS_ENV, Lpips, LpipsError};
pub use method::{
    Anatomy, Budget, DrawError, Drawing, Finetuned, Input, Method, Ours, Potrace, SPILL_DILATION, SlicMosaic,
    Vectorizer, Vtracer,
};
pub use peers::{PeerError, VtracerSettings, available, render_chart, render_svg};
pub use rate::{RatePoint, at, frontier};
pub use report::{
    Header, Results, Row, SweepPoint, Table, TimePoint, rate_chart, rate_section, report, sweep_points,
    time_chart, time_points, time_section,
};
pub use spill::spill;
