//! What the `infer` program decides before any work, as a library the program's tests can
//! call: where each input's outputs go ([`plan`]) and the flag values the library's [`Job`]
//! does not check itself ([`working_size`], [`colour`]). Behind the `cli` feature.
//!
//! [`Job`]: crate::Job

use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail};
use common::WORKING_SIZES;
use common::outputs::{absolute, check_not_input, check_writable, create_folder};

/// A long side within [`WORKING_SIZES`].
pub fn working_size(text: &str) -> Result<u32, String> {
    let (low, high) = (WORKING_SIZES.start(), WORKING_SIZES.end());
    match text.parse::<u32>() {
        Ok(size) if WORKING_SIZES.contains(&size) => Ok(size),
        _ => Err(format!("{text:?} is not a working size: a number of pixels from {low} to {high}")),
    }
}

/// `#rrggbb` (or `rrggbb`) as an RGB colour in [0, 1]: six hexadecimal digits, nothing else
/// (`from_str_radix` alone would take `+f` for `0f`).
pub fn colour(text: &str) -> Result<[f32; 3], String> {
    let hex = text.strip_prefix('#').unwrap_or(text);
    let digits = hex.bytes().all(|b| b.is_ascii_hexdigit());
    let channel =
        |i: usize| hex.get(i..i + 2).filter(|_| digits).and_then(|h| u8::from_str_radix(h, 16).ok());
    match (hex.len(), channel(0), channel(2), channel(4)) {
        (6, Some(r), Some(g), Some(b)) => Ok([r, g, b].map(|c| c as f32 / 255.0)),
        _ => Err(format!("{text:?} is not a colour: write it #rrggbb")),
    }
}

/// Whether stdout was closed when the program started (`infer a.png -o - >&-`): Rust's runtime
/// then puts `/dev/null`, opened read-write, in its place, and the SVG would vanish while the
/// program reports it written. A shell's `>/dev/null` opens it write-only, so that stays
/// allowed. Read from /proc: Linux only (elsewhere `false`).
pub fn stdout_closed() -> bool {
    #[cfg(target_os = "linux")]
    if let (Ok(target), Ok(info)) =
        (std::fs::read_link("/proc/self/fd/1"), std::fs::read_to_string("/proc/self/fdinfo/1"))
    {
        let flags = info.lines().find_map(|line| line.strip_prefix("flags:"));
        let mode = flags.and_then(|flags| u32::from_str_radix(flags.trim(), 8).ok()).map(|f| f & 0o3);
        return target == Path::new("/dev/null") && mode == Some(0o2);
    }
    false
}

/// One input and every output it gets, decided before any work.
#[derive(Clone, Debug, PartialEq)]
pub struct Planned {
    /// The image (`None`: stdin).
    pub input: Option<PathBuf>,
    /// Where its SVG goes (`None`: stdout).
    pub svg: Option<PathBuf>,
    /// Its `--preview` PNG.
    pub preview: Option<PathBuf>,
    /// Its `--compare` PNG.
    pub compare: Option<PathBuf>,
    /// Its `--metrics` JSON.
    pub metrics: Option<PathBuf>,
}

/// The output arguments of a command line: `-o` and the optional extra outputs.
#[derive(Clone, Copy, Debug)]
pub struct Outputs<'a> {
    /// `-o`: a file, a folder, or `-`.
    pub svg: &'a Path,
    /// `--preview`.
    pub preview: Option<&'a Path>,
    /// `--compare`.
    pub compare: Option<&'a Path>,
    /// `--metrics`.
    pub metrics: Option<&'a Path>,
}

/// What [`plan`] decided: the jobs, and the output folders to create.
#[derive(Debug)]
pub struct Plan {
    /// One per input, in order.
    pub jobs: Vec<Planned>,
    /// Folders that get one file per input.
    pub folders: Vec<PathBuf>,
}

impl Plan {
    /// Creates the output folders and checks that every output can be written there.
    pub fn prepare(&self) -> anyhow::Result<()> {
        for folder in &self.folders {
            create_folder(folder)?;
        }
        for planned in &self.jobs {
            let outputs = [&planned.svg, &planned.preview, &planned.compare, &planned.metrics];
            outputs.into_iter().flatten().try_for_each(|file| check_writable(file))?;
        }
        Ok(())
    }
}

impl Planned {
    /// The input as messages name it.
    pub fn name(&self) -> String {
        self.input.as_ref().map_or_else(|| "<stdin>".into(), |path| path.display().to_string())
    }
}

/// Every one of `inputs` (`-`: stdin) with its outputs, and the output folders to create, or
/// the first reason the command cannot run as asked: a file output for several inputs, a
/// wrong extension, an output that is an input or one of the `models` files the command reads
/// ([`check_not_input`]), two outputs on one file. Creates nothing ([`Plan::prepare`] does).
pub fn plan(inputs: &[PathBuf], models: &[PathBuf], outputs: Outputs) -> anyhow::Result<Plan> {
    let inputs: Vec<Option<PathBuf>> =
        inputs.iter().map(|path| (path.as_os_str() != "-").then(|| path.clone())).collect();
    if inputs.iter().filter(|input| input.is_none()).count() > 1 {
        bail!("stdin (-) can be read only once");
    }
    let many = inputs.len() > 1;
    let mut folders = Vec::new();
    // Each output argument resolved to a destination per input (`None`: stdout).
    let mut resolve = |flag: &str, path: &Path, extension: &str| -> anyhow::Result<Vec<Option<PathBuf>>> {
        let shown = path.display();
        if flag == "-o" && path.as_os_str() == "-" {
            return if many {
                Err(anyhow!("{flag} -: several inputs cannot all go to stdout"))
            } else {
                Ok(vec![None])
            };
        }
        if path.to_string_lossy().ends_with('/') || path.is_dir() {
            if path.exists() && !path.is_dir() {
                bail!("{flag} {shown}: not a folder");
            }
            folders.push(path.to_path_buf());
            let named = |input: &Option<PathBuf>| {
                let stem = input.as_ref().and_then(|p| p.file_stem()).map(|s| s.to_os_string());
                Some(path.join(Path::new(&stem.unwrap_or_else(|| "stdin".into())).with_extension(extension)))
            };
            return Ok(inputs.iter().map(named).collect());
        }
        if many {
            bail!("{flag} {shown}: several inputs need a folder (end the path with /)");
        }
        // A device or a pipe (`/dev/null`) has no extension to check.
        let special = std::fs::metadata(path).is_ok_and(|m| !m.is_file());
        if !special && !path.extension().is_some_and(|e| e.eq_ignore_ascii_case(extension)) {
            bail!("{flag} {shown}: the file name must end in .{extension}");
        }
        Ok(vec![Some(path.to_path_buf())])
    };
    let svg = resolve("-o", outputs.svg, "svg")?;
    let mut optional = |flag, path: Option<&Path>, extension| match path {
        Some(path) => resolve(flag, path, extension),
        None => Ok(vec![None; inputs.len()]),
    };
    let preview = optional("--preview", outputs.preview, "png")?;
    let compare = optional("--compare", outputs.compare, "png")?;
    let metrics = optional("--metrics", outputs.metrics, "json")?;

    let files: Vec<&PathBuf> = inputs.iter().flatten().chain(models).collect();
    // (absolute path, what would be written there), for every output file.
    let mut taken: Vec<(PathBuf, String)> = Vec::new();
    let mut jobs = Vec::new();
    for (index, input) in inputs.iter().enumerate() {
        let (svg, preview, compare, metrics) =
            (svg[index].clone(), preview[index].clone(), compare[index].clone(), metrics[index].clone());
        let job = Planned { input: input.clone(), svg, preview, compare, metrics };
        let outputs =
            [("the SVG", &job.svg), ("the --preview", &job.preview), ("the --compare", &job.compare)];
        for (what, file) in outputs.into_iter().chain([("the --metrics", &job.metrics)]) {
            let Some(file) = file else { continue };
            check_not_input(file, &files)?;
            let this = format!("{what} of {}", job.name());
            let absolute = absolute(file);
            if let Some((_, other)) = taken.iter().find(|(path, _)| *path == absolute) {
                bail!(
                    "{}: both {other} and {this} would be written there; give them different names",
                    file.display()
                );
            }
            taken.push((absolute, this));
        }
        jobs.push(job);
    }
    Ok(Plan { jobs, folders })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn paths(names: &[&str]) -> Vec<PathBuf> {
        names.iter().map(PathBuf::from).collect()
    }

    #[test]
    fn folders_name_each_output_after_its_input() {
        let outputs =
            Outputs { svg: Path::new("out/"), preview: None, compare: None, metrics: Some(Path::new("m/")) };
        let plan = plan(&paths(&["a/x.png", "b/y.jpg", "-"]), &[], outputs).unwrap();
        let svgs: Vec<_> = plan.jobs.iter().map(|j| j.svg.clone().unwrap()).collect();
        assert_eq!(svgs, paths(&["out/x.svg", "out/y.svg", "out/stdin.svg"]));
        assert_eq!(plan.jobs[1].metrics, Some(PathBuf::from("m/y.json")));
        assert_eq!(plan.folders, paths(&["out/", "m/"]));
        assert_eq!(plan.jobs[2].name(), "<stdin>");
    }

    #[test]
    fn outputs_that_cannot_be_planned_are_refused_with_the_reason() {
        fn one<'a>(svg: &'a str, preview: Option<&'a str>) -> Outputs<'a> {
            Outputs { svg: Path::new(svg), preview: preview.map(Path::new), compare: None, metrics: None }
        }
        let cases = [
            (paths(&["a.png", "b.png"]), one("x.svg", None), "several inputs need a folder"),
            (paths(&["a.png", "b.png"]), one("-", None), "cannot all go to stdout"),
            (paths(&["a.png"]), one("x.png", None), "must end in .svg"),
            (paths(&["a.png"]), one("x.svg", Some("x.svg")), "must end in .png"),
            (paths(&["-", "-"]), one("out/", None), "only once"),
            (
                paths(&["a/x.png", "b/x.png"]),
                one("out/", None),
                "both the SVG of a/x.png and the SVG of b/x.png",
            ),
        ];
        for (inputs, outputs, message) in cases {
            let err = plan(&inputs, &[], outputs).unwrap_err().to_string();
            assert!(err.contains(message), "{inputs:?}: {err}");
        }
        // A model file the command reads is no output either, whatever its name.
        let err = plan(&paths(&["a.png"]), &paths(&["m.svg"]), one("m.svg", None)).unwrap_err().to_string();
        assert!(err.contains("is the input m.svg"), "{err}");
    }

    #[test]
    fn colours_and_sizes_read_as_written() {
        assert_eq!(colour("#ff0080"), Ok([1.0, 0.0, 128.0 / 255.0]));
        assert_eq!(colour("000000"), Ok([0.0; 3]));
        for bad in ["#fff", "+f0000", "#gg0000", "#ff00801"] {
            assert!(colour(bad).is_err(), "{bad}");
        }
        assert_eq!(working_size("512"), Ok(512));
        assert!(working_size("15").is_err() && working_size("x").is_err());
    }
}
