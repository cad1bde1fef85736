//! The TUM RGB-D trajectory format (Sturm et al. 2012): one pose per line,
//! `timestamp tx ty tz qx qy qz qw`, stamps in seconds, `#` starts a comment.

use std::io::Write;
use std::path::Path;

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};

use super::{check_increasing, create, data_lines, parse_numbers, read_text, write_error};
use crate::{EvalError, Malformed, Trajectory};

/// Largest accepted deviation of a quaternion's norm from 1; quaternions within it are
/// normalised (as evo does when it builds rotation matrices).
pub(crate) const QUATERNION_NORM_TOLERANCE: f64 = 1e-2;

/// Reads a TUM trajectory file.
///
/// Errors name the file and line: wrong column count, a non-number, NaN or infinity, a
/// stamp that does not increase, a quaternion whose norm is off by more than 1e-2.
pub fn read_tum(path: impl AsRef<Path>) -> Result<Trajectory, EvalError> {
    let path = path.as_ref();
    parse_tum(&read_text(path)?, path)
}

/// Parses the text of a TUM trajectory; `path` only names the source in errors.
pub fn parse_tum(text: &str, path: &Path) -> Result<Trajectory, EvalError> {
    let mut trajectory = Trajectory::default();
    for (line, content) in data_lines(text) {
        let [t, x, y, z, qx, qy, qz, qw] = parse_numbers::<8>(content, path, line)?;
        check_increasing(trajectory.stamps.last().copied(), t, path, line)?;
        let q = Quaternion::new(qw, qx, qy, qz);
        let norm = q.norm();
        if (norm - 1.0).abs() > QUATERNION_NORM_TOLERANCE {
            return Err(EvalError::Malformed {
                path: path.to_path_buf(),
                line,
                kind: Malformed::QuaternionNorm {
                    norm,
                    tolerance: QUATERNION_NORM_TOLERANCE,
                },
            });
        }
        trajectory.stamps.push(t);
        trajectory.poses.push(Isometry3::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::new_normalize(q),
        ));
    }
    if trajectory.is_empty() {
        return Err(EvalError::Empty {
            path: path.to_path_buf(),
        });
    }
    Ok(trajectory)
}

/// Writes a TUM trajectory file; numbers are written with the shortest representation
/// that reads back to the same `f64`.
pub fn write_tum(path: impl AsRef<Path>, trajectory: &Trajectory) -> Result<(), EvalError> {
    let path = path.as_ref();
    let mut out = create(path)?;
    let result = (|| {
        writeln!(out, "# timestamp tx ty tz qx qy qz qw")?;
        for (t, pose) in trajectory.stamps.iter().zip(&trajectory.poses) {
            let p = &pose.translation.vector;
            let q = pose.rotation.quaternion();
            writeln!(
                out,
                "{t} {} {} {} {} {} {} {}",
                p.x, p.y, p.z, q.i, q.j, q.k, q.w
            )?;
        }
        out.flush()
    })();
    result.map_err(|source| write_error(path, source))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Trajectory, EvalError> {
        parse_tum(text, Path::new("gt.tum"))
    }

    #[test]
    fn parses_comments_and_normalises_quaternions() {
        let t = parse("# t x y z qx qy qz qw\n\n1.0 1 2 3 0 0 0 1\n1.5 4 5 6 0 0 0.7071 0.7071\n")
            .unwrap();
        assert_eq!(t.stamps, vec![1.0, 1.5], "expected two stamps");
        assert_eq!(t.poses[1].translation.vector.z, 6.0, "expected z = 6");
        let angle = t.poses[1].rotation.angle();
        assert!(
            (angle - std::f64::consts::FRAC_PI_2).abs() < 1e-4,
            "expected a 90° rotation, got {angle}"
        );
        assert!(
            (t.poses[1].rotation.norm() - 1.0).abs() < 1e-15,
            "expected a normalised quaternion"
        );
    }

    #[test]
    fn malformed_lines_name_file_and_line() {
        let cases = [
            ("1 2 3 4 5 6 7\n", "gt.tum:1: expected 8 columns, found 7"),
            (
                "# c\n1 0 0 0 0 0 0 1\n2 0 nan 0 0 0 0 1\n",
                "gt.tum:3: column 3 is not finite",
            ),
            (
                "1 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n",
                "gt.tum:2: time stamp 1 does not increase",
            ),
            (
                "1 0 0 0 0 0 0 1.2\n",
                "gt.tum:1: quaternion norm 1.2 is far from 1",
            ),
            ("1 0 0 zero 0 0 0 1\n", "gt.tum:1: column 4 is not a number"),
            ("# only a comment\n", "gt.tum: no poses"),
        ];
        for (text, expected) in cases {
            let message = parse(text).unwrap_err().to_string();
            assert!(
                message.starts_with(expected),
                "expected {expected:?}, got {message:?}"
            );
            assert!(
                !message.contains('\n'),
                "expected a one-line message, got {message:?}"
            );
        }
    }

    #[test]
    fn write_then_read_is_exact() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.tum");
        let pose = Isometry3::new(
            nalgebra::Vector3::new(0.1, -2.0 / 3.0, 1e-9),
            nalgebra::Vector3::new(0.3, 0.2, 0.1),
        );
        let t = Trajectory::new(
            vec![1e9 + 0.123456789, 1e9 + 0.2],
            vec![pose, pose.inverse()],
        );
        write_tum(&path, &t).unwrap();
        let back = read_tum(&path).unwrap();
        assert_eq!(
            back.stamps, t.stamps,
            "expected stamps to round-trip exactly"
        );
        assert_eq!(
            back.poses[0].translation, t.poses[0].translation,
            "expected positions to round-trip exactly"
        );
        assert!(
            back.poses[1].rotation.angle_to(&t.poses[1].rotation) < 1e-15,
            "expected rotations to round-trip"
        );
    }

    #[test]
    fn missing_file_is_named() {
        let message = read_tum("/nonexistent/x.tum").unwrap_err().to_string();
        assert!(
            message.starts_with("/nonexistent/x.tum: cannot read"),
            "expected the path in {message:?}"
        );
    }
}
