//! End-to-end tests of vinebench: real plugins loaded from their `.so` by the real
//! `vinebench` binary on short simulated routes, with assertions on the numbers that come
//! out, and the pieces they are built of on simulated data. One test binary (one link of
//! every plugin) for all of them; a module per subject.

mod common;

mod bench;
mod cli;
mod conformance;
mod dataset;
mod gnss;
mod joins;
mod lio_sam;
mod localize;
mod orbslam2;
mod python;
mod report;
mod results_mcap;
mod rtabmap;
mod staticmapping;
mod sweep;
