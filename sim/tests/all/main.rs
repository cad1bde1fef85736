//! The simulator's tests, one module per subject, in one test binary (one link).

mod camera;
mod camera_features;
mod embree;
mod kernels;
mod sim;
