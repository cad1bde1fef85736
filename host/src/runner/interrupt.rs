//! Ctrl-C (SIGINT, and SIGTERM, SIGHUP) during a bench, run or sweep: the first asks the
//! runner to stop — no new run starts, the running workers are killed, and the command keeps
//! what has finished (a bench's partial folder, a sweep's filed runs) and says so; a second
//! one ends the process at once.
//!
//! Workers run in process groups of their own (`supervise::spawn`), so the terminal's
//! Ctrl-C reaches the supervisor only, which decides what to keep.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

static INTERRUPTED: AtomicBool = AtomicBool::new(false);
static SIGNALS: AtomicUsize = AtomicUsize::new(0);

/// The reason an interrupted run carries: not a failure of the plugin, and not kept.
pub const REASON: &str = "interrupted (Ctrl-C)";

/// Installs the handler (once; later calls do nothing).
pub fn install() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let installed = ctrlc::set_handler(|| {
            if SIGNALS.fetch_add(1, Ordering::SeqCst) == 0 {
                INTERRUPTED.store(true, Ordering::SeqCst);
                let _ = std::io::Write::write_all(
                    &mut std::io::stderr(),
                    b"\ninterrupted: stopping the running workers and keeping what has finished (Ctrl-C again to quit at once)\n",
                );
            } else {
                // The user insists: nothing more is kept.
                #[allow(clippy::disallowed_methods)]
                std::process::exit(130);
            }
        });
        if let Err(e) = installed {
            eprintln!("warning: Ctrl-C will not be handled: {e}");
        }
    });
}

/// Whether a stop was asked for.
pub fn interrupted() -> bool {
    INTERRUPTED.load(Ordering::SeqCst)
}

/// Whether a stop is asked for within `within`: for a worker that died of SIGINT, SIGTERM
/// or SIGHUP, which a terminal's or `pkill`'s signal may deliver to it a moment before the
/// supervisor's handler has run.
pub fn interrupted_within(within: std::time::Duration) -> bool {
    let started = std::time::Instant::now();
    loop {
        if interrupted() {
            return true;
        }
        if started.elapsed() >= within {
            return false;
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
}

/// Whether a run's failure reason is an interruption rather than the plugin's doing.
pub fn is_interruption(reason: &str) -> bool {
    reason == REASON
}
