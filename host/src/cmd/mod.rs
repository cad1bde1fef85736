//! One module per `vinebench` subcommand: its arguments and its `run`.

pub mod bench;
pub mod eval;
pub mod plugins;
pub mod run;
pub mod simulate;
pub mod worker;
