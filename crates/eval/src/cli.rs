//! What the evaluation programs share: loading the models and turning a run's result into an
//! exit code (a folder's images are listed by [`common::folder::files_in`]).

use std::path::Path;
use std::process::ExitCode;

use burn::tensor::Device;
use infer::{BUILT_IN_COARSE, BUILT_IN_MOVER, BUILT_IN_REFINE, ModelSource, Models, ModelsError, bundled};

/// Prints a failed run's error and gives the exit code: 0 on success, 1 on error.
pub fn finish(result: anyhow::Result<()>) -> ExitCode {
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            common::say!("error: {}", common::say::chain(err.as_ref()));
            ExitCode::FAILURE
        }
    }
}

/// How to run this program again with the arguments it was given, for a report's "Command:"
/// line: as `cargo run` from the repository (whatever path the binary was started by, so a
/// report made with an installed or copied binary reads the same), each argument quoted for a
/// POSIX shell where it needs it (`--peers ''` stays two words).
pub fn command_line(bin: &str, args: impl IntoIterator<Item = String>) -> String {
    let mut line = format!("cargo run --release -p eval --bin {bin} --");
    for arg in args {
        line.push(' ');
        line.push_str(&shell_quoted(&arg));
    }
    line
}

fn shell_quoted(arg: &str) -> String {
    let plain = |c: char| c.is_ascii_alphanumeric() || "-_./,=:+@%".contains(c);
    if !arg.is_empty() && arg.chars().all(plain) {
        arg.to_string()
    } else {
        format!("'{}'", arg.replace('\'', r"'\''"))
    }
}

/// The mark the files `eval` names after its report carry (the contact sheet's `Software` text,
/// the chart's comment), so that a file of that name it did not write is never replaced.
pub const MARK: &str = "supersvg eval";

/// E_c, E_r and the mover, from the given checkpoints (read and verified now) or the bundled
/// ones (verified when first used); each network's [`infer::Identity`] says which.
pub fn load_models(
    coarse: Option<&Path>,
    refine: Option<&Path>,
    mover: Option<&Path>,
    device: &Device,
) -> Result<Models, ModelsError> {
    let source = |path: Option<&Path>, built_in| match path {
        Some(path) => Ok(ModelSource::File(path.to_path_buf())),
        None => bundled(built_in),
    };
    let coarse = source(coarse, &BUILT_IN_COARSE)?;
    let refine = source(refine, &BUILT_IN_REFINE)?;
    let mover = source(mover, &BUILT_IN_MOVER)?;
    Ok(Models::from_sources(&coarse, Some(&refine), device)?.with_mover(&mover, device)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn command_line_names_cargo_and_quotes_what_a_shell_would_split() {
        let args =
            ["data/eval/photos", "--paths", "500,2000", "--peers", "", "--out", "my report.md", "it's"];
        assert_eq!(
            command_line("eval", args.map(String::from)),
            "cargo run --release -p eval --bin eval -- data/eval/photos --paths 500,2000 --peers '' \
             --out 'my report.md' 'it'\\''s'"
        );
    }
}
