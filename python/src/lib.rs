//! `supersvg._native`: the Python package's bridge to [`infer::run`]. One function a kind of
//! input (a file, a file's bytes, pixels); `supersvg/__init__.py` picks between them and turns
//! Python's types (paths, numpy arrays, `paths="auto"`) into their arguments.
//!
//! The work runs on a worker thread with the GIL released, on the built-in models, loaded once
//! per process; the calling thread waits for it and hears Ctrl-C meanwhile, which stops the
//! work (a huge image's read, fine-tuning) and raises `KeyboardInterrupt` at once.
//! Errors become Python exceptions carrying the library's message: an image that cannot be read,
//! a budget out of range or an `out` that is the input is a `ValueError`, a file that cannot be
//! opened or written an `OSError` (`FileNotFoundError` when it does not exist), named in the
//! message. `out` is checked before any work.

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::sync::mpsc::RecvTimeoutError;
use std::time::Duration;

use burn::tensor::Device;
use common::decode::{self, Cancel, DecodeError, DecodeProblem, LoadOptions, Loaded, PixelLayout};
use common::outputs::{OutputError, check_output};
use common::write::write_atomic;
use infer::{
    AutoRule, BUILT_IN_MOVER, Fills, FinetuneOptions, Job, Limit, Models, MoverNetwork, Moves, PathBudget,
};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;

/// The built-in E_c and E_r on the CPU, opened by the first call (each network's weights are
/// read when a job first uses it), or why they could not be.
fn models() -> PyResult<&'static (Models, Device)> {
    static MODELS: OnceLock<Result<(Models, Device), String>> = OnceLock::new();
    let loaded = MODELS.get_or_init(|| {
        let device = Device::flex();
        let sources = |built_in| infer::bundled(built_in).map_err(|err| err.to_string());
        let (coarse, refine) = (sources(&infer::BUILT_IN_COARSE)?, sources(&infer::BUILT_IN_REFINE)?);
        Models::from_sources(&coarse, Some(&refine), &device)
            .map(|models| (models, device))
            .map_err(|err| err.to_string())
    });
    loaded.as_ref().map_err(|message| PyRuntimeError::new_err(format!("the models: {message}")))
}

/// [`models`] with the built-in mover, loaded by the first job that can use it: a
/// `SUPERSVG_MODELS` folder without one serves the jobs that do not.
fn models_for(job: &Job) -> PyResult<Models> {
    static MOVER: OnceLock<Result<MoverNetwork, String>> = OnceLock::new();
    let (models, device) = models()?;
    if !job.may_move() {
        return Ok(models.clone());
    }
    let mover = MOVER.get_or_init(|| {
        let source = infer::bundled(&BUILT_IN_MOVER).map_err(|err| err.to_string())?;
        MoverNetwork::load(&source, device).map_err(|err| err.to_string())
    });
    let mover =
        mover.as_ref().map_err(|message| PyRuntimeError::new_err(format!("the models: {message}")))?;
    Ok(Models { mover: Some(mover.clone()), ..models.clone() })
}

/// How often the waiting caller looks for a signal (Ctrl-C) while the work runs.
const SIGNAL_POLL: Duration = Duration::from_millis(50);

/// What every entry point is asked, beside its input.
struct Request {
    /// A number of paths, or `None` for `paths="auto"`.
    paths: Option<usize>,
    /// SuperSVG-F for this many seconds after B.
    finetune_secs: Option<f64>,
    /// Long side of the working image.
    size: u32,
    /// What the regions are filled with (`None`: the job's default).
    fills: Option<Fills>,
    /// Where the mover moves B's outlines (`None`: the job's default).
    moves: Option<Moves>,
    /// Where to write the SVG too.
    out: Option<PathBuf>,
}

impl Request {
    fn new(
        paths: Option<usize>,
        finetune_secs: Option<f64>,
        size: u32,
        (fills, moves): (Option<&str>, Option<&str>),
        out: Option<PathBuf>,
        input: Option<&Path>,
    ) -> PyResult<Self> {
        let fills = fills
            .map(str::parse::<Fills>)
            .transpose()
            .map_err(|err| PyValueError::new_err(format!("fills: {err}")))?;
        let moves = moves
            .map(str::parse::<Moves>)
            .transpose()
            .map_err(|err| PyValueError::new_err(format!("moves: {err}")))?;
        if let Some(out) = &out {
            check_out(out, input)?;
        }
        if !decode::WORKING_SIZES.contains(&size) {
            let (low, high) = (decode::WORKING_SIZES.start(), decode::WORKING_SIZES.end());
            return Err(PyValueError::new_err(format!(
                "size {size} is not a working size: {low} to {high} pixels"
            )));
        }
        if let Some(seconds) = finetune_secs.filter(|s| !(s.is_finite() && *s > 0.0)) {
            return Err(PyValueError::new_err(format!(
                "finetune_secs={seconds}: not a positive number of seconds"
            )));
        }
        let request = Self { paths, finetune_secs, size, fills, moves, out };
        // The library's limits, said in the words of `vectorize`'s arguments.
        request.job().validate().map_err(|err| {
            let argument = match err.field() {
                "finetune" => "finetune_secs",
                "paths" => "paths",
                field => field,
            };
            PyValueError::new_err(format!("{argument}: {err}"))
        })?;
        Ok(request)
    }

    fn load_options(&self) -> LoadOptions {
        LoadOptions { long_side: self.size, ..LoadOptions::default() }
    }

    fn job(&self) -> Job {
        Job {
            paths: self.paths.map_or(PathBudget::Auto(AutoRule::default()), PathBudget::Count),
            finetune: self.finetune_secs.map(|seconds| FinetuneOptions {
                limit: Limit::Seconds(seconds),
                ..FinetuneOptions::default()
            }),
            fills: self.fills,
            moves: self.moves.unwrap_or_default(),
            ..Job::default()
        }
    }

    /// Vectorizes the image `read` gives on a worker thread, while this one waits with the GIL
    /// released and looks for signals: Ctrl-C (any exception a signal handler raises) stops the
    /// work where it hears it (reading a huge image, fine-tuning) and is raised here at once.
    /// Writes `out` if asked. Returns the SVG and the warnings the job gave (the caller shows
    /// them as Python warnings).
    fn run(
        &self,
        py: Python<'_>,
        read: impl FnOnce(&LoadOptions) -> Result<Loaded, DecodeError> + Send + 'static,
    ) -> PyResult<(String, Vec<String>)> {
        let job = self.job();
        let device = models()?.1.clone();
        let models = models_for(&job)?;
        let cancel = Cancel::new();
        let options = LoadOptions { cancel: cancel.clone(), ..self.load_options() };
        let (sender, results) = std::sync::mpsc::channel();
        let stop = cancel.clone();
        std::thread::spawn(move || {
            let work = || -> PyResult<infer::Outcome> {
                let loaded = read(&options).map_err(decode_error)?;
                let mut on_step = |_: &infer::Progress| match stop.is_raised() {
                    true => ControlFlow::Break(()),
                    false => ControlFlow::Continue(()),
                };
                infer::run_with_progress(&models, &loaded, &job, &device, &mut on_step)
                    .map_err(|err| PyValueError::new_err(err.to_string()))
            };
            // The caller may have gone (a signal): then nobody reads the result.
            let _ = sender.send(work());
        });
        // Waited on with the GIL released, from whichever thread Python runs this one on.
        let results = std::sync::Mutex::new(results);
        let outcome = loop {
            let next = || {
                results.lock().unwrap_or_else(std::sync::PoisonError::into_inner).recv_timeout(SIGNAL_POLL)
            };
            match py.detach(next) {
                Ok(outcome) => break outcome?,
                Err(RecvTimeoutError::Timeout) => {
                    if let Err(err) = py.check_signals() {
                        cancel.raise();
                        return Err(err);
                    }
                }
                Err(RecvTimeoutError::Disconnected) => {
                    return Err(PyRuntimeError::new_err("the vectorizing thread ended without a result"));
                }
            }
        };
        if let Some(path) = &self.out {
            py.detach(|| write_atomic(path, outcome.svg.as_bytes())).map_err(|err| os_error(path, err))?;
        }
        let warnings = outcome.warnings.iter().map(ToString::to_string).collect();
        Ok((outcome.svg, warnings))
    }
}

/// Refuses, before any work, an `out` that is not an `.svg` file, that is the input (by any
/// name), or that cannot be written where it goes (its folder, its name's length).
fn check_out(out: &Path, input: Option<&Path>) -> PyResult<()> {
    if !out.extension().is_some_and(|ext| ext.eq_ignore_ascii_case("svg")) {
        return Err(PyValueError::new_err(format!("out={}: the SVG's file must end in .svg", out.display())));
    }
    use std::io::ErrorKind;
    check_output(out, input.as_slice()).map_err(|err| {
        let kind = match &err {
            OutputError::IsInput { .. } => return PyValueError::new_err(err.to_string()),
            OutputError::NotWritable { source, .. } | OutputError::CreateFolder { source, .. } => {
                source.kind()
            }
            OutputError::NotAFolder(_) => ErrorKind::NotADirectory,
            OutputError::Busy(_) => ErrorKind::ResourceBusy,
            OutputError::NotOurs { .. } => ErrorKind::AlreadyExists,
            OutputError::IsFolder(_) => ErrorKind::IsADirectory,
            OutputError::NameTooLong { .. } => ErrorKind::InvalidFilename,
            OutputError::NoFolder { .. } | OutputError::DanglingLink(_) => ErrorKind::NotFound,
        };
        std::io::Error::new(kind, err.to_string()).into()
    })
}

/// A decoding error as Python says it: `OSError` (its subclass by kind) when the file cannot be
/// read, `ValueError` when what was read is no usable image.
fn decode_error(err: DecodeError) -> PyErr {
    match err.problem {
        DecodeProblem::Io(io) => os_error(Path::new(&err.input), io),
        _ => PyValueError::new_err(err.to_string()),
    }
}

/// `err` about `path` as Python's `OSError` of the same kind, the path in its message.
fn os_error(path: &Path, err: std::io::Error) -> PyErr {
    std::io::Error::new(err.kind(), format!("{}: {err}", path.display())).into()
}

/// A budget from Python: a number of paths, or `None` for an automatic one.
type Paths = Option<usize>;

/// Vectorizes the image file at `path`. Returns `(svg, warnings)`.
#[pyfunction]
#[pyo3(signature = (path, paths, finetune_secs, size, fills, moves, out))]
fn from_file(
    py: Python<'_>,
    path: PathBuf,
    paths: Paths,
    finetune_secs: Option<f64>,
    size: u32,
    fills: Option<&str>,
    moves: Option<&str>,
    out: Option<PathBuf>,
) -> PyResult<(String, Vec<String>)> {
    Request::new(paths, finetune_secs, size, (fills, moves), out, Some(&path))?
        .run(py, move |options| decode::open(&path, options))
}

/// Vectorizes an image file's bytes (any format the files may have). Returns `(svg, warnings)`.
#[pyfunction]
#[pyo3(signature = (data, paths, finetune_secs, size, fills, moves, out))]
fn from_bytes(
    py: Python<'_>,
    data: &[u8],
    paths: Paths,
    finetune_secs: Option<f64>,
    size: u32,
    fills: Option<&str>,
    moves: Option<&str>,
    out: Option<PathBuf>,
) -> PyResult<(String, Vec<String>)> {
    Request::new(paths, finetune_secs, size, (fills, moves), out, None)?
        // The worker outlives a call a signal ends: it reads its own copy.
        .run(py, {
            let data = data.to_vec();
            move |options| decode::decode(&data, "<bytes>", options)
        })
}

/// Vectorizes `height` rows of `width` pixels of `channels` (1, 3 or 4) bytes each, in C order.
/// Returns `(svg, warnings)`.
#[pyfunction]
#[pyo3(signature = (data, width, height, channels, paths, finetune_secs, size, fills, moves, out))]
#[allow(clippy::too_many_arguments)] // one per keyword of `supersvg.vectorize`
fn from_pixels(
    py: Python<'_>,
    data: &[u8],
    width: u32,
    height: u32,
    channels: usize,
    paths: Paths,
    finetune_secs: Option<f64>,
    size: u32,
    fills: Option<&str>,
    moves: Option<&str>,
    out: Option<PathBuf>,
) -> PyResult<(String, Vec<String>)> {
    let layout = PixelLayout::from_channels(channels)
        .ok_or_else(|| PyValueError::new_err(format!("{channels} channels: an array needs 1, 3 or 4")))?;
    Request::new(paths, finetune_secs, size, (fills, moves), out, None)?.run(py, {
        let data = data.to_vec();
        move |options| decode::from_pixels(&data, (width, height), layout, "<array>", options)
    })
}

/// The module Python imports as `supersvg._native`.
#[pymodule]
fn _native(module: &Bound<'_, PyModule>) -> PyResult<()> {
    module.add_function(wrap_pyfunction!(from_file, module)?)?;
    module.add_function(wrap_pyfunction!(from_bytes, module)?)?;
    module.add_function(wrap_pyfunction!(from_pixels, module)?)?;
    module.add("MAX_PATHS", infer::MAX_PATHS)?;
    module.add("MAX_WORKING_SIZE", *decode::WORKING_SIZES.end())?;
    Ok(())
}
