//! Factor graphs: the backend every plugin's graph is solved by, pose-graph files replayed
//! through it, and ORB-SLAM2's bundle adjustment.
//!
//! - [`backend`]: a small factor-graph interface (variables, factors, update, estimate) and
//!   its implementations (native iSAM2, factrs, GTSAM), chosen by name in a plugin's
//!   configuration;
//! - [`posegraph`]: g2o/TORO/City10000 pose-graph files replayed through any backend, with
//!   GTSAM's graph error and the ATE as yardsticks (the `graph-replay` binary);
//! - [`ba`]: sparse Schur-complement Levenberg–Marquardt over keyframe poses and map points
//!   with monocular and stereo reprojection residuals, and the motion-only pose optimisation
//!   with χ² outlier rounds.

pub mod ba;
pub mod backend;
pub mod posegraph;

pub use ba::{bundle_adjust, optimize_pose};
pub use backend::{Backend, BackendConfig, BackendError, Factor, FactorId, Var, from_config};
pub use posegraph::{PoseGraph, replay};
