//! The rtabmap plugin's own tests, one module per subject, in one test binary (one link).

#[path = "../../../slam-common/tests/support/bow_route.rs"]
mod bow_route;

mod config;
mod memory;
