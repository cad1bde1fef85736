//! Reading and writing trajectory files (TUM and KITTI), with line-precise errors.

pub(crate) mod kitti;
pub(crate) mod tum;

use std::path::{Path, PathBuf};

use crate::{EvalError, Malformed, Trajectory};

/// The trajectory file formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Format {
    /// `t x y z qx qy qz qw` per line (Sturm et al. 2012).
    #[default]
    Tum,
    /// 12 numbers per line, the 3x4 `world_from_body` matrix row-major (Geiger et al. 2012).
    Kitti,
}

/// Reads a trajectory in `format`; `times` is the optional KITTI times file (one stamp in
/// seconds per line). Without one, KITTI poses get their index as stamp.
pub fn read_trajectory(
    path: impl AsRef<Path>,
    format: Format,
    times: Option<&Path>,
) -> Result<Trajectory, EvalError> {
    match format {
        Format::Tum => tum::read_tum(path),
        Format::Kitti => kitti::read_kitti(path, times),
    }
}

/// Reads a whole file, naming it in the error.
pub(crate) fn read_text(path: &Path) -> Result<String, EvalError> {
    std::fs::read_to_string(path).map_err(|source| EvalError::Read {
        path: path.to_path_buf(),
        source,
    })
}

/// The data lines of a text file: 1-based line number and the trimmed line, skipping
/// blank lines and `#` comments.
pub(crate) fn data_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'))
}

/// Parses exactly `N` whitespace-separated finite numbers.
pub(crate) fn parse_numbers<const N: usize>(
    line: &str,
    path: &Path,
    line_no: usize,
) -> Result<[f64; N], EvalError> {
    let malformed = |kind| EvalError::Malformed {
        path: path.to_path_buf(),
        line: line_no,
        kind,
    };
    let mut out = [0.0; N];
    let mut found = 0;
    for token in line.split_ascii_whitespace() {
        if found < N {
            let value: f64 = token.parse().map_err(|_| {
                malformed(Malformed::NotANumber {
                    column: found + 1,
                    token: token.to_owned(),
                })
            })?;
            if !value.is_finite() {
                return Err(malformed(Malformed::NotFinite {
                    column: found + 1,
                    token: token.to_owned(),
                }));
            }
            out[found] = value;
        }
        found += 1;
    }
    if found != N {
        return Err(malformed(Malformed::ColumnCount { expected: N, found }));
    }
    Ok(out)
}

/// Checks that `stamp` is larger than `previous`.
pub(crate) fn check_increasing(
    previous: Option<f64>,
    stamp: f64,
    path: &Path,
    line: usize,
) -> Result<(), EvalError> {
    match previous {
        Some(previous) if stamp <= previous => Err(EvalError::Malformed {
            path: path.to_path_buf(),
            line,
            kind: Malformed::NonMonotonic { stamp, previous },
        }),
        _ => Ok(()),
    }
}

/// Creates a buffered file for writing.
pub(crate) fn create(path: &Path) -> Result<std::io::BufWriter<std::fs::File>, EvalError> {
    std::fs::File::create(path)
        .map(std::io::BufWriter::new)
        .map_err(|source| write_error(path, source))
}

pub(crate) fn write_error(path: &Path, source: std::io::Error) -> EvalError {
    EvalError::Write {
        path: PathBuf::from(path),
        source,
    }
}
