//! A stop asked for by a signal: Ctrl-C, SIGTERM or SIGHUP end training with a checkpoint, and
//! the data loader, the teacher and the scoring hear them too.
//!
//! One stop is one stop: a signal delivered again (`timeout` signals the program and then its
//! process group) changes nothing. A stop the program has not heard within [`GRACE`] (work that
//! does not look at [`interrupted`] often enough) ends the process there, every file it wrote
//! whole ([`common::write::exit`]), its last checkpoint standing: no setting makes a trainer
//! ignore a stop.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use common::say;

static INTERRUPTED: AtomicBool = AtomicBool::new(false);
static HEARD: AtomicBool = AtomicBool::new(false);

/// How long a stop may go unheard ([`heard`]) before the process ends without saving.
pub const GRACE: Duration = Duration::from_secs(2);

/// Makes Ctrl-C, SIGTERM and SIGHUP (what `timeout`, Slurm and `docker stop` send) request a
/// checkpoint and a clean stop; installed once per process, by the programs before they read
/// their data, so a stop while images are decoded is heard too.
pub fn catch_interrupts() {
    static INSTALLED: std::sync::Once = std::sync::Once::new();
    INSTALLED.call_once(|| {
        // Without a handler (another one installed), Ctrl-C simply ends the process.
        let _ = ctrlc::set_handler(|| {
            if INTERRUPTED.swap(true, Ordering::SeqCst) {
                return;
            }
            std::thread::spawn(|| {
                std::thread::sleep(GRACE);
                if !HEARD.load(Ordering::SeqCst) {
                    say!(
                        "stopped: no checkpoint could be saved in time (the last one saved, if any, stands)"
                    );
                    common::write::exit(130);
                }
            });
        });
    });
}

/// Whether a stop was requested ([`catch_interrupts`]).
pub fn interrupted() -> bool {
    INTERRUPTED.load(Ordering::SeqCst)
}

/// Says that the stop was heard: the caller saves what it did and ends right after, and the
/// [`GRACE`] period no longer cuts that short.
pub fn heard() {
    HEARD.store(true, Ordering::SeqCst);
}
