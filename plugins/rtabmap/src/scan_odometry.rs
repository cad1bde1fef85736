//! Wheel odometry refined by ICP on a 2D laser scan, the odometry the paper ran RTAB-Map on
//! (RTAB-Map's `icp_odometry` with the wheels' pose as guess and `Reg/Force3DoF`): every scan
//! is registered point-to-line to a local map of recent key scans, starting from the last
//! refined pose moved by what the wheels measured since. Where the scan does not constrain a
//! direction (along a row of a vineyard, two parallel lines of trunks and foliage can leave
//! the along-row translation weakly constrained), the wheels' motion stands.
//!
//! The guess is dead reckoning from the wheels' forward speed with the yaw rate of the IMU's
//! gyro (or of the wheels): a skid-steered base turning on the spot in a headland, where the
//! scan sees little, loses degrees of heading on its wheels alone, which no later
//! registration along a row of identical trunks can take back.
//!
//! Only returns on narrow objects are registered ([`narrow_returns`]): the level scan plane,
//! 0.35 m above uneven ground, cuts rising ground (a headland's undulations, a lane seen
//! while the robot rolls or pitches) along contours metres long that move with the robot's
//! attitude, not with the world. Registered to its own recent key scans, such a contour
//! drags the pose along with it: entering a lane after a headland turn in S2, where it was
//! most of the points within 4 m, it slid the odometry by 0.8 m and 4° within seconds in
//! steps each below the per-scan correction limits, every registration fitting well (ratio
//! ≈ 1, rmse ≈ 2 cm). The trunks and posts of the rows stand upright and are at most
//! 0.17 m wide. With the ground removed so, the range no longer has to be cut at 4 m,
//! where the plane meets flat ground: returns out to 15 m give the registration the
//! row ends during a headland turn and many more trunks along a row.
//!
//! When the caller gives the sweep's timing ([`ScanOdometry::on_timed_scan`]), every return
//! is first moved to where the scanner was at the stamp.
//!
//! The registration is planar, but the ground is not: with the IMU's specific force as
//! well as its rates ([`ScanOdometry::on_imu`]), roll and pitch come from a complementary
//! filter ([`crate::attitude::Tilt`]) and the height from the wheels' travel on that
//! slope; [`ScanOdometry::lift`] gives the pose in 3D. On the default world's undulations
//! (RMS 5 cm in height) planar poses are off by about that much in z whatever their x and
//! y: S1's ATE was 0.055 m planar, of which 0.052 m in height (plugin, seed 0).

use std::collections::VecDeque;

use nalgebra::{Isometry2, Isometry3, Translation3, UnitQuaternion, Vector2, Vector3};
use slam_common::registration::scan2d::{Icp2dTarget, icp2d};

use crate::attitude::Tilt;
use crate::config::{ScanOdometryConfig, YawSource};

/// The planar part of a pose: x, y and yaw.
pub fn planar(pose: &Isometry3<f64>) -> Isometry2<f64> {
    let t = pose.translation.vector;
    let forward = pose.rotation * Vector3::x();
    Isometry2::new(Vector2::new(t.x, t.y), forward.y.atan2(forward.x))
}

/// A planar pose as a 3D one (z, roll and pitch 0).
pub fn spatial(pose: &Isometry2<f64>) -> Isometry3<f64> {
    raised(pose, 0.0, 0.0, 0.0)
}

/// A planar pose (x, y, yaw) raised to 3D at height `z_m` with `roll` and `pitch` (ZYX
/// angles, rad).
pub fn raised(pose: &Isometry2<f64>, z_m: f64, roll: f64, pitch: f64) -> Isometry3<f64> {
    let t = pose.translation.vector;
    Isometry3::from_parts(
        Translation3::new(t.x, t.y, z_m),
        UnitQuaternion::from_euler_angles(roll, pitch, pose.rotation.angle()),
    )
}

/// When the samples of a scan were taken, as a ROS `LaserScan` tells it: sample `i`, at
/// bearing `angle_min_rad + i · angle_increment_rad` in the scanner's frame, was taken
/// `i · time_increment_s` after the scan's stamp.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sweep {
    pub angle_min_rad: f64,
    pub angle_increment_rad: f64,
    pub time_increment_s: f64,
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
    /// Roll and pitch from the IMU, and the height climbed (see
    /// [`ScanOdometryConfig::attitude_gain`]); the last wheel speed and yaw rate with the
    /// forward acceleration, the base's own acceleration for the tilt filter.
    tilt: Tilt,
    height_m: f64,
    speed: Option<(f64, f64, f64)>,
}

impl ScanOdometry {
    pub fn new(cfg: ScanOdometryConfig, base_from_scan: &Isometry3<f64>) -> Self {
        Self {
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
            tilt: Tilt::new(cfg.attitude_gain, cfg.attitude_bias_gain),
            height_m: 0.0,
            speed: None,
            cfg,
        }
    }

    /// An IMU sample in the base frame: angular rate (rad/s) and specific force (m/s²).
    /// Its yaw rate feeds the dead reckoning; with an attitude gain, all of it the tilt.
    pub fn on_imu(&mut self, stamp_ns: i64, gyro: &Vector3<f64>, specific_force: &Vector3<f64>) {
        self.on_gyro(stamp_ns, gyro.z);
        if self.cfg.attitude_gain > 0.0 {
            let (forward, turning, accelerating) = self.speed.unwrap_or_default();
            let own = Vector3::new(accelerating, forward * turning, 0.0);
            self.tilt.update(stamp_ns, gyro, specific_force, &own);
        }
    }

    /// The base's pose in 3D at the planar `odom_from_base`: with the IMU's tilt, the roll,
    /// pitch and height it has had the wheels climb; otherwise level at z = 0.
    pub fn lift(&self, odom_from_base: &Isometry2<f64>) -> Isometry3<f64> {
        let (roll, pitch) = self.tilt.roll_pitch().unwrap_or_default();
        raised(odom_from_base, self.height_m, roll, pitch)
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
        if let Some((last, _)) = self.reckoned {
            let dt = (stamp_ns - last) as f64 * 1e-9;
            let accelerating = match self.speed {
                Some((before, _, _)) if dt > 0.0 => (linear_mps - before) / dt,
                _ => 0.0,
            };
            self.speed = Some((linear_mps, angular_rps, accelerating));
            if let Some((_, pitch)) = self.tilt.roll_pitch() {
                // Forward along a base pitched by θ climbs −sin θ per metre (ZYX angles).
                let step = linear_mps * dt;
                self.height_m -= step * pitch.sin();
                if self.cfg.height_leak_m > 0.0 {
                    self.height_m *= 1.0 - (step.abs() / self.cfg.height_leak_m).min(1.0);
                }
            }
        }
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

    /// Registers a scan (points in the scan's frame, in scan order, from
    /// [`slam_common::registration::scan2d::points_from_ranges`]); None until the wheels have reported.
    /// Without `sweep`, all its returns count as taken at its stamp; with it, every return is
    /// first moved to where the scanner was at the stamp (motion compensation, as LOAM does with its IMU: Zhang and
    /// Singh, "LOAM: Lidar odometry and mapping in real-time", RSS 2014). The sweep of the
    /// default scanner lasts 18 ms: turning at 20°/s in a headland, it bends the scan by a
    /// third of a degree, by a different angle for objects at different bearings.
    pub fn on_timed_scan(
        &mut self,
        stamp_ns: i64,
        points: &[Vector2<f64>],
        sweep: Option<&Sweep>,
    ) -> Option<ScanStep> {
        let wheel_now = self.wheels_at(stamp_ns)?;
        let guess = match self.last {
            Some((wheel_then, refined)) => refined * (wheel_then.inverse() * wheel_now),
            None => wheel_now,
        };
        let deskewed;
        let points = match sweep {
            Some(sweep) => {
                deskewed = self.deskew(stamp_ns, points, sweep);
                &deskewed[..]
            }
            None => points,
        };
        let max_range = if self.cfg.max_range_m > 0.0 {
            self.cfg.max_range_m
        } else {
            f64::INFINITY
        };
        let narrow = narrow_returns(points, &self.cfg);
        let in_base: Vec<Vector2<f64>> = points
            .iter()
            .zip(&narrow)
            .filter(|(p, narrow)| **narrow && p.norm() <= max_range)
            .map(|(p, _)| (self.base_from_scan * nalgebra::Point2::from(*p)).coords)
            .collect();
        let mut step = ScanStep {
            odom_from_base: guess,
            registered: false,
            degenerate: false,
        };
        // A limit of 0 refuses every correction: the wheels alone, no need to register.
        let icp = self.cfg.max_correction_m > 0.0 && self.cfg.max_correction_rad > 0.0;
        if icp && !self.target.is_empty() {
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

    /// `points` moved to the scanner's pose at `stamp_ns`, in the same order: a return at
    /// bearing `a` was taken `(a − angle_min) / angle_increment · time_increment` after the
    /// stamp, while the base moved as the wheels and gyro tell, at constant velocity over
    /// the sweep.
    fn deskew(&self, stamp_ns: i64, points: &[Vector2<f64>], sweep: &Sweep) -> Vec<Vector2<f64>> {
        let increment = sweep.angle_increment_rad;
        if sweep.time_increment_s <= 0.0 || increment == 0.0 || !increment.is_finite() {
            return points.to_vec();
        }
        let seconds: Vec<f64> = points
            .iter()
            .map(|p| {
                let turned = ((p.y.atan2(p.x) - sweep.angle_min_rad) * increment.signum())
                    .rem_euclid(std::f64::consts::TAU);
                (turned / increment.abs()).round() * sweep.time_increment_s
            })
            .collect();
        let sweep_s = seconds.iter().copied().fold(0.0, f64::max);
        if sweep_s <= 0.0 {
            return points.to_vec();
        }
        let motion = self.motion_between(stamp_ns, stamp_ns + (sweep_s * 1e9).round() as i64);
        let scan_from_base = self.base_from_scan.inverse();
        points
            .iter()
            .zip(&seconds)
            .map(|(p, s)| {
                let moved = Isometry2::identity().lerp_slerp(&motion, s / sweep_s);
                (scan_from_base * moved * self.base_from_scan * nalgebra::Point2::from(*p)).coords
            })
            .collect()
    }

    /// The wheels' motion from `t0_ns` to `t1_ns`; past the newest reading, the motion over
    /// as long a span up to it (constant velocity).
    fn motion_between(&self, t0_ns: i64, t1_ns: i64) -> Isometry2<f64> {
        let shift = self
            .wheels
            .back()
            .map_or(0, |(newest, _)| (t1_ns - newest).max(0));
        match (self.wheels_at(t0_ns - shift), self.wheels_at(t1_ns - shift)) {
            (Some(a), Some(b)) => a.inverse() * b,
            _ => Isometry2::identity(),
        }
    }

    fn add_key_scan(&mut self, odom_from_base: &Isometry2<f64>, in_base: &[Vector2<f64>]) {
        let scan = slam_common::registration::scan2d::downsample(
            &in_base
                .iter()
                .map(|p| (odom_from_base * nalgebra::Point2::from(*p)).coords)
                .collect::<Vec<_>>(),
            self.cfg.icp.voxel_size_m,
        );
        self.last_key = Some(*odom_from_base);
        // A scan with nothing to register (a headland) leaves the map as it is: pushed, it
        // would neither add points nor ever be dropped by the size limit.
        if scan.is_empty() {
            return;
        }
        self.key_scans.push_back(scan);
        while self.key_scans.iter().map(Vec::len).sum::<usize>() > self.cfg.local_map_size
            && self.key_scans.len() > 1
        {
            self.key_scans.pop_front();
        }
        let points: Vec<Vector2<f64>> = self.key_scans.iter().flatten().copied().collect();
        self.target = Icp2dTarget::new(&points, &self.cfg.icp);
    }
}

/// Which of `points` (sensor frame, in scan order, as
/// [`slam_common::registration::scan2d::points_from_ranges`] gives them) lie on narrow objects, to be
/// registered (see [`ScanOdometryConfig::max_segment_m`]; all of them when it is 0). The
/// scan is cut into segments by Borges and Aldon's adaptive breakpoint detector ("Line
/// extraction in 2D range images for mobile robotics", J. Intelligent and Robotic Systems
/// 40, 2004): consecutive returns `p`, `q`, `Δφ` apart in bearing, lie on one surface when
/// `|q − p| ≤ |p| sin Δφ / sin(λ − Δφ) + 3σ`, i.e. when a surface through `p` seen at more
/// than `λ` from grazing incidence could have produced `q`. A segment whose bounding box
/// has a diagonal longer than `max_segment_m` is a surface, not an object.
pub fn narrow_returns(points: &[Vector2<f64>], cfg: &ScanOdometryConfig) -> Vec<bool> {
    let mut keep = vec![true; points.len()];
    if cfg.max_segment_m <= 0.0 || points.is_empty() {
        return keep;
    }
    let (sin_l, cos_l) = cfg.breakpoint_incidence_rad.sin_cos();
    let gap_noise = 3.0 * cfg.breakpoint_sigma_m;
    let mut close = |start: usize, end: usize| {
        let (lo, hi) = points[start..end]
            .iter()
            .fold((points[start], points[start]), |(lo, hi), p| {
                (lo.inf(p), hi.sup(p))
            });
        if (hi - lo).norm() > cfg.max_segment_m {
            keep[start..end].fill(false);
        }
    };
    let mut start = 0;
    for i in 1..points.len() {
        let (p, q) = (&points[i - 1], &points[i]);
        let norms = p.norm() * q.norm();
        let (sin_d, cos_d) = (p.perp(q).abs() / norms, p.dot(q) / norms);
        // sin(λ − Δφ), positive while Δφ < λ.
        let sin_rest = sin_l * cos_d - cos_l * sin_d;
        let joined = norms > 0.0
            && sin_rest > 0.0
            && (q - p).norm() <= p.norm() * sin_d / sin_rest + gap_noise;
        if !joined {
            close(start, i);
            start = i;
        }
    }
    close(start, points.len());
    keep
}

#[cfg(test)]
mod tests {
    use super::*;

    /// In scan order: a trunk (an arc 0.08 m wide), 2 m of ground contour, a post.
    #[test]
    fn a_ground_contour_is_dropped_and_narrow_objects_kept() {
        let mut points = Vec::new();
        for k in -2..=2 {
            let a = f64::from(k) * 0.4;
            points.push(Vector2::new(2.0, 1.0) + 0.04 * Vector2::new(-a.cos(), a.sin()));
        }
        let contour = points.len();
        for k in 0..=100 {
            points.push(Vector2::new(
                3.0 + 0.02 * f64::from(k),
                0.3 - 0.01 * f64::from(k),
            ));
        }
        let post = points.len();
        points.extend([Vector2::new(1.5, -1.5), Vector2::new(1.52, -1.49)]);
        let keep = narrow_returns(&points, &ScanOdometryConfig::default());
        assert!(keep[..contour].iter().all(|k| *k), "trunk {keep:?}");
        assert!(keep[contour..post].iter().all(|k| !*k), "contour {keep:?}");
        assert!(keep[post..].iter().all(|k| *k), "post {keep:?}");
        let all = ScanOdometryConfig {
            max_segment_m: 0.0,
            ..ScanOdometryConfig::default()
        };
        assert!(narrow_returns(&points, &all).iter().all(|k| *k));
    }

    /// A scanner turning on the spot at 1 rad/s sweeps a circle of posts; moved to the
    /// stamp, each return lies where it is in the frame of the sweep's start.
    #[test]
    fn a_turning_sweep_is_moved_to_its_stamp() {
        let cfg = ScanOdometryConfig {
            yaw_source: YawSource::Wheels,
            ..ScanOdometryConfig::default()
        };
        let mut odometry = ScanOdometry::new(cfg, &Isometry3::identity());
        for k in 0..5 {
            odometry.on_wheels(k * 10_000_000, 0.0, 1.0);
        }
        let sweep = Sweep {
            angle_min_rad: -2.0,
            angle_increment_rad: 0.01,
            time_increment_s: 5e-5,
        };
        let (mut measured, mut truth) = (Vec::new(), Vec::new());
        for i in (0..400).step_by(10) {
            let bearing = sweep.angle_min_rad + f64::from(i) * sweep.angle_increment_rad;
            let turned = f64::from(i) * sweep.time_increment_s;
            measured.push(3.0 * Vector2::new(bearing.cos(), bearing.sin()));
            let world = bearing + turned;
            truth.push(3.0 * Vector2::new(world.cos(), world.sin()));
        }
        let deskewed = odometry.deskew(0, &measured, &sweep);
        for (d, t) in deskewed.iter().zip(&truth) {
            assert!((d - t).norm() < 1e-6, "{d:?} vs {t:?}");
        }
        // Uncorrected, the sweep's end is off by 0.02 rad at 3 m.
        assert!((measured[39] - truth[39]).norm() > 0.05);
    }
}
