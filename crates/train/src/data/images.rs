//! A folder of training images, decoded once at the training size and kept in memory.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use common::decode::{LoadOptions, open};
use image::Rgb32FImage;
use rayon::prelude::*;

use super::source::DataError;

pub(crate) const EXTENSIONS: [&str; 9] = ["png", "jpg", "jpeg", "webp", "gif", "bmp", "tif", "tiff", "tga"];

/// Every readable image under a folder, read as inference reads its input (turned by its EXIF
/// orientation, over white, scaled down to a long side in floating point): a region of a
/// training image is the region inference would cut from the same file at that size.
pub struct ImageSet {
    images: Vec<Rgb32FImage>,
}

impl ImageSet {
    /// Reads every image under `folder` (recursively, in sorted order), scaling those larger
    /// than `long_side`. Unreadable files are skipped with one warning each; a folder without a
    /// single readable image is an error.
    pub fn load(folder: &Path, long_side: u32) -> Result<Self, DataError> {
        if !folder.is_dir() {
            return Err(DataError::NotAFolder(folder.to_path_buf()));
        }
        let mut files = Vec::new();
        collect_files(folder, &mut HashSet::new(), &mut files);
        files.sort();
        let options = LoadOptions { long_side, ..LoadOptions::default() };
        let decoded: Vec<Option<Rgb32FImage>> = files
            .par_iter()
            .map(|path| match open(path, &options) {
                _ if crate::stop::interrupted() => None,
                Ok(loaded) => Some(loaded.image),
                Err(err) => {
                    common::say!("warning: skipping {err}");
                    None
                }
            })
            .collect();
        if crate::stop::interrupted() {
            return Err(DataError::Interrupted(folder.to_path_buf()));
        }
        let images: Vec<Rgb32FImage> = decoded.into_iter().flatten().collect();
        if images.is_empty() {
            return Err(DataError::NoImages(folder.to_path_buf()));
        }
        Ok(Self { images })
    }

    /// Number of images.
    pub fn len(&self) -> usize {
        self.images.len()
    }

    /// Whether the set is empty (never, once loaded).
    pub fn is_empty(&self) -> bool {
        self.images.is_empty()
    }

    /// Image `index`, RGB in [0, 1].
    pub fn get(&self, index: usize) -> &Rgb32FImage {
        &self.images[index]
    }

    /// The pixels of the largest image.
    pub fn largest_pixels(&self) -> usize {
        self.images.iter().map(|image| image.width() as usize * image.height() as usize).max().unwrap_or(0)
    }
}

/// The image files under `folder`, recursively; each folder is read once however many links
/// lead to it (`seen` holds the folders read, resolved), so a link loop ends.
fn collect_files(folder: &Path, seen: &mut HashSet<PathBuf>, files: &mut Vec<PathBuf>) {
    let Ok(resolved) = std::fs::canonicalize(folder) else { return };
    if !seen.insert(resolved) {
        return;
    }
    let Ok(entries) = std::fs::read_dir(folder) else { return };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            collect_files(&path, seen, files);
        } else if path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
        {
            // A pipe would block its reader for ever, a device such as /dev/zero never ends.
            if path.is_file() {
                files.push(path);
            } else {
                common::say!(
                    "warning: skipping {}: not a regular file (a pipe, a device or a dead link)",
                    path.display()
                );
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use image::RgbImage;

    use super::*;

    #[test]
    fn loads_readable_images_and_reports_empty_folders() {
        let dir = std::env::temp_dir().join(format!("supersvg-images-{}", std::process::id()));
        let nested = dir.join("nested");
        std::fs::create_dir_all(&nested).unwrap();
        let err = ImageSet::load(&dir, 64).err().unwrap();
        assert!(err.to_string().contains("no readable image"), "{err}");

        RgbImage::from_pixel(300, 100, image::Rgb([10, 20, 30])).save(nested.join("a.png")).unwrap();
        std::fs::write(dir.join("broken.jpg"), b"not a jpeg").unwrap();
        std::fs::write(dir.join("notes.txt"), b"ignored").unwrap();
        let set = ImageSet::load(&dir, 64).unwrap();
        let scaled = common::decode::load(&nested.join("a.png"), 64).unwrap().image;
        assert_eq!(set.get(0), &scaled, "the pixels inference reads from the same file");
        assert_eq!(set.len(), 1);
        assert_eq!(set.get(0).dimensions(), (64, 21));
        std::fs::remove_dir_all(&dir).unwrap();

        let err = ImageSet::load(&dir, 64).err().unwrap();
        assert!(matches!(err, DataError::NotAFolder(_)) && err.to_string().contains("not a folder"), "{err}");
    }

    #[cfg(unix)]
    #[test]
    fn pipes_and_devices_are_skipped_not_read() {
        let dir = std::env::temp_dir().join(format!("supersvg-images-fifo-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        RgbImage::from_pixel(20, 10, image::Rgb([1, 2, 3])).save(dir.join("a.png")).unwrap();
        let made = std::process::Command::new("mkfifo").arg(dir.join("pipe.png")).status().unwrap();
        assert!(made.success());
        std::os::unix::fs::symlink("/dev/zero", dir.join("zero.png")).unwrap();
        // On a thread, so that a reader blocked on the pipe fails the test instead of hanging it.
        let (done, result) = std::sync::mpsc::channel();
        let folder = dir.clone();
        std::thread::spawn(move || done.send(ImageSet::load(&folder, 64).map(|set| set.len())));
        let loaded = result.recv_timeout(std::time::Duration::from_secs(30)).expect("the loader blocked");
        assert_eq!(loaded.unwrap(), 1, "only the regular file");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[cfg(unix)]
    #[test]
    fn a_link_loop_is_read_once() {
        let dir = std::env::temp_dir().join(format!("supersvg-images-loop-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("a")).unwrap();
        RgbImage::from_pixel(20, 10, image::Rgb([1, 2, 3])).save(dir.join("a/x.png")).unwrap();
        std::os::unix::fs::symlink(&dir, dir.join("a/up")).unwrap();
        std::os::unix::fs::symlink(dir.join("a"), dir.join("also-a")).unwrap();
        let set = ImageSet::load(&dir, 64).unwrap();
        assert_eq!(set.len(), 1, "one image behind two links and a loop");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
