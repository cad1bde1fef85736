//! The shared SLAM pieces' tests, one module per subject, in one test binary (one link).

#[path = "../support/bow_route.rs"]
mod bow_route;

mod ba;
mod backend;
mod bow;
mod graph_replay;
mod gtsam;
mod isam2;
mod occupancy;
mod scan2d;
mod vocabulary;
