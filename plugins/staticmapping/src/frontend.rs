//! Scan-to-keyframe lidar odometry, StaticMapping's front end: each sweep is matched by
//! [`crate::icp`] to the last keyframe, from a guess extrapolated from the poses before it
//! (the gyroscope's rotation when the IMU is used, constant velocity otherwise, as
//! Cartographer's pose extrapolator, which StaticMapping adopts); a sweep becomes the new
//! keyframe once it has moved `keyframe_translation_m` or turned `keyframe_angle_deg`
//! (the sum of its absolute Euler angles) from the last one.

use nalgebra::{Isometry3, UnitQuaternion, Vector3};

use crate::config::{FrontEndConfig, IcpConfig};
use crate::icp::{self, Reference};
use crate::input::{self, Sweep};

/// A gyroscope sample: stamp and angular rate in the IMU frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gyro {
    pub stamp_ns: i64,
    pub rate_rps: Vector3<f64>,
}

/// The rotation of the IMU frame from `t0_ns` to `t1_ns` (`imu0_from_imu1`), integrating
/// the rates as held from each sample to the next. None without samples covering `t0_ns`.
pub fn gyro_rotation(samples: &[Gyro], t0_ns: i64, t1_ns: i64) -> Option<UnitQuaternion<f64>> {
    if t1_ns <= t0_ns {
        return Some(UnitQuaternion::identity());
    }
    // The sample in force at t0: the last at or before it.
    let first = samples.partition_point(|s| s.stamp_ns <= t0_ns);
    if first == 0 || samples.last()?.stamp_ns < t0_ns {
        return None;
    }
    let mut q = UnitQuaternion::identity();
    let mut t = t0_ns;
    let mut k = first - 1;
    while t < t1_ns {
        let until = samples.get(k + 1).map_or(t1_ns, |s| s.stamp_ns.min(t1_ns));
        let dt = (until - t) as f64 * 1e-9;
        q *= UnitQuaternion::from_scaled_axis(samples[k].rate_rps * dt);
        t = until;
        k += 1;
        if k >= samples.len() {
            k = samples.len() - 1;
        }
    }
    Some(q)
}

/// Predicts the lidar's pose at a time from the poses registered so far (Cartographer's
/// pose extrapolator): velocities from the oldest and newest pose of a queue spanning
/// `queue_ns`.
#[derive(Debug, Clone)]
pub struct Extrapolator {
    /// Registered poses, `world_from_lidar`, with their stamps, oldest first.
    poses: std::collections::VecDeque<(i64, Isometry3<f64>)>,
    queue_ns: i64,
    imu_from_lidar: UnitQuaternion<f64>,
}

impl Extrapolator {
    pub fn new(imu_from_lidar: UnitQuaternion<f64>, queue_ns: i64) -> Self {
        Self {
            poses: std::collections::VecDeque::new(),
            queue_ns,
            imu_from_lidar,
        }
    }

    /// Adds a pose; the queue keeps the newest pose at least `queue_ns` old and those after
    /// it.
    pub fn add(&mut self, stamp_ns: i64, world_from_lidar: Isometry3<f64>) {
        self.poses.push_back((stamp_ns, world_from_lidar));
        while self.poses.len() > 2 && self.poses[1].0 <= stamp_ns - self.queue_ns {
            self.poses.pop_front();
        }
    }

    /// The pose at `t_ns`: the last pose moved on at the last velocity; rotated by the
    /// gyroscope if `gyro` is given and covers the interval, else at the last angular
    /// velocity.
    pub fn predict(&self, t_ns: i64, gyro: Option<&[Gyro]>) -> Isometry3<f64> {
        let Some(&(t1, last)) = self.poses.back() else {
            return Isometry3::identity();
        };
        let dt_ahead = (t_ns - t1) as f64 * 1e-9;
        let (velocity, spin) = match self.poses.front() {
            Some(&(t0, prev)) if t1 > t0 => {
                let dt = (t1 - t0) as f64 * 1e-9;
                let v = (last.translation.vector - prev.translation.vector) / dt;
                // Angular velocity in the lidar frame, from the last interval.
                let w = (prev.rotation.inverse() * last.rotation).scaled_axis() / dt;
                (v, w)
            }
            _ => (Vector3::zeros(), Vector3::zeros()),
        };
        let turn = gyro
            .and_then(|g| gyro_rotation(g, t1, t_ns))
            .map(|imu| self.imu_from_lidar.inverse() * imu * self.imu_from_lidar)
            .unwrap_or_else(|| UnitQuaternion::from_scaled_axis(spin * dt_ahead));
        Isometry3::from_parts(
            (last.translation.vector + velocity * dt_ahead).into(),
            last.rotation * turn,
        )
    }
}

/// A keyframe: a sweep de-skewed, in its own lidar frame, and its front-end pose.
#[derive(Debug, Clone)]
pub struct Keyframe {
    pub stamp_ns: i64,
    pub world_from_lidar: Isometry3<f64>,
    pub cloud: Vec<Vector3<f64>>,
}

/// What the front end makes of the whole stream.
#[derive(Debug, Clone, Default)]
pub struct Odometry {
    pub keyframes: Vec<Keyframe>,
    /// Every sweep: stamp, front-end pose, and the keyframe it was matched to (its own index
    /// if it became one).
    pub sweeps: Vec<(i64, Isometry3<f64>, usize)>,
    /// Sweeps whose match failed (too few points): the guess was kept.
    pub failed_matches: usize,
    /// Mean score of the sweep matches.
    pub mean_score: f64,
}

/// True when `keyframe_from_sweep` has moved far enough for a new keyframe.
pub fn is_keyframe(keyframe_from_sweep: &Isometry3<f64>, cfg: &FrontEndConfig) -> bool {
    let (r, p, y) = keyframe_from_sweep.rotation.euler_angles();
    let angle_deg = (r.abs() + p.abs() + y.abs()).to_degrees();
    keyframe_from_sweep.translation.vector.norm() >= cfg.keyframe_translation_m
        || (cfg.keyframe_angle_deg > 1e-3 && angle_deg >= cfg.keyframe_angle_deg)
}

/// The front end one sweep at a time: the offline build runs it over the whole stream
/// ([`run`]); localisation (issue 46) runs it online, as odometry.
#[derive(Debug, Clone)]
pub struct FrontEnd {
    sweep_ns: i64,
    deskew: bool,
    cfg: FrontEndConfig,
    icp: IcpConfig,
    extrapolator: Extrapolator,
    reference: Option<Reference>,
    score_sum: f64,
    scored: usize,
    /// Keep every keyframe and sweep (the offline build) or only the last keyframe (online).
    history: bool,
    /// What the sweeps so far made (`mean_score` is set by [`FrontEnd::finish`]).
    pub odometry: Odometry,
}

impl FrontEnd {
    pub fn new(
        imu_from_lidar: UnitQuaternion<f64>,
        sweep_ns: i64,
        deskew: bool,
        cfg: &FrontEndConfig,
        icp: &IcpConfig,
    ) -> Self {
        let queue_ns = (cfg.pose_queue_s * 1e9).round() as i64;
        Self {
            sweep_ns,
            deskew,
            cfg: cfg.clone(),
            icp: icp.clone(),
            extrapolator: Extrapolator::new(imu_from_lidar, queue_ns),
            reference: None,
            score_sum: 0.0,
            scored: 0,
            history: true,
            odometry: Odometry::default(),
        }
    }

    /// Keeps only the last keyframe and no sweep list: odometry for a run of any length.
    pub fn without_history(mut self) -> Self {
        self.history = false;
        self
    }

    /// Registers the next sweep (in time order), with the gyroscope's samples so far if it
    /// uses the IMU: its pose `world_from_lidar` and its de-skewed cloud, lidar frame.
    pub fn step(
        &mut self,
        sweep: &Sweep,
        gyro: Option<&[Gyro]>,
    ) -> (Isometry3<f64>, Vec<Vector3<f64>>) {
        let gyro = gyro.filter(|g| !g.is_empty());
        let sweep_s = self.sweep_ns as f64 * 1e-9;
        let guess = self.extrapolator.predict(sweep.stamp_ns, gyro);
        let motion = self.deskew.then(|| {
            guess.inverse()
                * self
                    .extrapolator
                    .predict(sweep.stamp_ns + self.sweep_ns, gyro)
        });
        let cloud = input::deskew(sweep, motion.as_ref(), sweep_s);
        let out = &mut self.odometry;
        let pose = match (out.keyframes.last(), &self.reference) {
            (Some(kf), Some(target)) => {
                let kf_from_guess = kf.world_from_lidar.inverse() * guess;
                match icp::align(&cloud, target, &kf_from_guess, &self.icp) {
                    Some(a) => {
                        self.score_sum += a.score;
                        self.scored += 1;
                        kf.world_from_lidar * a.reference_from_reading
                    }
                    None => {
                        out.failed_matches += 1;
                        guess
                    }
                }
            }
            _ => guess,
        };
        self.extrapolator.add(sweep.stamp_ns, pose);
        let new_keyframe = match out.keyframes.last() {
            None => true,
            Some(kf) => is_keyframe(&(kf.world_from_lidar.inverse() * pose), &self.cfg),
        };
        if new_keyframe {
            self.reference = Some(Reference::new(&cloud, self.icp.knn_normal));
            if !self.history {
                out.keyframes.clear();
            }
            out.keyframes.push(Keyframe {
                stamp_ns: sweep.stamp_ns,
                world_from_lidar: pose,
                cloud: cloud.clone(),
            });
        }
        if self.history {
            out.sweeps
                .push((sweep.stamp_ns, pose, out.keyframes.len() - 1));
        }
        (pose, cloud)
    }

    /// The odometry of every sweep stepped, with its mean match score.
    pub fn finish(mut self) -> Odometry {
        self.odometry.mean_score = if self.scored > 0 {
            self.score_sum / self.scored as f64
        } else {
            0.0
        };
        self.odometry
    }
}

/// Runs the front end over `sweeps` (in time order), each lasting `sweep_ns`, with the
/// gyroscope's samples if it uses the IMU, deskewing each sweep if `deskew`.
pub fn run(
    sweeps: &[Sweep],
    gyro: Option<&[Gyro]>,
    imu_from_lidar: UnitQuaternion<f64>,
    sweep_ns: i64,
    deskew: bool,
    front_end: &FrontEndConfig,
    icp_cfg: &IcpConfig,
) -> Odometry {
    let mut f = FrontEnd::new(imu_from_lidar, sweep_ns, deskew, front_end, icp_cfg);
    for sweep in sweeps {
        f.step(sweep, gyro);
    }
    f.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gyro_rotation_integrates_a_constant_rate() {
        let samples: Vec<Gyro> = (0..=200)
            .map(|k| Gyro {
                stamp_ns: k * 5_000_000,
                rate_rps: Vector3::new(0.0, 0.0, 0.5),
            })
            .collect();
        let q = gyro_rotation(&samples, 100_000_000, 600_000_000).expect("covered");
        assert!((q.angle() - 0.25).abs() < 1e-12, "{}", q.angle());
        assert!(
            gyro_rotation(&samples, -1, 10).is_none(),
            "not covered before the first"
        );
    }

    #[test]
    fn extrapolates_constant_velocity() {
        let mut e = Extrapolator::new(UnitQuaternion::identity(), 1_000_000);
        let pose = |t: f64| {
            Isometry3::from_parts(
                Vector3::new(0.5 * t, 0.1 * t, 0.0).into(),
                UnitQuaternion::from_euler_angles(0.0, 0.0, 0.2 * t),
            )
        };
        e.add(0, pose(0.0));
        e.add(100_000_000, pose(0.1));
        let p = e.predict(200_000_000, None);
        let err = p.inverse() * pose(0.2);
        assert!(err.translation.vector.norm() < 1e-9 && err.rotation.angle() < 1e-9);
    }

    #[test]
    fn keyframe_after_a_metre_or_one_and_a_half_degrees() {
        let cfg = FrontEndConfig::default();
        let moved = |x: f64, yaw_deg: f64| {
            Isometry3::from_parts(
                Vector3::new(x, 0.0, 0.0).into(),
                UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_deg.to_radians()),
            )
        };
        assert!(!is_keyframe(&moved(0.9, 1.4), &cfg));
        assert!(is_keyframe(&moved(1.0, 0.0), &cfg));
        assert!(is_keyframe(&moved(0.0, 1.5), &cfg));
    }
}
