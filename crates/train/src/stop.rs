//! A stop asked for by a signal: Ctrl-C, SIGTERM or SIGHUP end training with a checkpoint, and
//! the data loader hears them too (a stop while images are decoded ends the program cleanly).

use std::sync::atomic::{AtomicBool, Ordering};

static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// Makes Ctrl-C, SIGTERM and SIGHUP (what `timeout`, Slurm and `docker stop` send) request a
/// checkpoint and a clean stop; installed once per process, by the programs before they read
/// their data, so a stop while images are decoded is heard too.
pub fn catch_interrupts() {
    static INSTALLED: std::sync::Once = std::sync::Once::new();
    INSTALLED.call_once(|| {
        // Without a handler (another one installed), Ctrl-C simply ends the process.
        let _ = ctrlc::set_handler(|| INTERRUPTED.store(true, Ordering::SeqCst));
    });
}

/// Whether a stop was requested ([`catch_interrupts`]).
pub fn interrupted() -> bool {
    INTERRUPTED.load(Ordering::SeqCst)
}
