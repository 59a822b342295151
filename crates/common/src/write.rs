//! Writing results without ever leaving a partial file behind, and without following a link
//! someone else planted where a temporary file goes. The temporaries being written are known,
//! so a program that is stopped ([`exit`]) lets them finish or removes them.

use std::fs::{File, OpenOptions};
use std::hash::{BuildHasher, Hasher};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Condvar, Mutex, PoisonError};
use std::time::{Duration, Instant};

use image::RgbImage;

/// Writes `bytes` to `path` through a temporary file in the same folder that is renamed over
/// `path` once complete and synced: a failure leaves either the old file or none, never half a
/// file, and no temporary.
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
            let mut file = OpenOptions::new().write(true).truncate(true).open(path)?;
            return file.write_all(bytes).and_then(|()| file.flush());
        }
    }
    let name = path.file_name().ok_or_else(|| std::io::Error::other("not a file path"))?;
    let (mut file, temporary) = create_temporary(folder_of(path), &name.to_string_lossy())?;
    file.write_all(bytes).and_then(|()| file.sync_all())?;
    temporary.rename_to(path)
}

/// Whether files can be created in `folder`: creates a temporary there (exclusively, never
/// through a link) and removes it.
pub fn probe_folder(folder: &Path) -> std::io::Result<()> {
    create_temporary(folder, "probe").map(drop)
}

/// The temporaries of this process being written now, and whether the process is ending
/// ([`exit`]): then no new one is made.
struct InFlight {
    paths: Vec<PathBuf>,
    closing: bool,
}

static IN_FLIGHT: Mutex<InFlight> = Mutex::new(InFlight { paths: Vec::new(), closing: false });
/// Signalled when a temporary is renamed into place or removed.
static SETTLED: Condvar = Condvar::new();

fn in_flight() -> std::sync::MutexGuard<'static, InFlight> {
    IN_FLIGHT.lock().unwrap_or_else(PoisonError::into_inner)
}

/// A temporary file being written: renamed into place ([`Temporary::rename_to`]) or, dropped
/// before that, removed.
struct Temporary {
    path: PathBuf,
}

impl Temporary {
    /// Registers `path` as in flight, unless the process is ending.
    fn register(path: PathBuf) -> std::io::Result<Self> {
        let mut in_flight = in_flight();
        if in_flight.closing {
            return Err(std::io::Error::other("the program is stopping"));
        }
        in_flight.paths.push(path.clone());
        Ok(Self { path })
    }

    /// Forgets the temporary without removing anything: its name was taken by a file not ours.
    fn disown(self) {
        let mut in_flight = in_flight();
        in_flight.paths.retain(|path| *path != self.path);
        drop(in_flight);
        std::mem::forget(self);
    }

    /// Renames the temporary over `path`: the file appears whole, at once.
    fn rename_to(self, path: &Path) -> std::io::Result<()> {
        std::fs::rename(&self.path, path)
    }
}

impl Drop for Temporary {
    fn drop(&mut self) {
        // Renamed, it is no longer there; otherwise it goes.
        let _ = std::fs::remove_file(&self.path);
        let mut in_flight = in_flight();
        in_flight.paths.retain(|path| *path != self.path);
        SETTLED.notify_all();
    }
}

/// How long [`exit`] lets the writes under way finish.
const WRITE_GRACE: Duration = Duration::from_secs(1);

/// Ends the process with `code`, as a stop does (Ctrl-C, SIGTERM): no new file is started, the
/// writes under way get [`WRITE_GRACE`] to finish, and the temporaries of any still going are
/// removed, so every file appears whole or not at all and none is left behind.
pub fn exit(code: i32) -> ! {
    let deadline = Instant::now() + WRITE_GRACE;
    let mut in_flight = in_flight();
    in_flight.closing = true;
    while !in_flight.paths.is_empty() {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            break;
        }
        in_flight = SETTLED.wait_timeout(in_flight, left).unwrap_or_else(PoisonError::into_inner).0;
    }
    for path in &in_flight.paths {
        let _ = std::fs::remove_file(path);
    }
    // Still holding the list: no other thread can start or finish a write now.
    std::process::exit(code)
}

/// How many names a temporary file tries before giving up: each is random, so a clash means
/// someone is planting names there.
const TEMPORARY_TRIES: usize = 16;

/// The longest file name (bytes) the common file systems take: a longer output name is refused
/// before any work instead of failing when the result is written.
pub const NAME_MAX: usize = 255;

/// A new file `.{stem}.{random}.tmp` in `folder`, created exclusively (`O_EXCL`: an existing
/// file or link of that name is never opened, so a planted link is never followed), and the
/// temporary it is. A stem too long for the name to fit [`NAME_MAX`] is cut short.
fn create_temporary(folder: &Path, stem: &str) -> std::io::Result<(File, Temporary)> {
    let stem = shortened(stem, NAME_MAX - TEMPORARY_EXTRA);
    // Registered before it exists, so that an exit in between removes it.
    let (file, temporary) = fresh(
        || folder.join(format!(".{stem}.{:016x}.tmp", random())),
        |path| {
            let temporary = Temporary::register(path.to_path_buf())?;
            match OpenOptions::new().write(true).create_new(true).open(path) {
                Ok(file) => Ok((file, temporary)),
                Err(err) => {
                    // Not ours: what is there stays.
                    temporary.disown();
                    Err(err)
                }
            }
        },
    )?
    .0;
    Ok((file, temporary))
}

/// What a temporary's name adds to its stem: `.`, `.`, 16 hexadecimal digits and `.tmp`.
const TEMPORARY_EXTRA: usize = 22;

/// The longest start of `text` of at most `bytes` bytes that ends on a character.
fn shortened(text: &str, bytes: usize) -> &str {
    let end = (0..=bytes.min(text.len())).rev().find(|&end| text.is_char_boundary(end)).unwrap_or(0);
    &text[..end]
}

/// A new folder `.{stem}.{random}` in `parent`, created exclusively (an existing folder or link
/// of that name is never used), for scratch files whose names other programs need to choose
/// (an extension a tool reads the format from): inside it, fixed names are safe.
pub fn create_temporary_folder(parent: &Path, stem: &str) -> std::io::Result<PathBuf> {
    fresh(|| parent.join(format!(".{stem}.{:016x}", random())), |path| std::fs::create_dir(path))
        .map(|((), path)| path)
}

/// `create` on names from `name` until one did not exist ([`TEMPORARY_TRIES`] at most): what
/// it made, and where.
fn fresh<T>(
    name: impl Fn() -> PathBuf,
    create: impl Fn(&Path) -> std::io::Result<T>,
) -> std::io::Result<(T, PathBuf)> {
    let mut last = None;
    for _ in 0..TEMPORARY_TRIES {
        let candidate = name();
        match create(&candidate) {
            Ok(made) => return Ok((made, candidate)),
            Err(err) if err.kind() == std::io::ErrorKind::AlreadyExists => last = Some(err),
            Err(err) => return Err(err),
        }
    }
    Err(last.unwrap_or_else(|| std::io::Error::other("no temporary name was free")))
}

/// 64 unpredictable bits: std's randomly keyed hasher over the process, the time and a counter.
fn random() -> u64 {
    use std::sync::atomic::{AtomicU64, Ordering};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let mut hasher = std::collections::hash_map::RandomState::new().build_hasher();
    hasher.write_u32(std::process::id());
    hasher.write_u64(COUNTER.fetch_add(1, Ordering::Relaxed));
    if let Ok(since) = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH) {
        hasher.write_u128(since.as_nanos());
    }
    hasher.finish()
}

/// The folder `path` is in (`.` for a bare file name).
pub fn folder_of(path: &Path) -> &Path {
    path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."))
}

/// `image` encoded as PNG.
pub fn png_bytes(image: &RgbImage) -> Vec<u8> {
    let mut bytes = Vec::new();
    image
        .write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Png)
        .expect("an RGB image encodes to memory");
    bytes
}

/// Encodes `image` as PNG and writes it atomically.
pub fn write_png(path: &Path, image: &RgbImage) -> std::io::Result<()> {
    write_atomic(path, &png_bytes(image))
}

/// Encodes `image` as PNG with `software` in its `Software` text chunk, which comes before the
/// pixels, and writes it atomically: a file a program can tell it wrote
/// ([`crate::outputs::check_replaceable`]).
pub fn write_png_marked(path: &Path, image: &RgbImage, software: &str) -> std::io::Result<()> {
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, image.width(), image.height());
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.add_text_chunk("Software".into(), software.into()).map_err(std::io::Error::other)?;
    let mut writer = encoder.write_header().map_err(std::io::Error::other)?;
    writer.write_image_data(image.as_raw()).map_err(std::io::Error::other)?;
    writer.finish().map_err(std::io::Error::other)?;
    write_atomic(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("supersvg-write-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn replaces_whole_files_and_leaves_nothing_on_failure() {
        let dir = scratch("whole");
        let file = dir.join("out.svg");
        write_atomic(&file, b"first").unwrap();
        write_atomic(&file, b"second").unwrap();
        assert_eq!(std::fs::read(&file).unwrap(), b"second");
        let missing = dir.join("no/such/folder/out.svg");
        assert!(write_atomic(&missing, b"x").is_err());
        probe_folder(&dir).unwrap();
        assert!(probe_folder(&dir.join("no/such")).is_err());
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1, "no temporary file is left");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[cfg(unix)]
    #[test]
    fn links_and_devices_are_written_through_not_replaced() {
        use std::os::unix::fs::FileTypeExt;
        let dir = scratch("links");
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

    /// A marked PNG reads back as the image, and holds its mark where the check looks.
    #[test]
    fn marked_pngs_read_back_and_carry_their_mark() {
        let dir = scratch("marked");
        let file = dir.join("sheet.png");
        let image = RgbImage::from_fn(7, 5, |x, y| image::Rgb([x as u8 * 30, y as u8 * 40, 9]));
        write_png_marked(&file, &image, "supersvg eval").unwrap();
        assert_eq!(image::open(&file).unwrap().to_rgb8(), image);
        crate::outputs::check_replaceable(&file, "supersvg eval", "eval").unwrap();
        assert!(crate::outputs::check_replaceable(&file, "supersvg tune", "tune").is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A temporary dropped before it is renamed into place is removed.
    #[test]
    fn a_temporary_dropped_is_removed() {
        let dir = scratch("dropped");
        let (file, temporary) = create_temporary(&dir, "out.svg").unwrap();
        let path = temporary.path.clone();
        drop(file);
        assert!(path.exists());
        drop(temporary);
        assert!(!path.exists());
        assert!(in_flight().paths.iter().all(|p| *p != path), "still registered");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn temporaries_are_new_files_with_unpredictable_names() {
        let dir = scratch("names");
        let (_, first) = create_temporary(&dir, "out.svg").unwrap();
        let (_, second) = create_temporary(&dir, "out.svg").unwrap();
        let (first, second) = (first.path.clone(), second.path.clone());
        assert_ne!(first, second);
        let name = first.file_name().unwrap().to_string_lossy().into_owned();
        assert!(name.starts_with(".out.svg.") && name.ends_with(".tmp"), "{name}");
        let (first, second) =
            (create_temporary_folder(&dir, "work").unwrap(), create_temporary_folder(&dir, "work").unwrap());
        assert_ne!(first, second);
        assert!(first.is_dir() && std::fs::read_dir(&first).unwrap().count() == 0);
        assert!(first.file_name().unwrap().to_string_lossy().starts_with(".work."));
        assert!(create_temporary_folder(&dir.join("missing"), "work").is_err());
        // A stem too long for the file system is cut short, on a character.
        let (_, long) = create_temporary(&dir, &"é".repeat(200)).unwrap();
        let name = long.path.file_name().unwrap().to_string_lossy().into_owned();
        assert!(name.len() <= NAME_MAX && name.starts_with(".éé"), "{}", name.len());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
