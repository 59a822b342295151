//! supersvg in the browser: [`Vectorizer`] is `infer`'s whole pipeline behind a wasm-bindgen
//! API — an image file's bytes and the page's [`Settings`] in, the SVG and the report out —
//! compiled to WebAssembly for the page in `www/` (which runs it in a Web Worker). Nothing
//! leaves the machine: the bundled networks are compiled into the module, as into the `infer`
//! program, and draw what it draws.
//!
//! Built and served by `scripts/web.sh`; natively this crate is an ordinary library, which the
//! workspace's tests check.

use std::ops::ControlFlow;

use burn::tensor::Device;
use common::decode::{LoadOptions, decode};
use infer::{
    BudgetParseError, Fills, FillsParseError, FinetuneOptions, InvalidJob, Job, Limit, Models, ModelsError,
    PathBudget, Progress, run_with_progress,
};
use serde::Deserialize;
use wasm_bindgen::prelude::*;

/// What the page's controls ask for, as JSON: the `infer` flags of the same names (a missing key
/// is the flag's default).
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Settings {
    /// `--paths`: a number of paths, or `auto` (default 500).
    pub paths: Option<String>,
    /// `--tolerance`: curves that stray at most this many pixels (default: traced polygons).
    pub tolerance: Option<f32>,
    /// `--fills`: `flat`, `linear` or `auto` (default: auto, flat when fine-tuning and for flat art).
    pub fills: Option<String>,
    /// `--finetune-secs`: SuperSVG-F for this many seconds after B (default: none).
    pub finetune_secs: Option<f64>,
}

/// Why [`Settings`] make no job; the message names the setting as the page labels it.
#[derive(Debug, thiserror::Error)]
pub enum SettingsError {
    /// Not JSON of the expected shape (an unknown key, a wrong type).
    #[error("settings: {0}")]
    Json(#[from] serde_json::Error),
    /// `paths` is neither `auto` nor a path count in range.
    #[error("paths: {0}")]
    Paths(#[from] BudgetParseError),
    /// `fills` is no fill.
    #[error("fills: {0}")]
    Fills(#[from] FillsParseError),
    /// A value out of its range, or values that contradict each other.
    #[error("{}: {}", .0.field(), .0)]
    Invalid(#[from] InvalidJob),
}

impl Settings {
    /// Reads the page's settings (JSON; unknown keys refused).
    pub fn from_json(text: &str) -> Result<Self, SettingsError> {
        Ok(serde_json::from_str(text)?)
    }

    /// The job `infer` runs for the same flags, checked.
    pub fn job(&self) -> Result<Job, SettingsError> {
        let defaults = Job::default();
        let job = Job {
            paths: self.paths.as_deref().map(str::parse::<PathBudget>).transpose()?.unwrap_or(defaults.paths),
            tolerance: self.tolerance,
            fills: self.fills.as_deref().map(str::parse::<Fills>).transpose()?,
            finetune: self.finetune_secs.map(|seconds| FinetuneOptions {
                limit: Limit::Seconds(seconds),
                ..FinetuneOptions::default()
            }),
            ..defaults
        };
        job.validate()?;
        Ok(job)
    }
}

/// The bundled networks on the CPU, ready to draw any number of images.
#[wasm_bindgen]
pub struct Vectorizer {
    models: Models,
    device: Device,
}

/// One image drawn: the SVG text and `infer --metrics`' report as JSON.
#[wasm_bindgen(getter_with_clone)]
pub struct Drawn {
    /// The SVG document.
    pub svg: String,
    /// The report (paths, PSNR, bytes, seconds per stage), as `infer --metrics` writes it.
    pub report: String,
}

#[wasm_bindgen]
impl Vectorizer {
    /// Opens the bundled networks (their weights are read when a stage first needs them).
    #[wasm_bindgen(constructor)]
    pub fn new() -> Result<Vectorizer, JsError> {
        Self::bundled().map_err(|err| JsError::new(&err.to_string()))
    }

    /// Draws the image file `bytes` (named `name` in errors) as `settings` (JSON, see
    /// [`Settings`]) ask. `progress`, if given, is called after every fine-tuning step with
    /// (seconds, PSNR in dB).
    pub fn vectorize(
        &self,
        bytes: &[u8],
        name: &str,
        settings: &str,
        progress: Option<js_sys::Function>,
    ) -> Result<Drawn, JsError> {
        self.draw(bytes, name, settings, &mut |step| {
            if let Some(progress) = &progress {
                // A throwing callback is the page's own bug; the drawing goes on regardless.
                let _ = progress.call2(&JsValue::NULL, &step.seconds.into(), &step.psnr.into());
            }
        })
        .map_err(|message| JsError::new(&message))
    }
}

impl Vectorizer {
    /// The bundled networks on the CPU (flex).
    pub fn bundled() -> Result<Self, ModelsError> {
        let device = Device::flex();
        Ok(Self { models: Models::bundled(true, &device)?, device })
    }

    /// [`Vectorizer::vectorize`] for Rust callers: the error is the message the page shows.
    pub fn draw(
        &self,
        bytes: &[u8],
        name: &str,
        settings: &str,
        on_step: &mut dyn FnMut(&Progress),
    ) -> Result<Drawn, String> {
        let job = Settings::from_json(settings).and_then(|s| s.job()).map_err(|err| err.to_string())?;
        let image = decode(bytes, name, &LoadOptions::default()).map_err(|err| err.to_string())?;
        let outcome = run_with_progress(&self.models, &image, &job, &self.device, &mut |step| {
            on_step(step);
            ControlFlow::Continue(())
        })
        .map_err(|err| format!("{name}: {err}"))?;
        let report = serde_json::to_string(&outcome.report).map_err(|err| err.to_string())?;
        Ok(Drawn { svg: outcome.svg, report })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_make_the_job_infer_runs_for_the_same_flags() {
        let settings =
            Settings::from_json(r#"{"paths": "auto", "tolerance": 1.5, "fills": "linear"}"#).unwrap();
        let job = settings.job().unwrap();
        assert!(matches!(job.paths, PathBudget::Auto(_)));
        assert_eq!(job.tolerance, Some(1.5));
        assert_eq!(job.fills, Some(Fills::Linear));
        assert!(job.finetune.is_none());
        let job = Settings::from_json(r#"{"finetune_secs": 2}"#).unwrap().job().unwrap();
        assert_eq!(job.paths, PathBudget::Count(500));
        assert!(matches!(job.finetune.map(|f| f.limit), Some(Limit::Seconds(2.0))));
    }

    #[test]
    fn bad_settings_name_what_is_wrong() {
        for (json, expected) in [
            (r#"{"paths": "many"}"#, "paths: "),
            (r#"{"fills": "radial"}"#, "fills: "),
            (r#"{"tolerance": 99}"#, "tolerance: "),
            (r#"{"colours": 3}"#, "settings: unknown field `colours`"),
        ] {
            let message = Settings::from_json(json).and_then(|s| s.job()).unwrap_err().to_string();
            assert!(message.starts_with(expected), "{json}: {message}");
        }
    }

    #[test]
    fn a_file_that_is_no_image_is_refused_by_name() {
        let vectorizer = Vectorizer::bundled().unwrap();
        let err = vectorizer.draw(b"hello, not a picture", "notes.txt", "{}", &mut |_| {}).err().unwrap();
        assert_eq!(err, "notes.txt: not an image in a known format");
    }
}
