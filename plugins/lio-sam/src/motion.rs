//! The sensor's motion during and between sweeps, as a short list of timed poses with
//! interpolation in between: from the IMU (preintegrated from the last estimated state,
//! LIO-SAM's imuPreintegration and imageProjection) or, without an IMU, from the constant
//! velocity of the last two estimates. Used to predict the pose at a sweep's start (the
//! initial guess of registration) and to deskew every point to that start.

use std::collections::VecDeque;

use nalgebra::{Isometry3, Vector3};
use plugin_api::Imu;
use slam_common::factor_graph::backend::{ImuBias, ImuSample};
use slam_common::motion::imu::{NavState, Preintegrated};

/// Poses of a frame at increasing times, in nanoseconds.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Motion {
    samples: Vec<(i64, Isometry3<f64>)>,
}

impl Motion {
    pub fn new(samples: Vec<(i64, Isometry3<f64>)>) -> Self {
        Self { samples }
    }

    /// The pose at `t_ns`, interpolated (linear in translation, slerp in rotation) and held
    /// constant-velocity beyond the ends.
    pub fn at(&self, t_ns: i64) -> Option<Isometry3<f64>> {
        let s = &self.samples;
        match s.len() {
            0 => None,
            1 => Some(s[0].1),
            _ => {
                let i = s.partition_point(|(t, _)| *t <= t_ns).clamp(1, s.len() - 1);
                let ((t0, a), (t1, b)) = (s[i - 1], s[i]);
                let u = (t_ns - t0) as f64 / (t1 - t0).max(1) as f64;
                Some(interpolate(&a, &b, u))
            }
        }
    }
}

/// `a` at u = 0, `b` at u = 1, extrapolated outside.
pub fn interpolate(a: &Isometry3<f64>, b: &Isometry3<f64>, u: f64) -> Isometry3<f64> {
    let delta = a.inverse() * b;
    let step = Isometry3::from_parts(
        (delta.translation.vector * u).into(),
        nalgebra::UnitQuaternion::from_scaled_axis(delta.rotation.scaled_axis() * u),
    );
    a * step
}

/// IMU messages waiting to be integrated.
#[derive(Debug, Clone, Default)]
pub struct ImuQueue {
    queue: VecDeque<Imu>,
}

impl ImuQueue {
    pub fn push(&mut self, imu: Imu) {
        self.queue.push_back(imu);
    }

    pub fn is_empty(&self) -> bool {
        self.queue.is_empty()
    }

    /// Drops messages older than `t_ns` except the last one before it, which covers
    /// the interval up to it.
    pub fn discard_before(&mut self, t_ns: i64) {
        while self.queue.len() > 1 && self.queue[1].stamp_ns <= t_ns {
            self.queue.pop_front();
        }
    }

    /// Samples covering `[t0, t1]`, each held from its stamp to the next (a zero-order hold,
    /// clipped to the interval), with the times they start at.
    pub fn samples(&self, t0_ns: i64, t1_ns: i64) -> Vec<(i64, ImuSample)> {
        let mut out = Vec::new();
        for (i, m) in self.queue.iter().enumerate() {
            let next = self
                .queue
                .get(i + 1)
                .map_or(t1_ns, |n| n.stamp_ns.min(t1_ns));
            let start = m.stamp_ns.max(t0_ns);
            if next <= start || m.stamp_ns >= t1_ns {
                continue;
            }
            out.push((
                start,
                ImuSample {
                    dt_s: (next - start) as f64 * 1e-9,
                    accel_mps2: Vector3::from(m.accel_mps2),
                    gyro_rps: Vector3::from(m.gyro_rps),
                },
            ));
        }
        out
    }

    /// The mean specific force over the first messages: gravity, when at rest.
    pub fn mean_accel(&self) -> Option<Vector3<f64>> {
        (!self.queue.is_empty()).then(|| {
            self.queue
                .iter()
                .map(|m| Vector3::from(m.accel_mps2))
                .sum::<Vector3<f64>>()
                / self.queue.len() as f64
        })
    }
}

/// Integrates the IMU from `start` at `t0_ns` over `samples`, returning the IMU's pose at
/// every sample boundary and the state at the end.
pub fn propagate(
    start: &NavState,
    t0_ns: i64,
    samples: &[(i64, ImuSample)],
    bias: &ImuBias,
    gravity_mps2: f64,
) -> (Motion, NavState) {
    let mut poses = vec![(t0_ns, start.world_from_imu)];
    let mut pre = Preintegrated::new(*bias);
    let mut state = *start;
    for (t, s) in samples {
        pre.integrate(s);
        state = pre.predict(start, gravity_mps2, bias);
        poses.push((t + (s.dt_s * 1e9).round() as i64, state.world_from_imu));
    }
    (Motion::new(poses), state)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    #[test]
    fn interpolation_is_exact_at_the_samples_and_extrapolates() {
        let a = Isometry3::identity();
        let b = Isometry3::from_parts(
            Translation3::new(1.0, 0.0, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 0.2),
        );
        let m = Motion::new(vec![(0, a), (100, b)]);
        assert_eq!(m.at(0), Some(a));
        let end = m.at(100).expect("two samples");
        assert!((end.inverse() * b).translation.vector.norm() < 1e-12);
        let beyond = m.at(200).expect("extrapolated");
        assert!(
            (beyond.rotation.euler_angles().2 - 0.4).abs() < 1e-12,
            "constant rate beyond the end"
        );
    }

    #[test]
    fn imu_samples_are_clipped_to_the_interval() {
        let mut q = ImuQueue::default();
        for k in 0..10 {
            q.push(Imu {
                stamp_ns: k * 5_000_000,
                accel_mps2: [0.0, 0.0, 9.8],
                gyro_rps: [0.0; 3],
                orientation_xyzw: [0.0; 4],
            });
        }
        let s = q.samples(7_000_000, 21_000_000);
        let total: f64 = s.iter().map(|(_, s)| s.dt_s).sum();
        assert!((total - 0.014).abs() < 1e-12, "14 ms covered, got {total}");
        assert_eq!(s[0].0, 7_000_000);
    }
}
