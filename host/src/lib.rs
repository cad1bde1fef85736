//! The vinebench host library: everything the `vinebench` binary does, as functions that
//! tests can call.

pub mod bench_config;
pub mod cmd;
pub mod conformance;
pub mod dataset;
pub mod dump;
pub mod exit;
pub mod plugins;
pub mod report;
pub mod results;
pub mod rig;
pub mod runner;
pub mod sweep;
pub mod topview;
