//! One module per `vinebench` subcommand: its arguments and its `run`.

pub mod bench;
pub mod eval;
pub mod export;
pub mod plugins;
pub mod progress;
pub mod record;
pub mod report;
pub mod run;
pub mod sim_args;
pub mod simulate;
pub mod sweep;
pub mod worker;
