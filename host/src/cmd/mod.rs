//! One module per `vinebench` subcommand: its arguments and its `run`.

pub mod eval;
pub mod simulate;
