//! The RGB-D camera as a sensor of the stream: a frame at every period, rendered from the
//! robot's pose at its stamp (global shutter; colour and depth registered and simultaneous).

use super::{Message, RgbdFrame, Scene, Sensor, sample_time_ns};
use crate::camera::RgbdCamera;
use crate::rng::SimRng;

#[derive(Debug)]
pub struct RgbdSensor {
    camera: RgbdCamera,
    k: u64,
    end_ns: i64,
    rng: SimRng,
}

impl RgbdSensor {
    pub fn new(camera: RgbdCamera, end_ns: i64, rng: SimRng) -> Self {
        Self {
            camera,
            k: 0,
            end_ns,
            rng,
        }
    }
}

impl Sensor for RgbdSensor {
    fn next_ready_ns(&self) -> Option<i64> {
        let t = sample_time_ns(self.k, self.camera.config().rate_hz);
        (t <= self.end_ns).then_some(t)
    }

    fn emit(&mut self, scene: &Scene<'_>) -> Message {
        let stamp_ns = sample_time_ns(self.k, self.camera.config().rate_hz);
        self.k += 1;
        let image = self
            .camera
            .render(&scene.trajectory.pose(stamp_ns), &mut self.rng);
        Message::Rgbd(RgbdFrame { stamp_ns, image })
    }
}
