//! The vinebench host library: everything the `vinebench` binary does, as functions that
//! tests can call.

pub mod cmd;
pub mod dump;
pub mod topview;
