//! A folder of training images, decoded once and kept small in memory.

use std::path::{Path, PathBuf};

use image::imageops::FilterType;
use image::{Rgb32FImage, RgbImage};
use rayon::prelude::*;

use super::source::DataError;

pub(crate) const EXTENSIONS: [&str; 9] = ["png", "jpg", "jpeg", "webp", "gif", "bmp", "tif", "tiff", "tga"];

/// Every readable image under a folder, scaled down to a long side, as 8-bit RGB over white.
pub struct ImageSet {
    images: Vec<RgbImage>,
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
        collect_files(folder, &mut files);
        files.sort();
        let decoded: Vec<Option<RgbImage>> = files
            .par_iter()
            .map(|path| match read(path, long_side) {
                Ok(image) => Some(image),
                Err(err) => {
                    eprintln!("warning: skipping {}: {err}", path.display());
                    None
                }
            })
            .collect();
        let images: Vec<RgbImage> = decoded.into_iter().flatten().collect();
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

    /// Image `index` as RGB in [0, 1].
    pub fn get(&self, index: usize) -> Rgb32FImage {
        image::DynamicImage::ImageRgb8(self.images[index].clone()).to_rgb32f()
    }
}

fn collect_files(folder: &Path, files: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(folder) else { return };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            collect_files(&path, files);
        } else if path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
        {
            files.push(path);
        }
    }
}

/// Why a training image was skipped.
#[derive(Debug, thiserror::Error)]
enum ReadError {
    /// The file cannot be opened.
    #[error("{0}")]
    Io(std::io::Error),
    /// The decoder refused it.
    #[error("{0}")]
    Decode(image::ImageError),
    /// Its pixels could not be turned into RGB.
    #[error("{0}")]
    Pixels(superpixel::InputError),
}

fn read(path: &Path, long_side: u32) -> Result<RgbImage, ReadError> {
    let decoded = image::ImageReader::open(path)
        .and_then(|reader| reader.with_guessed_format())
        .map_err(ReadError::Io)?
        .decode()
        .map_err(ReadError::Decode)?;
    let rgb = superpixel::to_rgb_over_white(&decoded).map_err(ReadError::Pixels)?;
    let rgb8 = image::DynamicImage::ImageRgb32F(rgb).to_rgb8();
    let (w, h) = rgb8.dimensions();
    if w.max(h) <= long_side {
        return Ok(rgb8);
    }
    let scale = long_side as f32 / w.max(h) as f32;
    let (nw, nh) = (((w as f32 * scale).round() as u32).max(1), ((h as f32 * scale).round() as u32).max(1));
    Ok(image::imageops::resize(&rgb8, nw, nh, FilterType::Triangle))
}

#[cfg(test)]
mod tests {
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
        assert_eq!(set.len(), 1);
        assert_eq!(set.get(0).dimensions(), (64, 21));
        std::fs::remove_dir_all(&dir).unwrap();

        let err = ImageSet::load(&dir, 64).err().unwrap();
        assert!(matches!(err, DataError::NotAFolder(_)) && err.to_string().contains("not a folder"), "{err}");
    }
}
