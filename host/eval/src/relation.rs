//! Pose relations: which part of an error pose `E` becomes the scalar error, as evo
//! defines them (evo documentation, "Metrics"; Sturm et al. 2012 use the translation).

use nalgebra::{Isometry3, Matrix3};

/// The scalar taken from an error pose `E = [R t; 0 1]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PoseRelation {
    /// `‖t‖`, metres (evo's `trans_part`).
    #[default]
    Translation,
    /// `‖R - I‖_F`, unitless (evo's `rot_part`).
    RotationPart,
    /// Rotation angle `|log(R)|`, degrees (evo's `angle_deg`).
    AngleDeg,
    /// Rotation angle `|log(R)|`, radians (evo's `angle_rad`).
    AngleRad,
    /// `‖E - I₄‖_F`, unitless (evo's `full`).
    Full,
}

impl PoseRelation {
    /// The error value of the error pose `e`.
    pub fn error(self, e: &Isometry3<f64>) -> f64 {
        match self {
            Self::Translation => e.translation.vector.norm(),
            Self::RotationPart => rotation_part(e),
            Self::AngleRad => rotation_angle(e),
            Self::AngleDeg => rotation_angle(e).to_degrees(),
            Self::Full => {
                let r = rotation_part(e);
                (r * r + e.translation.vector.norm_squared()).sqrt()
            }
        }
    }

    /// The unit of the error, for tables.
    pub fn unit(self) -> &'static str {
        match self {
            Self::Translation => "m",
            Self::AngleDeg => "deg",
            Self::AngleRad => "rad",
            Self::RotationPart | Self::Full => "unit-less",
        }
    }

    /// evo's wording of the relation, for titles ("translation part", …).
    pub fn describe(self) -> &'static str {
        match self {
            Self::Translation => "translation part",
            Self::RotationPart => "rotation part",
            Self::AngleDeg => "rotation angle in degrees",
            Self::AngleRad => "rotation angle in radians",
            Self::Full => "full transformation",
        }
    }
}

/// `‖R - I‖_F` of the rotation of `e`.
fn rotation_part(e: &Isometry3<f64>) -> f64 {
    (e.rotation.to_rotation_matrix().into_inner() - Matrix3::identity()).norm()
}

/// The rotation angle in `[0, π]`, as `2 atan2(‖v‖, |w|)`, which stays accurate for small
/// angles (unlike `acos`).
fn rotation_angle(e: &Isometry3<f64>) -> f64 {
    let q = e.rotation.quaternion();
    2.0 * q.imag().norm().atan2(q.w.abs())
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn relations_of_a_known_error_pose() {
        // 3-4-5 translation and a 90° rotation about z: R - I has entries -1,-1 (diagonal)
        // and -1,+1 (off-diagonal), so ‖R - I‖_F = 2 and ‖E - I‖_F = sqrt(4 + 25).
        let e = Isometry3::new(
            Vector3::new(3.0, 4.0, 0.0),
            Vector3::new(0.0, 0.0, std::f64::consts::FRAC_PI_2),
        );
        let close = |a: f64, b: f64| (a - b).abs() < 1e-12;
        assert!(
            close(PoseRelation::Translation.error(&e), 5.0),
            "expected 5 m"
        );
        assert!(
            close(PoseRelation::RotationPart.error(&e), 2.0),
            "expected ‖R - I‖ = 2"
        );
        assert!(
            close(PoseRelation::AngleDeg.error(&e), 90.0),
            "expected 90 deg"
        );
        assert!(
            close(
                PoseRelation::AngleRad.error(&e),
                std::f64::consts::FRAC_PI_2
            ),
            "expected π/2 rad"
        );
        assert!(
            close(PoseRelation::Full.error(&e), 29f64.sqrt()),
            "expected sqrt(29)"
        );
    }

    #[test]
    fn small_angles_are_accurate() {
        let e = Isometry3::new(Vector3::zeros(), Vector3::new(1e-9, 0.0, 0.0));
        let angle = PoseRelation::AngleRad.error(&e);
        assert!(
            (angle - 1e-9).abs() < 1e-20,
            "expected 1e-9 rad, got {angle}"
        );
    }
}
