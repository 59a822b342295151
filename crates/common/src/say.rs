//! Messages on stderr that never panic. `eprintln!` panics when stderr is gone (`2>&-`,
//! `2>/dev/full`, `2>&1 | head -1`), which would end a program in the middle of its work; a
//! message that cannot be shown is dropped instead, the work goes on and the exit status still
//! says how it went.

use std::io::Write;

/// Writes one line on stderr, dropping it when stderr cannot take it.
pub fn line(message: std::fmt::Arguments) {
    let _ = writeln!(std::io::stderr().lock(), "{message}");
}

/// Writes one line on stdout, and whether it was written (a reader that went away, `| head`,
/// is no reason to panic; the caller decides what it means).
pub fn out(message: std::fmt::Arguments) -> bool {
    let mut stdout = std::io::stdout().lock();
    writeln!(stdout, "{message}").and_then(|()| stdout.flush()).is_ok()
}

/// `eprintln!` that never panics: the line is dropped when stderr is gone ([`line`]).
#[macro_export]
macro_rules! say {
    ($($arg:tt)*) => { $crate::say::line(format_args!($($arg)*)) };
}

/// An error and its causes in one line, `outer: inner: …`, leaving out a cause whose words the
/// line already holds (an error that names its cause in its own message, as most here do, is
/// not followed by the same words again).
pub fn chain(error: &(dyn std::error::Error + 'static)) -> String {
    let mut line = error.to_string();
    let mut cause = error.source();
    while let Some(inner) = cause {
        let words = inner.to_string();
        if !line.contains(&words) {
            line.push_str(": ");
            line.push_str(&words);
        }
        cause = inner.source();
    }
    line
}

#[cfg(test)]
mod tests {
    #[derive(Debug, thiserror::Error)]
    #[error("out.svg: cannot write in .: {source}")]
    struct Outer {
        source: std::io::Error,
    }

    #[derive(Debug, thiserror::Error)]
    #[error("writing the report")]
    struct Context {
        source: std::io::Error,
    }

    /// A cause already said is not said again; one not yet said is added.
    #[test]
    fn causes_are_said_once() {
        let said = || std::io::Error::other("Read-only file system (os error 30)");
        assert_eq!(
            super::chain(&Outer { source: said() }),
            "out.svg: cannot write in .: Read-only file system (os error 30)"
        );
        assert_eq!(
            super::chain(&Context { source: said() }),
            "writing the report: Read-only file system (os error 30)"
        );
    }
}
