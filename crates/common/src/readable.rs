//! Opening an input for reading without ever blocking on the open: a named pipe that no program
//! writes to would otherwise hold `open(2)` forever. Regular files are opened as usual; anything
//! else that can be read (a pipe, `<(…)`, `/dev/stdin`, a device) is opened without waiting
//! for a writer and then read as a stream, which ends at once when nobody writes to it.

use std::fs::File;
use std::io::Read;
use std::path::Path;

/// An input opened for reading ([`open`]).
#[derive(Debug)]
pub enum Readable {
    /// A regular file: it can seek, and its length is known.
    File(File),
    /// A pipe, a device or a socket: read it whole, once ([`read_whole`]).
    Stream(File),
}

/// Opens `path` for reading. A folder is an error ([`std::io::ErrorKind::IsADirectory`]); what
/// is not a regular file is opened without waiting for a writer, then read blocking (a pipe
/// with a writer waits for its data; one without ends at once).
pub fn open(path: &Path) -> std::io::Result<Readable> {
    let metadata = std::fs::metadata(path)?;
    if metadata.is_dir() {
        return Err(std::io::Error::new(std::io::ErrorKind::IsADirectory, "is a folder"));
    }
    if metadata.is_file() {
        return File::open(path).map(Readable::File);
    }
    open_stream(path).map(Readable::Stream)
}

#[cfg(unix)]
fn open_stream(path: &Path) -> std::io::Result<File> {
    use rustix::fs::{Mode, OFlags, fcntl_getfl, fcntl_setfl};
    let fd = rustix::fs::open(path, OFlags::RDONLY | OFlags::NONBLOCK | OFlags::CLOEXEC, Mode::empty())?;
    let flags = fcntl_getfl(&fd)?;
    fcntl_setfl(&fd, flags - OFlags::NONBLOCK)?;
    Ok(File::from(fd))
}

#[cfg(not(unix))]
fn open_stream(path: &Path) -> std::io::Result<File> {
    File::open(path)
}

/// Why a stream could not be read whole.
#[derive(Debug, thiserror::Error)]
pub enum StreamError {
    /// Reading failed.
    #[error("{0}")]
    Io(#[from] std::io::Error),
    /// Nothing came: an empty stream, or a named pipe that no program writes to.
    #[error("nothing to read: an empty stream, or a named pipe that no program writes to")]
    Empty,
    /// More than the caller's limit came.
    #[error("more than {} MiB from a stream (a pipe, stdin or a device); save it to a file first", .max >> 20)]
    TooLong {
        /// The limit, in bytes.
        max: u64,
    },
}

/// The whole of `stream`, at most `max` bytes: an endless stream (`/dev/zero`) ends with an
/// error, not with memory full.
pub fn read_whole(stream: impl Read, max: u64) -> Result<Vec<u8>, StreamError> {
    let mut bytes = Vec::new();
    stream.take(max + 1).read_to_end(&mut bytes)?;
    match bytes.len() as u64 {
        0 => Err(StreamError::Empty),
        len if len > max => Err(StreamError::TooLong { max }),
        _ => Ok(bytes),
    }
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;

    fn scratch(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("supersvg-readable-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// A named pipe nobody writes to is opened and read at once, as an empty stream; one with a
    /// writer is read to its end; a regular file opens as a file and a folder is refused.
    #[test]
    fn a_pipe_without_a_writer_never_blocks() {
        let dir = scratch("fifo");
        let fifo = dir.join("fifo");
        assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
        let started = std::time::Instant::now();
        let Readable::Stream(stream) = open(&fifo).unwrap() else { panic!("a pipe is a stream") };
        assert!(matches!(read_whole(stream, 1 << 20), Err(StreamError::Empty)));
        assert!(started.elapsed() < std::time::Duration::from_secs(5));

        let writer = {
            let fifo = fifo.clone();
            // A reader that gave up between the writer's open and its write leaves it a broken
            // pipe: it writes again (22 bytes go through a pipe in one piece).
            std::thread::spawn(move || while std::fs::write(&fifo, b"written through a pipe").is_err() {})
        };
        // The writer's open waits for a reader: read until the pipe had a writer and data came.
        let read = loop {
            let Readable::Stream(stream) = open(&fifo).unwrap() else { panic!("a stream") };
            match read_whole(stream, 1 << 20) {
                Ok(bytes) => break bytes,
                Err(StreamError::Empty) => std::thread::sleep(std::time::Duration::from_millis(10)),
                Err(err) => panic!("{err}"),
            }
        };
        writer.join().unwrap();
        assert_eq!(read, b"written through a pipe");

        std::fs::write(dir.join("file"), b"x").unwrap();
        assert!(matches!(open(&dir.join("file")).unwrap(), Readable::File(_)));
        assert_eq!(open(&dir).unwrap_err().kind(), std::io::ErrorKind::IsADirectory);
        let Readable::Stream(zero) = open(Path::new("/dev/zero")).unwrap() else { panic!("a device") };
        assert!(matches!(read_whole(zero, 1 << 16), Err(StreamError::TooLong { max: 65536 })));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
