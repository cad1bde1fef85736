//! Trajectory evaluation as evo defines it: TUM/KITTI I/O, association by timestamp,
//! alignment (origin, SE(3)/Sim(3) Umeyama, 4-DoF), APE/RPE with evo's pose relations
//! and statistics, KITTI-style drift, loop closures judged against ground truth, and
//! top-view plots.
//!
//! Implemented from the definitions, not from evo's (GPL) code:
//! - Sturm et al., "A Benchmark for the Evaluation of RGB-D SLAM Systems", IROS 2012
//!   (absolute trajectory error, relative pose error, association by timestamp);
//! - Umeyama, "Least-squares estimation of transformation parameters between two point
//!   patterns", IEEE PAMI 13(4), 1991 (SE(3)/Sim(3) alignment);
//! - Zhang & Scaramuzza, "A Tutorial on Quantitative Trajectory Evaluation for
//!   Visual(-Inertial) Odometry", IROS 2018 (4-DoF position + yaw alignment);
//! - Geiger et al., "Are we ready for autonomous driving? The KITTI vision benchmark
//!   suite", CVPR 2012 (segment drift);
//! - evo's documentation (M. Grupp, <https://github.com/MichaelGrupp/evo>) for the exact
//!   semantics that make our numbers equal to evo's (checked in `tests/evo_crosscheck.rs`).
//!
//! A typical APE evaluation:
//! ```no_run
//! # fn main() -> Result<(), eval::EvalError> {
//! let reference = eval::read_tum("groundtruth.tum")?;
//! let estimate = eval::read_tum("estimate.tum")?;
//! let options = eval::ApeOptions { alignment: eval::Alignment::Se3, ..Default::default() };
//! let result = eval::evaluate_ape(&reference, &estimate, &options)?;
//! println!("pairs {} rmse {}", result.stats.pairs, result.stats.rmse);
//! # Ok(()) }
//! ```

mod align;
mod ape;
mod associate;
mod drift;
mod error;
mod intervals;
mod io;
mod joins;
mod localization;
mod loops;
pub mod plot;
mod relation;
mod rpe;
mod stats;
mod trajectory;

pub use align::{Alignment, Sim3, align, align_4dof, umeyama};
pub use ape::{ApeOptions, ApeResult, ape_errors, evaluate_ape};
pub use associate::{
    Association, Pairing, PosePairs, associate, associate_by_index, matching_time_indices,
};
pub use drift::{DriftOptions, SegmentDrift, drift};
pub use error::{EvalError, Malformed};
pub use intervals::{Rate, mean_interval95, t975};
pub use io::kitti::{parse_kitti, read_kitti, write_kitti};
pub use io::tum::{parse_tum, read_tum, write_tum};
pub use io::{Format, read_trajectory};
pub use joins::{
    EXPLAIN_WINDOW_S, EpisodeKind, JoinCriteria, JoinEpisode, JoinReport, MapChangeVerdict,
    wrong_joins,
};
pub use localization::{
    FalseLocalization, Lanes, LocalizationCriteria, LocalizationReport, LocalizedTrajectory,
    MapReference, evaluate_localization,
};
pub use loops::{
    CorrectionJudgement, LoopCounts, LoopCriteria, LoopJudgement, judge_correction, judge_loop,
};
pub use relation::PoseRelation;
pub use rpe::{DeltaUnit, RpeOptions, RpeResult, evaluate_rpe, rpe_errors, rpe_pairs};
pub use stats::Statistics;
pub use trajectory::Trajectory;
