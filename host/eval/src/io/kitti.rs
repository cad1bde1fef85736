//! The KITTI odometry pose format (Geiger et al. 2012): one pose per line, the first three
//! rows of the 4x4 `world_from_body` matrix, row-major (12 numbers). Stamps come from an
//! optional times file with one stamp in seconds per line.

use std::io::Write;
use std::path::Path;

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion};

use super::{check_increasing, create, data_lines, parse_numbers, read_text, write_error};
use crate::{EvalError, Malformed, Trajectory};

/// Largest accepted Frobenius norm of `RᵀR - I` for a KITTI rotation block.
const ROTATION_TOLERANCE: f64 = 1e-2;

/// Reads a KITTI pose file and, if given, its times file. Without a times file the poses
/// get their index (0, 1, 2, …) as stamp; such trajectories are paired by index.
pub fn read_kitti(path: impl AsRef<Path>, times: Option<&Path>) -> Result<Trajectory, EvalError> {
    let path = path.as_ref();
    let text = read_text(path)?;
    let times = match times {
        Some(times_path) => Some((read_text(times_path)?, times_path)),
        None => None,
    };
    parse_kitti(
        &text,
        path,
        times.as_ref().map(|(text, path)| (text.as_str(), *path)),
    )
}

/// Parses the text of a KITTI pose file and optionally of its times file; the paths only
/// name the sources in errors.
pub fn parse_kitti(
    text: &str,
    path: &Path,
    times: Option<(&str, &Path)>,
) -> Result<Trajectory, EvalError> {
    let mut poses = Vec::new();
    let mut last_line = 0;
    for (line, content) in data_lines(text) {
        let m = parse_numbers::<12>(content, path, line)?;
        let r = Matrix3::new(m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10]);
        let deviation = (r.transpose() * r - Matrix3::identity()).norm();
        let det = r.determinant();
        // Written so that a NaN (from entries whose products overflow) fails the check.
        if !(deviation <= ROTATION_TOLERANCE && det > 0.0) {
            return Err(EvalError::Malformed {
                path: path.to_path_buf(),
                line,
                kind: Malformed::NotARotation { deviation, det },
            });
        }
        let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
        poses.push(Isometry3::from_parts(
            Translation3::new(m[3], m[7], m[11]),
            UnitQuaternion::new_normalize(q.into_inner()),
        ));
        last_line = line;
    }
    if poses.is_empty() {
        return Err(EvalError::Empty {
            path: path.to_path_buf(),
        });
    }
    let stamps = match times {
        None => (0..poses.len()).map(|i| i as f64).collect(),
        Some((times_text, times_path)) => {
            let mut stamps: Vec<f64> = Vec::with_capacity(poses.len());
            let mut times_last_line = 0;
            for (line, content) in data_lines(times_text) {
                let [t] = parse_numbers::<1>(content, times_path, line)?;
                check_increasing(stamps.last().copied(), t, times_path, line)?;
                stamps.push(t);
                times_last_line = line;
            }
            if stamps.len() != poses.len() {
                let (blame, line) = if stamps.len() > poses.len() {
                    (times_path, times_last_line)
                } else {
                    (path, last_line)
                };
                return Err(EvalError::Malformed {
                    path: blame.to_path_buf(),
                    line,
                    kind: Malformed::CountMismatch {
                        poses: poses.len(),
                        stamps: stamps.len(),
                    },
                });
            }
            stamps
        }
    };
    Ok(Trajectory { stamps, poses })
}

/// Writes the poses as a KITTI file and, if `times` is given, the stamps as a times file.
pub fn write_kitti(
    path: impl AsRef<Path>,
    trajectory: &Trajectory,
    times: Option<&Path>,
) -> Result<(), EvalError> {
    let path = path.as_ref();
    let mut out = create(path)?;
    let result = (|| {
        for pose in &trajectory.poses {
            let m = pose.to_homogeneous();
            let row = |r: usize| format!("{} {} {} {}", m[(r, 0)], m[(r, 1)], m[(r, 2)], m[(r, 3)]);
            writeln!(out, "{} {} {}", row(0), row(1), row(2))?;
        }
        out.flush()
    })();
    result.map_err(|source| write_error(path, source))?;
    if let Some(times) = times {
        let mut out = create(times)?;
        let result = (|| {
            for t in &trajectory.stamps {
                writeln!(out, "{t}")?;
            }
            out.flush()
        })();
        result.map_err(|source| write_error(times, source))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const IDENTITY_AT_1_2_3: &str = "1 0 0 1 0 1 0 2 0 0 1 3\n";

    #[test]
    fn parses_poses_with_and_without_times() {
        let turned = "0 -1 0 0 1 0 0 0 0 0 1 0\n";
        let text = format!("{IDENTITY_AT_1_2_3}{turned}");
        let t = parse_kitti(&text, Path::new("p.txt"), None).unwrap();
        assert_eq!(
            t.stamps,
            vec![0.0, 1.0],
            "expected index stamps without a times file"
        );
        assert_eq!(
            t.poses[0].translation.vector,
            nalgebra::Vector3::new(1.0, 2.0, 3.0),
            "expected t = (1,2,3)"
        );
        let yaw = t.poses[1].rotation.euler_angles().2;
        assert!(
            (yaw - std::f64::consts::FRAC_PI_2).abs() < 1e-12,
            "expected yaw 90°, got {yaw}"
        );
        let t = parse_kitti(
            &text,
            Path::new("p.txt"),
            Some(("0.5\n0.6\n", Path::new("times.txt"))),
        )
        .unwrap();
        assert_eq!(t.stamps, vec![0.5, 0.6], "expected the times file's stamps");
    }

    #[test]
    fn malformed_kitti_names_file_and_line() {
        let bad_rotation = "2 0 0 0 0 1 0 0 0 0 1 0\n";
        let cases = [
            (
                "1 0 0\n".to_string(),
                None,
                "p.txt:1: expected 12 columns, found 3",
            ),
            (
                format!("{IDENTITY_AT_1_2_3}{bad_rotation}"),
                None,
                "p.txt:2: 3x3 block is not a rotation",
            ),
            (
                IDENTITY_AT_1_2_3.repeat(2),
                Some("1\n1\n"),
                "times.txt:2: time stamp 1 does not increase",
            ),
            (
                IDENTITY_AT_1_2_3.repeat(2),
                Some("1\n"),
                "p.txt:2: 2 poses but 1 time stamps",
            ),
            (
                IDENTITY_AT_1_2_3.to_string(),
                Some("1\n2\n"),
                "times.txt:2: 1 poses but 2 time stamps",
            ),
        ];
        for (text, times, expected) in cases {
            let times = times.map(|t| (t, Path::new("times.txt")));
            let message = parse_kitti(&text, Path::new("p.txt"), times)
                .unwrap_err()
                .to_string();
            assert!(
                message.starts_with(expected),
                "expected {expected:?}, got {message:?}"
            );
        }
    }

    /// fuzz/regressions/kitti/overflowing-rotation.kitti: entries whose products overflow
    /// make `RᵀR - I` NaN, which passed the rotation check as "not above the tolerance".
    #[test]
    fn a_block_whose_check_overflows_is_not_a_rotation() {
        let text = "1e200 1e200 0 0 -1e200 1e200 0 0 0 0 1 0\n";
        let message = parse_kitti(text, Path::new("p.txt"), None)
            .unwrap_err()
            .to_string();
        assert!(
            message.starts_with("p.txt:1: 3x3 block is not a rotation"),
            "{message}"
        );
    }

    #[test]
    fn write_then_read_round_trips() {
        let dir = tempfile::tempdir().unwrap();
        let (poses_path, times_path) = (dir.path().join("p.txt"), dir.path().join("t.txt"));
        let pose = Isometry3::new(
            nalgebra::Vector3::new(1.0, -2.0, 0.5),
            nalgebra::Vector3::new(0.1, -0.4, 2.0),
        );
        let t = Trajectory::new(vec![3.0, 3.1], vec![pose, Isometry3::identity()]);
        write_kitti(&poses_path, &t, Some(&times_path)).unwrap();
        let back = read_kitti(&poses_path, Some(&times_path)).unwrap();
        assert_eq!(back.stamps, t.stamps, "expected stamps back");
        let d = back.poses[0].inverse() * t.poses[0];
        assert!(
            d.translation.vector.norm() < 1e-12 && d.rotation.angle() < 1e-12,
            "expected the pose back"
        );
    }
}
