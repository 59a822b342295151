//! Writing results without ever leaving a partial file behind.

use std::io::Write;
use std::path::Path;

use image::RgbImage;

/// Writes `bytes` to `path` through a temporary file in the same folder that is renamed over
/// `path` once complete: a failure leaves either the old file or none, never half a file.
///
/// Only a regular file (or nothing) is replaced that way. Anything else that exists at `path` —
/// a symbolic link, a device such as `/dev/stdout`, a pipe — is opened and written to as it is
/// (renaming over it would replace the link or the device with a file); a folder is an error.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    if let Ok(metadata) = std::fs::symlink_metadata(path) {
        if metadata.is_dir() {
            return Err(std::io::Error::other("is a folder"));
        }
        if !metadata.is_file() {
            let mut file = std::fs::OpenOptions::new().write(true).truncate(true).open(path)?;
            return file.write_all(bytes).and_then(|()| file.flush());
        }
    }
    let folder = folder_of(path);
    let name = path.file_name().ok_or_else(|| std::io::Error::other("not a file path"))?;
    let temporary = folder.join(format!(".{}.{}.tmp", name.to_string_lossy(), std::process::id()));
    let result = std::fs::File::create(&temporary)
        .and_then(|mut file| file.write_all(bytes).and_then(|()| file.sync_all()))
        .and_then(|()| std::fs::rename(&temporary, path));
    if result.is_err() {
        let _ = std::fs::remove_file(&temporary);
    }
    result
}

/// The folder `path` is in (`.` for a bare file name).
pub fn folder_of(path: &Path) -> &Path {
    path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."))
}

/// Encodes `image` as PNG and writes it atomically.
pub fn write_png(path: &Path, image: &RgbImage) -> std::io::Result<()> {
    let mut bytes = Vec::new();
    image
        .write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Png)
        .map_err(std::io::Error::other)?;
    write_atomic(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replaces_whole_files_and_leaves_nothing_on_failure() {
        let dir = std::env::temp_dir().join(format!("supersvg-write-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("out.svg");
        write_atomic(&file, b"first").unwrap();
        write_atomic(&file, b"second").unwrap();
        assert_eq!(std::fs::read(&file).unwrap(), b"second");
        let missing = dir.join("no/such/folder/out.svg");
        assert!(write_atomic(&missing, b"x").is_err());
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1, "no temporary file is left");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[cfg(unix)]
    #[test]
    fn links_and_devices_are_written_through_not_replaced() {
        use std::os::unix::fs::FileTypeExt;
        let dir = std::env::temp_dir().join(format!("supersvg-write-links-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let target = dir.join("target.svg");
        std::fs::write(&target, b"old").unwrap();
        let link = dir.join("link.svg");
        std::os::unix::fs::symlink(&target, &link).unwrap();
        write_atomic(&link, b"new").unwrap();
        assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink(), "the link stays a link");
        assert_eq!(std::fs::read(&target).unwrap(), b"new");
        write_atomic(Path::new("/dev/null"), b"discarded").unwrap();
        assert!(std::fs::metadata("/dev/null").unwrap().file_type().is_char_device());
        assert!(write_atomic(&dir, b"x").is_err(), "a folder is not overwritten");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
