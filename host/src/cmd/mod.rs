//! One module per `vinebench` subcommand: its arguments and its `run`; and what they share:
//! [`out!`] (standard output that a closed pipe does not break) and [`Exit`] (the exit code
//! of a command that ran but must not say success).
//!
//! Exit codes (docs/cli.md): 0 success; 1 an error (bad input, a file, a plugin that could
//! not be resolved), with one line on standard error naming the culprit; 2 a usage error
//! (clap); 3 the command ran but some runs or checks failed (`--allow-failures` makes that
//! 0); 130 interrupted by Ctrl-C (SIGINT), after saying what it kept.

pub use crate::exit::Exit;

/// Writes one line to standard output; a closed output (`vinebench bench … | head -2`) is
/// not an error: the command goes on and keeps what it finishes.
pub fn print_line(args: std::fmt::Arguments<'_>) {
    use std::io::Write as _;
    let mut stdout = std::io::stdout().lock();
    let _ = stdout
        .write_fmt(args)
        .and_then(|()| stdout.write_all(b"\n"))
        .and_then(|()| stdout.flush());
}

/// `println!` that a closed standard output does not turn into a panic ([`print_line`]).
#[macro_export]
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::cmd::print_line(format_args!($($arg)*))
    };
}
pub use crate::out;

pub mod bench;
pub mod check_plugin;
pub mod eval;
pub mod export;
pub mod gnss_map;
pub mod localize;
pub mod plugins;
pub mod progress;
pub mod record;
pub mod report;
pub mod rescore;
pub mod run;
pub mod sim_args;
pub mod simulate;
pub mod sweep;
pub mod worker;
pub mod world;
