//! Helpers for the command-line tests of every crate (behind the `testing` feature, which
//! only dev-dependencies turn on).

use std::process::{Child, Output};
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
