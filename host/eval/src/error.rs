//! The one error type of the crate: every message is one line and names the file and
//! line where the input is at fault.

use std::path::PathBuf;

/// What is wrong with one line of a trajectory file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Malformed {
    /// The line does not have the number of columns the format requires.
    #[error("expected {expected} columns, found {found}")]
    ColumnCount { expected: usize, found: usize },
    /// A column is not a number.
    #[error("column {column} is not a number: {token:?}")]
    NotANumber { column: usize, token: String },
    /// A column is NaN or infinite.
    #[error("column {column} is not finite: {token:?}")]
    NotFinite { column: usize, token: String },
    /// The time stamp is not larger than the previous one.
    #[error("time stamp {stamp} does not increase (previous {previous})")]
    NonMonotonic { stamp: f64, previous: f64 },
    /// The quaternion's norm is too far from 1 to be a rotation.
    #[error("quaternion norm {norm} is far from 1 (allowed deviation {tolerance})")]
    QuaternionNorm { norm: f64, tolerance: f64 },
    /// The 3x3 block of a KITTI pose is not a rotation matrix.
    #[error("3x3 block is not a rotation (|RᵀR - I| = {deviation}, det = {det})")]
    NotARotation { deviation: f64, det: f64 },
    /// A times file and a KITTI pose file have different lengths.
    #[error("{poses} poses but {stamps} time stamps")]
    CountMismatch { poses: usize, stamps: usize },
}

/// Errors of trajectory evaluation.
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    /// A file could not be read.
    #[error("{}: cannot read", path.display())]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    /// A plot could not be drawn (nothing to draw, or the drawing library failed).
    #[error("plot {title:?}: {message}")]
    Plot { title: String, message: String },
    /// A file could not be written.
    #[error("{}: cannot write", path.display())]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    /// A line of a trajectory file is malformed (`line` counts from 1).
    #[error("{}:{line}: {kind}", path.display())]
    Malformed {
        path: PathBuf,
        line: usize,
        kind: Malformed,
    },
    /// A trajectory file holds no pose.
    #[error("{}: no poses", path.display())]
    Empty { path: PathBuf },
    /// Association found no pair of stamps within `max_diff`.
    #[error(
        "found no matching timestamps between reference and estimate with max. time diff {max_diff} s and time offset {offset} s"
    )]
    NoMatches { max_diff: f64, offset: f64 },
    /// Trajectories without stamps must be paired by index and have the same length.
    #[error(
        "reference has {reference} poses but estimate has {estimate}; without time stamps they must be equal"
    )]
    LengthMismatch { reference: usize, estimate: usize },
    /// Two lists that go pose for pose have different lengths.
    #[error("{what}: {got} where there are {expected} poses")]
    CountsDiffer {
        what: &'static str,
        expected: usize,
        got: usize,
    },
    /// Too few poses for an operation.
    #[error("{what} needs at least {needed} poses, got {got}")]
    TooFewPoses {
        what: &'static str,
        needed: usize,
        got: usize,
    },
    /// The positions are degenerate (e.g. all on one point), so alignment is not defined.
    #[error(
        "degenerate covariance rank, {what} alignment is not possible (the positions lie on a \
         point or a line: a route cut while the robot turns in place or drives straight?)"
    )]
    Degenerate { what: &'static str },
    /// No drift segment fits in the reference path.
    #[error(
        "no drift segment fits: the reference path is {path_length} m, the shortest segment {shortest} m"
    )]
    NoSegments { path_length: f64, shortest: f64 },
    /// An option is out of its valid range.
    #[error("invalid option: {0}")]
    InvalidOption(String),
    /// An image could not be encoded.
    #[error("{}: cannot encode image: {message}", path.display())]
    Encode { path: PathBuf, message: String },
}
