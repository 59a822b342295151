//! The one rule every program follows before any work: an output is never one of its inputs,
//! and it can be written where it goes. `infer`, `eval`, `tune`, `export-model` and the Python
//! package all check their outputs here, so a mistyped name never turns an image into an SVG,
//! a report or a truncated checkpoint.

use std::path::{Path, PathBuf};

use crate::write::{NAME_MAX, folder_of, probe_folder};

/// Why an output cannot be written where it was asked to go, or its folder cannot be used.
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
    /// Something other than a folder where an output folder goes.
    #[error("{}: is a file, not a folder", .0.display())]
    NotAFolder(PathBuf),
    /// The output folder could not be created.
    #[error("{}: cannot create the folder: {source}", path.display())]
    CreateFolder {
        /// The folder.
        path: PathBuf,
        /// What creating it said.
        source: std::io::Error,
    },
    /// An output folder another run of a program is writing to ([`lock_folder`]).
    #[error("{}: another run is writing to this folder; wait for it to end or choose another folder", .0.display())]
    Busy(PathBuf),
    /// A file a program derives from its output's name (a report's contact sheet) that it did not
    /// write itself ([`check_replaceable`]).
    #[error("{}: exists and was not written by {by}; move it away or choose another name", path.display())]
    NotOurs {
        /// The file.
        path: PathBuf,
        /// The program that would replace it.
        by: &'static str,
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

/// Creates the output folder `path` (and its parents) unless it is there; a file in its place
/// is said as such, not as the operating system's "File exists".
pub fn create_folder(path: &Path) -> Result<(), OutputError> {
    // `plain/` names the file `plain` too (asking for `plain/` itself fails with "not a folder").
    let bare = path.components().as_path();
    let not_a_folder = || std::fs::metadata(bare).is_ok_and(|m| !m.is_dir());
    if not_a_folder() {
        return Err(OutputError::NotAFolder(path.to_path_buf()));
    }
    std::fs::create_dir_all(path).map_err(|source| match not_a_folder() {
        true => OutputError::NotAFolder(path.to_path_buf()),
        false => OutputError::CreateFolder { path: path.to_path_buf(), source },
    })
}

/// The name of the lock file [`lock_folder`] takes in a folder.
pub const LOCK_NAME: &str = ".supersvg.lock";

/// An output folder held by this process ([`lock_folder`]) until it is dropped (or the process
/// ends, however it ends: the operating system releases the lock).
#[derive(Debug)]
pub struct FolderLock {
    _file: std::fs::File,
}

/// Holds `folder` (which must exist) for this process, so that a second run writing to the same
/// folder is refused before any work ([`OutputError::Busy`]) instead of both losing each
/// other's files: an exclusive lock on [`LOCK_NAME`] in it, created without following a
/// planted link.
pub fn lock_folder(folder: &Path) -> Result<FolderLock, OutputError> {
    let path = folder.join(LOCK_NAME);
    let failed =
        |source| OutputError::NotWritable { path: path.clone(), folder: folder.to_path_buf(), source };
    let file = open_lock(&path).map_err(failed)?;
    match file.try_lock() {
        Ok(()) => Ok(FolderLock { _file: file }),
        Err(std::fs::TryLockError::WouldBlock) => Err(OutputError::Busy(folder.to_path_buf())),
        Err(std::fs::TryLockError::Error(source)) => Err(failed(source)),
    }
}

#[cfg(unix)]
fn open_lock(path: &Path) -> std::io::Result<std::fs::File> {
    use rustix::fs::{Mode, OFlags};
    let flags = OFlags::RDWR | OFlags::CREATE | OFlags::NOFOLLOW | OFlags::CLOEXEC;
    Ok(rustix::fs::open(path, flags, Mode::from_raw_mode(0o644))?.into())
}

#[cfg(not(unix))]
fn open_lock(path: &Path) -> std::io::Result<std::fs::File> {
    std::fs::OpenOptions::new().read(true).write(true).create(true).truncate(false).open(path)
}

/// How many bytes at the start of a file [`check_replaceable`] reads for the mark.
const MARK_WITHIN: usize = 4096;

/// Refuses to replace `path` unless it is absent or a file `by` wrote: one whose first bytes
/// hold `mark` (a PNG's text chunk, an SVG's comment). For the files a program names after its
/// output (`eval --out keep.md` writes `keep.png` beside it): a file of that name the user
/// made is not silently replaced.
pub fn check_replaceable(path: &Path, mark: &str, by: &'static str) -> Result<(), OutputError> {
    let Ok(file) = std::fs::File::open(path) else {
        return match std::fs::symlink_metadata(path) {
            Err(_) => Ok(()),
            Ok(_) => Err(OutputError::NotOurs { path: path.to_path_buf(), by }),
        };
    };
    let mut start = Vec::with_capacity(MARK_WITHIN);
    let ours = std::io::Read::read_to_end(&mut std::io::Read::take(file, MARK_WITHIN as u64), &mut start)
        .is_ok_and(|_| start.windows(mark.len()).any(|window| window == mark.as_bytes()));
    if ours { Ok(()) } else { Err(OutputError::NotOurs { path: path.to_path_buf(), by }) }
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

    /// A folder is held by one run at a time; a file where a folder goes is said as such.
    #[test]
    fn an_output_folder_is_held_by_one_run() {
        let dir = scratch("lock");
        let first = lock_folder(&dir).unwrap();
        assert!(matches!(lock_folder(&dir), Err(OutputError::Busy(_))));
        drop(first);
        let _again = lock_folder(&dir).unwrap();
        let file = dir.join("plain");
        std::fs::write(&file, b"x").unwrap();
        assert!(matches!(create_folder(&file), Err(OutputError::NotAFolder(_))));
        let slashed = PathBuf::from(format!("{}/", file.display()));
        assert!(matches!(create_folder(&slashed), Err(OutputError::NotAFolder(_))));
        assert!(matches!(
            create_folder(&file.join("below")),
            Err(OutputError::NotAFolder(_) | OutputError::CreateFolder { .. })
        ));
        let err = create_folder(&file).unwrap_err().to_string();
        assert!(err.ends_with("is a file, not a folder"), "{err}");
        create_folder(&dir.join("new/deeper")).unwrap();
        assert!(dir.join("new/deeper").is_dir());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A derived output is replaced only when it bears its program's mark.
    #[test]
    fn only_marked_files_are_replaced() {
        let dir = scratch("marks");
        let (ours, theirs) = (dir.join("ours.png"), dir.join("theirs.png"));
        std::fs::write(&ours, b"\x89PNG....tEXtSoftware\0supersvg eval....").unwrap();
        std::fs::write(&theirs, b"\x89PNG....a holiday picture").unwrap();
        check_replaceable(&ours, "supersvg eval", "eval").unwrap();
        check_replaceable(&dir.join("absent.png"), "supersvg eval", "eval").unwrap();
        let err = check_replaceable(&theirs, "supersvg eval", "eval").unwrap_err();
        assert!(matches!(err, OutputError::NotOurs { .. }), "{err}");
        assert!(err.to_string().contains("not written by eval"), "{err}");
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
