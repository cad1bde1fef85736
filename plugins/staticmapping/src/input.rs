//! What is kept of each sweep (StaticMapping's `filters`: `Range`, then `RandomSampler`),
//! and its linear de-skew.
//!
//! A sweep is one revolution (`accumulate_cloud_num = 1`): points fired over its 0.1 s,
//! each with its time after the sweep's start. The robot moves meanwhile, so each point is
//! carried to the sweep's start with the motion predicted for the sweep, interpolated
//! linearly in the point's time (translation scaled, rotation slerped from the identity),
//! as StaticMapping's `MotionCompensation` does.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use plugin_api::LidarPoint;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use crate::config::InputConfig;

/// A sweep as kept: points in the lidar frame and their time after the sweep's start.
#[derive(Debug, Clone, Default)]
pub struct Sweep {
    pub stamp_ns: i64,
    /// x, y, z (m) and time after `stamp_ns` (s).
    pub points: Vec<[f32; 4]>,
}

/// Keeps the points within the range gate, then each with probability `sampling_rate`.
pub fn filter(
    stamp_ns: i64,
    points: &[LidarPoint],
    cfg: &InputConfig,
    rng: &mut ChaCha8Rng,
) -> Sweep {
    let (lo, hi) = (
        cfg.min_range_m * cfg.min_range_m,
        cfg.max_range_m * cfg.max_range_m,
    );
    let mut kept = Vec::with_capacity((points.len() as f64 * cfg.sampling_rate) as usize + 16);
    for p in points {
        let (x, y, z) = (f64::from(p.x), f64::from(p.y), f64::from(p.z));
        let r2 = x * x + y * y + z * z;
        if !r2.is_finite() || r2 < lo || r2 > hi || !p.time_s.is_finite() {
            continue;
        }
        // Every point in range draws, so the sample depends only on the sweep and the seed.
        if cfg.sampling_rate < 1.0 && rng.random::<f64>() >= cfg.sampling_rate {
            continue;
        }
        kept.push([p.x, p.y, p.z, p.time_s]);
    }
    Sweep {
        stamp_ns,
        points: kept,
    }
}

/// The pose a fraction `u` of the way from the identity to `motion`: translation scaled,
/// rotation slerped.
pub fn fraction(motion: &Isometry3<f64>, u: f64) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::from(motion.translation.vector * u),
        UnitQuaternion::identity().slerp(&motion.rotation, u),
    )
}

/// The sweep's points in the lidar frame at its start. `start_from_end` is the lidar's motion
/// over `sweep_s` (None: no correction).
pub fn deskew(
    sweep: &Sweep,
    start_from_end: Option<&Isometry3<f64>>,
    sweep_s: f64,
) -> Vec<Vector3<f64>> {
    let point = |p: &[f32; 4]| Vector3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]));
    match start_from_end {
        None => sweep.points.iter().map(point).collect(),
        Some(motion) => sweep
            .points
            .iter()
            .map(|p| {
                let u = (f64::from(p[3]) / sweep_s).clamp(0.0, 1.5);
                (fraction(motion, u) * Point3::from(point(p))).coords
            })
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn lidar_point(x: f32, y: f32, z: f32, t: f32) -> LidarPoint {
        LidarPoint {
            x,
            y,
            z,
            intensity: 0.0,
            time_s: t,
            ring: 0,
        }
    }

    #[test]
    fn range_gate_and_sampling_rate() {
        let points: Vec<LidarPoint> = (0..20_000)
            .map(|i| lidar_point(1.0 + (i % 100) as f32, 0.5, 0.0, 0.0))
            .collect();
        let cfg = InputConfig::default();
        let sweep = filter(0, &points, &cfg, &mut ChaCha8Rng::seed_from_u64(1));
        assert!(sweep.points.iter().all(|p| {
            let r = (p[0] * p[0] + p[1] * p[1]).sqrt();
            (4.5..=75.0).contains(&r)
        }));
        // Ranges 4.5-75 m: 71 of every 100 points in range (x = 5..=75, y = 0.5).
        let in_range = 20_000.0 * 71.0 / 100.0;
        let rate = sweep.points.len() as f64 / in_range;
        assert!(
            (rate - 0.35).abs() < 0.02,
            "kept {rate:.3} of the points in range"
        );
        let again = filter(0, &points, &cfg, &mut ChaCha8Rng::seed_from_u64(1));
        assert_eq!(
            sweep.points, again.points,
            "the same seed keeps the same points"
        );
    }

    /// A static wall seen by a lidar moving at 0.5 m/s and turning at 0.5 rad/s: every
    /// point de-skewed with the true motion lands on the wall as seen from the start pose.
    #[test]
    fn deskew_with_the_true_motion_undoes_the_smear() {
        let sweep_s = 0.1;
        let motion_at = |t: f64| {
            Isometry3::from_parts(
                Translation3::new(0.5 * t, 0.0, 0.0),
                UnitQuaternion::from_euler_angles(0.0, 0.0, 0.5 * t),
            )
        };
        let mut sweep = Sweep::default();
        let mut truth = Vec::new();
        for i in 0..100 {
            let t = sweep_s * f64::from(i) / 100.0;
            let in_start = Vector3::new(10.0, -5.0 + 0.1 * f64::from(i), 1.0);
            let seen = motion_at(t).inverse() * Point3::from(in_start);
            sweep
                .points
                .push([seen.x as f32, seen.y as f32, seen.z as f32, t as f32]);
            truth.push(in_start);
        }
        let raw = deskew(&sweep, None, sweep_s);
        let fixed = deskew(&sweep, Some(&motion_at(sweep_s)), sweep_s);
        let worst = |ps: &[Vector3<f64>]| {
            ps.iter()
                .zip(&truth)
                .map(|(p, q)| (p - q).norm())
                .fold(0.0, f64::max)
        };
        assert!(worst(&raw) > 0.4, "raw smear {:.3} m", worst(&raw));
        assert!(
            worst(&fixed) < 1e-5,
            "de-skewed error {:.2e} m",
            worst(&fixed)
        );
    }
}
