//! Ground truth: the base's pose and velocity from the trajectory itself.

use super::{GroundTruth, Message, Scene, Sensor, sample_time_ns};

#[derive(Debug)]
pub struct GroundTruthSensor {
    rate_hz: f64,
    k: u64,
    end_ns: i64,
}

impl GroundTruthSensor {
    pub fn new(rate_hz: f64, end_ns: i64) -> Self {
        Self {
            rate_hz,
            k: 0,
            end_ns,
        }
    }
}

impl Sensor for GroundTruthSensor {
    fn next_ready_ns(&self) -> Option<i64> {
        let t = sample_time_ns(self.k, self.rate_hz);
        (t <= self.end_ns).then_some(t)
    }

    fn emit(&mut self, scene: &Scene<'_>) -> Message {
        let stamp_ns = sample_time_ns(self.k, self.rate_hz);
        self.k += 1;
        let s = scene.trajectory.state(stamp_ns);
        Message::GroundTruth(GroundTruth {
            stamp_ns,
            world_from_base: s.world_from_base,
            velocity_in_world: s.velocity,
            omega_in_base: s.omega_in_base,
        })
    }
}
