//! Runs one job in a child process (this same binary, `vinebench worker`) with a timeout,
//! and turns however it ended into a one-line reason: a panic, abort, segfault, hang or
//! runaway allocation in a plugin costs that run only.

use std::io::{BufRead, BufReader};
use std::os::unix::process::ExitStatusExt;
use std::path::Path;
use std::process::{Child, ChildStdin, Command, Stdio};
use std::time::{Duration, Instant};

use crate::results::files;

/// How often the child is checked on.
const POLL: Duration = Duration::from_millis(20);
/// How long a worker's death by a stop signal waits for the supervisor's own stop
/// (`interrupt::interrupted_within`) before it counts as the plugin's failure.
const INTERRUPT_GRACE: Duration = Duration::from_millis(500);

/// Runs the worker on the job file in `run_dir` (absolute), in that folder; `progress(fraction)` is called as it
/// advances. `Err` is the failure reason.
pub fn supervise(
    run_dir: &Path,
    base_dir: Option<&Path>,
    timeout: Duration,
    memory_limit_mb: u64,
    progress: &(dyn Fn(f64) + Sync),
) -> Result<(), String> {
    let (child, _) = spawn(run_dir, false, base_dir)?;
    watch(child, run_dir, timeout, memory_limit_mb, progress)
}

/// How a run's failure reason begins when its worker could not be started (the executable
/// gone or replaced by a rebuild, no processes left): the host's failure, not the plugin's.
pub const CANNOT_START: &str = "cannot start the worker process";

/// Whether a run's failure reason is the host's, not the plugin's: its worker could not be
/// started, or the recording it was to replay could not be made. A sweep does not file such
/// a run, so that resuming it runs it (as an interrupted one).
pub fn is_start_failure(reason: &str) -> bool {
    reason.starts_with(CANNOT_START) || reason.starts_with(super::record::CANNOT_RECORD)
}

/// Starts the worker on the job file in `run_dir` (absolute), in that folder. With `fed`,
/// its stdin is a pipe, returned for the caller to stream the simulation into
/// ([`super::feed`]); otherwise it reads nothing. `base_dir` (absolute), the folder the
/// plugin's relative paths are relative to, is its `VINEBENCH_BENCH_DIR`.
pub fn spawn(
    run_dir: &Path,
    fed: bool,
    base_dir: Option<&Path>,
) -> Result<(Child, Option<ChildStdin>), String> {
    let exe = std::env::current_exe().map_err(|e| format!("{CANNOT_START}: {e}"))?;
    let log_path = run_dir.join(files::LOG);
    let log =
        std::fs::File::create(&log_path).map_err(|e| format!("{}: {e}", log_path.display()))?;
    // The worker runs in its run folder, so a relative output path in a plugin's
    // parameters (lio-sam's `profile_csv`, say) lands beside the run's other files.
    let mut command = Command::new(exe);
    // A process group of its own: the terminal's Ctrl-C reaches the supervisor only, which
    // stops the workers itself and keeps what has finished (`super::interrupt`).
    std::os::unix::process::CommandExt::process_group(&mut command, 0);
    if let Some(dir) = base_dir {
        command.env("VINEBENCH_BENCH_DIR", dir);
    }
    let mut child = command
        .current_dir(run_dir)
        .arg("worker")
        .arg("--job")
        .arg(run_dir.join(files::JOB))
        .stdin(if fed { Stdio::piped() } else { Stdio::null() })
        .stdout(Stdio::piped())
        .stderr(log)
        .spawn()
        .map_err(|e| format!("{CANNOT_START}: {e}"))?;
    let stdin = child.stdin.take();
    Ok((child, stdin))
}

/// Watches a worker started by [`spawn`] until it ends, killing it at `timeout`; `Err` is
/// the failure reason.
pub fn watch(
    mut child: Child,
    run_dir: &Path,
    timeout: Duration,
    memory_limit_mb: u64,
    progress: &(dyn Fn(f64) + Sync),
) -> Result<(), String> {
    let log_path = run_dir.join(files::LOG);
    let stdout = child.stdout.take().expect("stdout is piped");
    let started = Instant::now();
    std::thread::scope(|scope| {
        scope.spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                let mut parts = line.split_whitespace();
                if parts.next() == Some("progress") {
                    let at: f64 = parts.next().and_then(|v| v.parse().ok()).unwrap_or(0.0);
                    let total: f64 = parts.next().and_then(|v| v.parse().ok()).unwrap_or(1.0);
                    progress((at / total.max(1.0)).clamp(0.0, 1.0));
                }
            }
        });
        let status = loop {
            match child.try_wait() {
                Ok(Some(status)) => break status,
                Ok(None) if started.elapsed() > timeout => {
                    let _ = child.kill();
                    let _ = child.wait();
                    return Err(format!("timed out after {} s", timeout.as_secs_f64()));
                }
                Ok(None) if super::interrupt::interrupted() => {
                    let _ = child.kill();
                    let _ = child.wait();
                    return Err(super::interrupt::REASON.to_owned());
                }
                Ok(None) => std::thread::sleep(POLL),
                Err(e) => return Err(format!("lost the worker process: {e}")),
            }
        };
        if status.success() {
            return Ok(());
        }
        // A stop signal that reached the worker with the supervisor (`pkill vinebench`, a
        // terminal's group) is the user's stop, not the plugin's failure: not filed.
        if matches!(status.signal(), Some(1 | 2 | 15))
            && super::interrupt::interrupted_within(INTERRUPT_GRACE)
        {
            return Err(super::interrupt::REASON.to_owned());
        }
        let log = std::fs::read_to_string(&log_path).unwrap_or_default();
        Err(reason(status, &log, memory_limit_mb))
    })
}

/// The last line the worker printed as an error, if any.
fn error_line(log: &str) -> Option<&str> {
    log.lines().rev().find_map(|l| l.strip_prefix("error: "))
}

fn reason(status: std::process::ExitStatus, log: &str, memory_limit_mb: u64) -> String {
    if log.contains("memory allocation of") {
        return format!("out of memory (limit {memory_limit_mb} MiB)");
    }
    let panic = log
        .lines()
        .find(|l| l.contains("panicked at"))
        .map(str::to_owned);
    match status.signal() {
        Some(11) => "crashed: segmentation fault (SIGSEGV)".into(),
        Some(7) => "crashed: bus error (SIGBUS)".into(),
        Some(6) => match panic {
            Some(p) => format!("aborted after a panic: {}", p.trim()),
            None => "aborted (SIGABRT)".into(),
        },
        Some(9) => "killed (SIGKILL; out of memory?)".into(),
        Some(sig) => format!("killed by signal {sig}"),
        None => error_line(log).map(str::to_owned).unwrap_or_else(|| {
            format!("worker exited with status {}", status.code().unwrap_or(-1))
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sweep files every failed run but these two kinds; the reason a failed start gives
    /// is the one it recognises, and a plugin's own failure is not mistaken for it.
    #[test]
    fn a_failed_start_is_told_from_a_plugins_failure() {
        let missing = std::io::Error::from(std::io::ErrorKind::NotFound);
        assert!(is_start_failure(&format!("{CANNOT_START}: {missing}")));
        for plugin_failure in [
            "timed out after 600 s",
            "plugin lio-sam failed to start: bad parameter",
            "the worker exited with signal 11 (SIGSEGV)",
        ] {
            assert!(!is_start_failure(plugin_failure), "{plugin_failure}");
        }
    }
}
