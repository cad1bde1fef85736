//! The recording's topics, their ROS 2 types and frame names (REP 105).

/// Frame of the IMU (`sensor_msgs/Imu` header).
pub const IMU_FRAME: &str = "imu_link";
/// Frame of the 3D lidar, named as the Velodyne ROS driver names it.
pub const LIDAR_FRAME: &str = "velodyne";
pub const LASER_FRONT_FRAME: &str = "laser_front";
pub const LASER_BACK_FRAME: &str = "laser_back";
pub const BASE_FRAME: &str = "base_link";
pub const ODOM_FRAME: &str = "odom";
pub const MAP_FRAME: &str = "map";
/// Optical frame (z forward, x right, y down; REP 103) of the RGB-D camera's colour image,
/// which the registered depth image shares, named as the RealSense and Kinect ROS drivers
/// name theirs.
pub const CAMERA_FRAME: &str = "camera_color_optical_frame";
/// Frame of the GNSS antenna (its phase centre), as `navsat_transform` expects a `gps` frame.
pub const GNSS_FRAME: &str = "gnss_link";

/// A topic of a recording.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Topic {
    TfStatic,
    GroundTruth,
    GroundTruthTwist,
    Imu,
    Odom,
    ScanFront,
    ScanBack,
    Points,
    ColorImage,
    DepthImage,
    CameraInfo,
    GnssFix,
    GnssEnu,
}

impl Topic {
    pub const ALL: [Topic; 13] = [
        Topic::TfStatic,
        Topic::GroundTruth,
        Topic::GroundTruthTwist,
        Topic::Imu,
        Topic::Odom,
        Topic::ScanFront,
        Topic::ScanBack,
        Topic::Points,
        Topic::ColorImage,
        Topic::DepthImage,
        Topic::CameraInfo,
        Topic::GnssFix,
        Topic::GnssEnu,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Topic::TfStatic => "/tf_static",
            Topic::GroundTruth => "/ground_truth",
            Topic::GroundTruthTwist => "/ground_truth/twist",
            Topic::Imu => "/imu",
            Topic::Odom => "/odom",
            Topic::ScanFront => "/scan_front",
            Topic::ScanBack => "/scan_back",
            Topic::Points => "/points",
            Topic::ColorImage => "/camera/color/image_raw",
            Topic::DepthImage => "/camera/depth/image_raw",
            Topic::CameraInfo => "/camera/color/camera_info",
            Topic::GnssFix => "/gnss/fix",
            Topic::GnssEnu => "/gnss/enu",
        }
    }

    /// The ROS 2 type, as rosbag2 names it in a schema.
    pub fn schema(self) -> &'static str {
        match self {
            Topic::TfStatic => "tf2_msgs/msg/TFMessage",
            Topic::GroundTruth => "geometry_msgs/msg/PoseStamped",
            Topic::GroundTruthTwist => "geometry_msgs/msg/TwistStamped",
            Topic::Imu => "sensor_msgs/msg/Imu",
            Topic::Odom => "nav_msgs/msg/Odometry",
            Topic::ScanFront | Topic::ScanBack => "sensor_msgs/msg/LaserScan",
            Topic::Points => "sensor_msgs/msg/PointCloud2",
            Topic::ColorImage | Topic::DepthImage => "sensor_msgs/msg/Image",
            Topic::CameraInfo => "sensor_msgs/msg/CameraInfo",
            Topic::GnssFix => "sensor_msgs/msg/NavSatFix",
            Topic::GnssEnu => "vinebench_msgs/msg/GnssEnu",
        }
    }

    pub fn from_name(name: &str) -> Option<Topic> {
        Topic::ALL.into_iter().find(|t| t.name() == name)
    }

    /// Whether a stream of `sensors` carries this topic (`/tf_static` always).
    pub fn in_set(self, sensors: &sim::SensorSet) -> bool {
        match self {
            Topic::TfStatic => true,
            Topic::GroundTruth | Topic::GroundTruthTwist => sensors.ground_truth,
            Topic::Imu => sensors.imu,
            Topic::Odom => sensors.wheel_odometry,
            Topic::ScanFront | Topic::ScanBack => sensors.scan2d,
            Topic::Points => sensors.lidar,
            Topic::ColorImage | Topic::DepthImage | Topic::CameraInfo => sensors.rgbd,
            Topic::GnssFix | Topic::GnssEnu => sensors.gnss,
        }
    }
}
