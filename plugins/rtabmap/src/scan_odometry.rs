//! Wheel odometry refined by ICP on a 2D laser scan, the odometry the paper ran RTAB-Map on
//! (RTAB-Map's `icp_odometry` with the wheels' pose as guess and `Reg/Force3DoF`): every scan
//! is registered point-to-line to a local map of recent key scans, starting from the last
//! refined pose moved by what the wheels measured since. Where the scan does not constrain a
//! direction (along a row of a vineyard, two parallel lines of trunks and foliage can leave
//! the along-row translation weakly constrained), the wheels' motion stands.
//!
//! The guess is dead reckoning from the wheels' forward speed with the yaw rate of the IMU's
//! gyro (or of the wheels): a skid-steered base turning on the spot in a headland, where the
//! scan sees nothing within range, loses degrees of heading on its wheels alone, which no
//! later registration along a row of identical trunks can take back.

use std::collections::VecDeque;

use nalgebra::{Isometry2, Isometry3, Translation3, UnitQuaternion, Vector2, Vector3};
use slam_common::scan2d::{Icp2dTarget, icp2d};

use crate::config::{ScanOdometryConfig, YawSource};

/// The planar part of a pose: x, y and yaw.
pub fn planar(pose: &Isometry3<f64>) -> Isometry2<f64> {
    let t = pose.translation.vector;
    let forward = pose.rotation * Vector3::x();
    Isometry2::new(Vector2::new(t.x, t.y), forward.y.atan2(forward.x))
}

/// A planar pose as a 3D one (z, roll and pitch 0).
pub fn spatial(pose: &Isometry2<f64>) -> Isometry3<f64> {
    let t = pose.translation.vector;
    Isometry3::from_parts(
        Translation3::new(t.x, t.y, 0.0),
        UnitQuaternion::from_euler_angles(0.0, 0.0, pose.rotation.angle()),
    )
}

/// What one scan did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanStep {
    pub odom_from_base: Isometry2<f64>,
    /// ICP's result was used (false: the wheels' guess stands).
    pub registered: bool,
    pub degenerate: bool,
}

#[derive(Debug)]
pub struct ScanOdometry {
    cfg: ScanOdometryConfig,
    base_from_scan: Isometry2<f64>,
    /// Recent dead-reckoned poses `(stamp, odom_from_base)`, for the guess at a scan's stamp.
    wheels: VecDeque<(i64, Isometry2<f64>)>,
    /// Dead reckoning: the last wheel reading's stamp and the pose there; the gyro's yaw
    /// integrated so far and its value at the last wheel reading.
    reckoned: Option<(i64, Isometry2<f64>)>,
    gyro_yaw: f64,
    gyro_yaw_at_wheels: f64,
    last_gyro_ns: Option<i64>,
    /// The wheel pose at the last scan, and the refined pose there.
    last: Option<(Isometry2<f64>, Isometry2<f64>)>,
    key_scans: VecDeque<Vec<Vector2<f64>>>,
    last_key: Option<Isometry2<f64>>,
    target: Icp2dTarget,
}

impl ScanOdometry {
    pub fn new(cfg: ScanOdometryConfig, base_from_scan: &Isometry3<f64>) -> Self {
        Self {
            cfg,
            base_from_scan: planar(base_from_scan),
            wheels: VecDeque::new(),
            reckoned: None,
            gyro_yaw: 0.0,
            gyro_yaw_at_wheels: 0.0,
            last_gyro_ns: None,
            last: None,
            key_scans: VecDeque::new(),
            last_key: None,
            target: Icp2dTarget::default(),
        }
    }

    /// The gyro's yaw rate about the base's z axis, rad/s.
    pub fn on_gyro(&mut self, stamp_ns: i64, yaw_rate_rps: f64) {
        if let Some(last) = self.last_gyro_ns {
            self.gyro_yaw += yaw_rate_rps * (stamp_ns - last) as f64 * 1e-9;
        }
        self.last_gyro_ns = Some(stamp_ns);
    }

    /// A wheel reading: forward speed and the wheels' yaw rate.
    pub fn on_wheels(&mut self, stamp_ns: i64, linear_mps: f64, angular_rps: f64) {
        let pose = match self.reckoned {
            None => Isometry2::identity(),
            Some((last, pose)) => {
                let dt = (stamp_ns - last) as f64 * 1e-9;
                let dyaw = match self.cfg.yaw_source {
                    YawSource::Imu if self.last_gyro_ns.is_some() => {
                        self.gyro_yaw - self.gyro_yaw_at_wheels
                    }
                    _ => angular_rps * dt,
                };
                let mid = pose.rotation.angle() + 0.5 * dyaw;
                let step = linear_mps * dt;
                Isometry2::new(
                    pose.translation.vector + Vector2::new(step * mid.cos(), step * mid.sin()),
                    pose.rotation.angle() + dyaw,
                )
            }
        };
        self.gyro_yaw_at_wheels = self.gyro_yaw;
        self.reckoned = Some((stamp_ns, pose));
        self.wheels.push_back((stamp_ns, pose));
        while self.wheels.len() > 64 {
            self.wheels.pop_front();
        }
    }

    /// The wheels' pose at `stamp_ns`, interpolated between the readings around it (the
    /// newest if the scan is newer).
    fn wheels_at(&self, stamp_ns: i64) -> Option<Isometry2<f64>> {
        let after = self.wheels.iter().position(|(t, _)| *t >= stamp_ns);
        match after {
            Some(0) => self.wheels.front().map(|(_, p)| *p),
            Some(k) => {
                let (t0, p0) = self.wheels[k - 1];
                let (t1, p1) = self.wheels[k];
                let s = (stamp_ns - t0) as f64 / (t1 - t0).max(1) as f64;
                Some(p0.lerp_slerp(&p1, s))
            }
            None => self.wheels.back().map(|(_, p)| *p),
        }
    }

    /// The refined pose now: the last scan's, moved by the wheels since.
    pub fn pose_at(&self, stamp_ns: i64) -> Option<Isometry2<f64>> {
        let (wheel_then, refined) = self.last?;
        let wheel_now = self.wheels_at(stamp_ns)?;
        Some(refined * (wheel_then.inverse() * wheel_now))
    }

    /// Registers a scan (points in the scan's frame, from [`slam_common::scan2d::points_from_ranges`]).
    /// None until the wheels have reported.
    pub fn on_scan(&mut self, stamp_ns: i64, points: &[Vector2<f64>]) -> Option<ScanStep> {
        let wheel_now = self.wheels_at(stamp_ns)?;
        let guess = match self.last {
            Some((wheel_then, refined)) => refined * (wheel_then.inverse() * wheel_now),
            None => wheel_now,
        };
        let max_range = if self.cfg.max_range_m > 0.0 {
            self.cfg.max_range_m
        } else {
            f64::INFINITY
        };
        let in_base: Vec<Vector2<f64>> = points
            .iter()
            .filter(|p| p.norm() <= max_range)
            .map(|p| (self.base_from_scan * nalgebra::Point2::from(*p)).coords)
            .collect();
        let mut step = ScanStep {
            odom_from_base: guess,
            registered: false,
            degenerate: false,
        };
        if !self.target.is_empty() {
            if let Some(result) = icp2d(&in_base, &self.target, guess, &self.cfg.icp) {
                let correction = guess.inverse() * result.target_from_source;
                if correction.translation.vector.norm() <= self.cfg.max_correction_m
                    && correction.rotation.angle().abs() <= self.cfg.max_correction_rad
                {
                    step = ScanStep {
                        odom_from_base: result.target_from_source,
                        registered: true,
                        degenerate: result.is_degenerate(),
                    };
                }
            }
        }
        self.last = Some((wheel_now, step.odom_from_base));
        let moved = self.last_key.is_none_or(|key| {
            let d = key.inverse() * step.odom_from_base;
            d.translation.vector.norm() >= self.cfg.key_scan_distance_m
                || d.rotation.angle().abs() >= self.cfg.key_scan_angle_rad
        });
        if moved {
            self.add_key_scan(&step.odom_from_base, &in_base);
        }
        Some(step)
    }

    fn add_key_scan(&mut self, odom_from_base: &Isometry2<f64>, in_base: &[Vector2<f64>]) {
        let scan = slam_common::scan2d::downsample(
            &in_base
                .iter()
                .map(|p| (odom_from_base * nalgebra::Point2::from(*p)).coords)
                .collect::<Vec<_>>(),
            self.cfg.icp.voxel_size_m,
        );
        self.key_scans.push_back(scan);
        while self.key_scans.iter().map(Vec::len).sum::<usize>() > self.cfg.local_map_size
            && self.key_scans.len() > 1
        {
            self.key_scans.pop_front();
        }
        let points: Vec<Vector2<f64>> = self.key_scans.iter().flatten().copied().collect();
        self.target = Icp2dTarget::new(&points, &self.cfg.icp);
        self.last_key = Some(*odom_from_base);
    }
}
