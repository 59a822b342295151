//! Helpers for the command-line tests of every crate (behind the `testing` feature, which
//! only dev-dependencies turn on).

use std::io::{BufRead, BufReader};
use std::process::{Child, Output};
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

/// Waits for `child` at most `seconds` and returns what it printed; past that it is killed
/// and the test fails, so a program that hangs fails its test instead of stalling CI.
///
/// # Panics
/// When the child is still running after `seconds`, or cannot be waited for.
pub fn wait_within(mut child: Child, seconds: u64) -> Output {
    let deadline = Instant::now() + Duration::from_secs(seconds);
    while child.try_wait().expect("the child can be polled").is_none() {
        if Instant::now() > deadline {
            child.kill().expect("the child can be killed");
            panic!("still running after {seconds} s");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().expect("the child's output can be read")
}

/// The lines `child` writes on stderr, as they come (its stderr, which must be piped, taken):
/// what a test reads a program's readiness from before it signals it.
///
/// # Panics
/// When the child's stderr is not piped.
pub fn stderr_lines(child: &mut Child) -> Receiver<String> {
    let stderr = child.stderr.take().expect("stderr is piped");
    let (send, lines) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if send.send(line).is_err() {
                break;
            }
        }
    });
    lines
}

/// Waits for a line of `lines` that holds `text`, at most `seconds`.
///
/// # Panics
/// When the program ends or the time runs out first, with every line seen.
pub fn wait_for(lines: &Receiver<String>, text: &str, seconds: u64) {
    let mut seen = Vec::new();
    loop {
        match lines.recv_timeout(Duration::from_secs(seconds)) {
            Ok(line) if line.contains(text) => return,
            Ok(line) => seen.push(line),
            Err(err) => panic!("no line with {text:?} ({err}): {seen:#?}"),
        }
    }
}
