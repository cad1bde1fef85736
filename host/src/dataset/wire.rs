//! A simulator message as the ROS 2 messages that carry it, and back: the one message codec
//! of the host. The recorder writes these messages into MCAP ([`super::Recorder`]), replay
//! reads them back ([`super::Replay`]), and a shared simulation streams them to its workers
//! (`runner::feed`), all through [`to_ros`] and [`Assembler`], so every value comes back bit
//! for bit whichever way it travelled.

use nalgebra::Isometry3;
use sim::sensors::{LaserScan, Message, ScanSide};

use super::decode::{self, Plane};
use super::topics::{LASER_BACK_FRAME, LASER_FRONT_FRAME, Topic};
use super::{DatasetError, encode};

/// What the ROS messages say that the simulator's do not: per 2D scanner, the scan period
/// (s) and how long after its stamp a scan is complete (ns), as
/// [`sim::sensors::Scan2dSensor`] times it (the mirror turns once per period, samples
/// `time_increment` apart); the camera's lens (`camera_info`'s `d`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WireDetails {
    scans: [(f32, i64); 2],
    /// `plumb_bob` `[k1, k2, p1, p2, k3]` (zero: a rectified image).
    distortion: [f64; 5],
}

impl WireDetails {
    pub fn new(config: &sim::SimConfig) -> Self {
        let timing = |cfg: &sim::config::Scan2dConfig| {
            let angle_increment =
                (cfg.angle_max_rad - cfg.angle_min_rad) / (cfg.samples - 1) as f64;
            let time_increment_s = angle_increment / std::f64::consts::TAU / cfg.rate_hz;
            let sweep_ns = (time_increment_s * (cfg.samples - 1) as f64 * 1e9).round() as i64;
            ((1.0 / cfg.rate_hz) as f32, sweep_ns)
        };
        let s = &config.sensors;
        Self {
            scans: [timing(&s.scan2d_front), timing(&s.scan2d_back)],
            distortion: s.camera.distortion,
        }
    }

    fn scan(&self, m: &LaserScan) -> (Topic, &'static str, (f32, i64)) {
        match m.side {
            ScanSide::Front => (Topic::ScanFront, LASER_FRONT_FRAME, self.scans[0]),
            ScanSide::Back => (Topic::ScanBack, LASER_BACK_FRAME, self.scans[1]),
        }
    }
}

/// One ROS 2 message: its topic, when it became available (simulated ns: a sweep's end,
/// everything else its stamp) and its CDR bytes.
pub type RosMessage = (Topic, i64, Vec<u8>);

/// The ROS 2 messages of one simulator message, in the order a reader needs them: ground
/// truth as its pose then its twist; a camera frame as colour, depth, then camera info.
pub fn to_ros(message: &Message, details: &WireDetails) -> Vec<RosMessage> {
    match message {
        Message::GroundTruth(m) => vec![
            (Topic::GroundTruth, m.stamp_ns, encode::pose_stamped(m)),
            (
                Topic::GroundTruthTwist,
                m.stamp_ns,
                encode::twist_stamped(m),
            ),
        ],
        Message::Imu(m) => vec![(Topic::Imu, m.stamp_ns, encode::imu(m))],
        // Available after the receiver's latency; the NavSatFix first, completed by the
        // east-north-up message.
        Message::Gnss(m) => {
            let ready = m.stamp_ns + m.latency_ns;
            vec![
                (Topic::GnssFix, ready, encode::nav_sat_fix(m)),
                (Topic::GnssEnu, ready, encode::gnss_enu(m)),
            ]
        }
        Message::WheelOdometry(m) => vec![(Topic::Odom, m.stamp_ns, encode::odometry(m))],
        Message::Lidar(m) => vec![(
            Topic::Points,
            m.stamp_ns + m.sweep_ns,
            encode::point_cloud(m),
        )],
        Message::Scan2d(m) => {
            let (topic, frame, (scan_time_s, sweep_ns)) = details.scan(m);
            vec![(
                topic,
                m.stamp_ns + sweep_ns,
                encode::laser_scan(m, frame, scan_time_s),
            )]
        }
        // A frame is available whole at its stamp (global shutter); the camera info comes
        // last and completes it.
        Message::Rgbd(m) => vec![
            (Topic::ColorImage, m.stamp_ns, encode::color_image(m)),
            (Topic::DepthImage, m.stamp_ns, encode::depth_image(m)),
            (
                Topic::CameraInfo,
                m.stamp_ns,
                encode::camera_info(m, &details.distortion),
            ),
        ],
    }
}

/// Turns ROS 2 messages back into simulator messages: the inverse of [`to_ros`].
#[derive(Debug, Default)]
pub struct Assembler {
    /// A `/ground_truth` pose waiting for its `/ground_truth/twist`.
    pose: Option<(i64, Isometry3<f64>)>,
    /// A camera frame's colour and depth images waiting for its camera info.
    color: Option<Plane<u8>>,
    depth: Option<Plane<f32>>,
    /// A `/gnss/fix` (stamp, geodetic position) waiting for its `/gnss/enu`.
    fix: Option<(i64, Option<[f64; 3]>)>,
}

impl Assembler {
    /// Takes one message (`ready_ns`: when it became available); returns the simulator
    /// message it completes, `None` for the first parts of a ground truth or camera frame
    /// (and for `/tf_static`).
    pub fn push(
        &mut self,
        topic: Topic,
        ready_ns: i64,
        data: &[u8],
    ) -> Result<Option<Message>, DatasetError> {
        Ok(Some(match topic {
            Topic::Imu => Message::Imu(decode::imu(data)?),
            Topic::Odom => Message::WheelOdometry(decode::odometry(data)?),
            Topic::Points => Message::Lidar(decode::point_cloud(data, ready_ns)?),
            Topic::ScanFront => Message::Scan2d(decode::laser_scan(data, ScanSide::Front)?),
            Topic::ScanBack => Message::Scan2d(decode::laser_scan(data, ScanSide::Back)?),
            Topic::GroundTruth => {
                self.pose = Some(decode::pose_stamped(data)?);
                return Ok(None);
            }
            Topic::GroundTruthTwist => {
                let pose = self
                    .pose
                    .take()
                    .ok_or_else(|| DatasetError::decode("a twist without the pose before it"))?;
                Message::GroundTruth(decode::twist_stamped(data, pose)?)
            }
            Topic::ColorImage => {
                if self.color.is_some() {
                    return Err(DatasetError::decode(
                        "a colour image follows one without its camera info",
                    ));
                }
                self.color = Some(decode::color_image(data)?);
                return Ok(None);
            }
            Topic::DepthImage => {
                if self.color.is_none() || self.depth.is_some() {
                    return Err(DatasetError::decode(
                        "a depth image without a colour image just before it",
                    ));
                }
                self.depth = Some(decode::depth_image(data)?);
                return Ok(None);
            }
            Topic::CameraInfo => {
                let (Some(color), Some(depth)) = (self.color.take(), self.depth.take()) else {
                    return Err(DatasetError::decode(
                        "a camera info without the colour and depth images before it",
                    ));
                };
                Message::Rgbd(decode::camera_info(data, color, depth)?)
            }
            Topic::GnssFix => {
                if self.fix.is_some() {
                    return Err(DatasetError::decode(
                        "a /gnss/fix follows one without its /gnss/enu",
                    ));
                }
                self.fix = Some(decode::nav_sat_fix(data)?);
                return Ok(None);
            }
            Topic::GnssEnu => {
                let fix = self.fix.take().ok_or_else(|| {
                    DatasetError::decode("a /gnss/enu without the /gnss/fix before it")
                })?;
                Message::Gnss(decode::gnss_enu(data, fix)?)
            }
            Topic::TfStatic => return Ok(None),
        }))
    }
}
