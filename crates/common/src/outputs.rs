//! The one rule every program follows before any work: an output is never one of its inputs,
//! and it can be written where it goes. `infer`, `eval`, `tune`, `export-model` and the Python
//! package all check their outputs here, so a mistyped name never turns an image into an SVG,
//! a report or a truncated checkpoint.

use std::path::{Path, PathBuf};

use crate::write::{NAME_MAX, folder_of, probe_folder};

/// Why an output cannot be written where it was asked to go.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The output is one of the inputs (the same file, through links or another name).
    #[error("{}: is the input {}; refusing to overwrite it", output.display(), input.display())]
    IsInput {
        /// The output as given.
        output: PathBuf,
        /// The input it is.
        input: PathBuf,
    },
    /// A symbolic link to nothing: writing through it would create a file somewhere else.
    #[error("{}: a link to nothing; remove it or write elsewhere", .0.display())]
    DanglingLink(PathBuf),
    /// A folder where a file is to be written.
    #[error("{}: is a folder", .0.display())]
    IsFolder(PathBuf),
    /// The folder of the output does not exist.
    #[error("{}: the folder {} does not exist", path.display(), folder.display())]
    NoFolder {
        /// The output.
        path: PathBuf,
        /// Its folder.
        folder: PathBuf,
    },
    /// No file can be created in the output's folder.
    #[error("{}: cannot write in {}: {source}", path.display(), folder.display())]
    NotWritable {
        /// The output.
        path: PathBuf,
        /// Its folder.
        folder: PathBuf,
        /// What creating a file there said.
        source: std::io::Error,
    },
    /// A file name longer than [`NAME_MAX`] bytes.
    #[error("{}: the file name is {len} bytes, longer than the {NAME_MAX} a file system takes", path.display())]
    NameTooLong {
        /// The output.
        path: PathBuf,
        /// Its name's length in bytes.
        len: usize,
    },
}

/// `output` checked against `inputs` ([`check_not_input`]) and for being writable
/// ([`check_writable`]).
pub fn check_output<P: AsRef<Path>>(output: &Path, inputs: &[P]) -> Result<(), OutputError> {
    check_not_input(output, inputs)?;
    check_writable(output)
}

/// Refuses `output` when it is one of `inputs` ([`same_file`]) or a link to nothing.
pub fn check_not_input<P: AsRef<Path>>(output: &Path, inputs: &[P]) -> Result<(), OutputError> {
    if let Some(input) = inputs.iter().map(AsRef::as_ref).find(|input| same_file(output, input)) {
        return Err(OutputError::IsInput { output: output.to_path_buf(), input: input.to_path_buf() });
    }
    if std::fs::symlink_metadata(output).is_ok_and(|m| m.file_type().is_symlink()) && !output.exists() {
        return Err(OutputError::DanglingLink(output.to_path_buf()));
    }
    Ok(())
}

/// Whether `file` can be written: its name fits a file system ([`NAME_MAX`]), it is not a
/// folder, and its folder exists and takes a new file (what an atomic write needs), unless it
/// is a device or a pipe, which is written in place.
pub fn check_writable(file: &Path) -> Result<(), OutputError> {
    let len = file.file_name().map_or(0, |name| name.len());
    if len > NAME_MAX {
        return Err(OutputError::NameTooLong { path: file.to_path_buf(), len });
    }
    if file.is_dir() {
        return Err(OutputError::IsFolder(file.to_path_buf()));
    }
    if std::fs::metadata(file).is_ok_and(|m| !m.is_file()) {
        return Ok(());
    }
    let folder = folder_of(file);
    if !folder.is_dir() {
        return Err(OutputError::NoFolder { path: file.to_path_buf(), folder: folder.to_path_buf() });
    }
    probe_folder(folder).map_err(|source| OutputError::NotWritable {
        path: file.to_path_buf(),
        folder: folder.to_path_buf(),
        source,
    })
}

/// Whether `a` and `b` are the same file: the same device and inode where both exist (so links,
/// hard links and `dir/../dir/x` all count), else the same absolute path ([`absolute`]).
pub fn same_file(a: &Path, b: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        if let (Ok(a), Ok(b)) = (std::fs::metadata(a), std::fs::metadata(b)) {
            return a.dev() == b.dev() && a.ino() == b.ino();
        }
    }
    absolute(a) == absolute(b)
}

/// `path` made absolute, with its folder resolved through links where it exists.
pub fn absolute(path: &Path) -> PathBuf {
    if let Ok(resolved) = std::fs::canonicalize(path) {
        return resolved;
    }
    let folder = folder_of(path);
    let folder = std::fs::canonicalize(folder).unwrap_or_else(|_| folder.to_path_buf());
    folder.join(path.file_name().unwrap_or_default())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("supersvg-outputs-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        dir
    }

    #[test]
    fn an_input_is_never_an_output_by_any_name() {
        let dir = scratch("inputs");
        let image = dir.join("image.png");
        std::fs::write(&image, b"png").unwrap();
        let other = dir.join("other.png");
        std::fs::write(&other, b"png").unwrap();
        let dotted = dir.join("sub/../image.png");
        let hard = dir.join("hard.png");
        std::fs::hard_link(&image, &hard).unwrap();
        for output in [&image, &dotted, &hard] {
            let err = check_output(output, &[&other, &image]).unwrap_err();
            assert!(matches!(&err, OutputError::IsInput { input, .. } if *input == image), "{err}");
            assert!(err.to_string().contains("refusing to overwrite"), "{err}");
        }
        #[cfg(unix)]
        {
            let link = dir.join("link.svg");
            std::os::unix::fs::symlink(&image, &link).unwrap();
            assert!(matches!(check_output(&link, &[&image]), Err(OutputError::IsInput { .. })));
            let dangling = dir.join("dangling.svg");
            std::os::unix::fs::symlink(dir.join("nothing"), &dangling).unwrap();
            assert!(matches!(check_output(&dangling, &[&image]), Err(OutputError::DanglingLink(_))));
        }
        check_output(&dir.join("image.svg"), &[&image, &other]).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn an_output_that_cannot_be_written_is_said_before_any_work() {
        let dir = scratch("writable");
        let long = dir.join(format!("{}.svg", "x".repeat(NAME_MAX)));
        assert!(
            matches!(check_writable(&long), Err(OutputError::NameTooLong { len, .. }) if len == NAME_MAX + 4)
        );
        // The longest name that fits is written, its temporary's name shortened to fit too.
        let longest = dir.join(format!("{}.svg", "y".repeat(NAME_MAX - 4)));
        check_writable(&longest).unwrap();
        crate::write::write_atomic(&longest, b"svg").unwrap();
        assert_eq!(std::fs::read(&longest).unwrap(), b"svg");
        assert!(matches!(check_writable(&dir.join("sub")), Err(OutputError::IsFolder(_))));
        assert!(matches!(check_writable(&dir.join("no/such/x.svg")), Err(OutputError::NoFolder { .. })));
        check_writable(Path::new("/dev/null")).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
