//! ROS 2 message definitions for the MCAP `ros2msg` schema encoding.
//!
//! A schema's data is the `.msg` text of the type followed by every type it depends on, each
//! introduced by a line of 80 `=` and a `MSG: pkg/Name` line (the format rosbag2 writes and
//! Foxglove and `mcap-ros2-support` parse; MCAP spec, "Well-known schema encodings":
//! <https://mcap.dev/spec/registry#ros2msg>). The texts are those of ROS 2 Humble's
//! `common_interfaces` (`visualization_msgs/Marker` of version 4.2, with the texture and
//! mesh-file fields added in 3.0) and `rcl_interfaces` with the comments left out.

/// Each type with its definition and the types it uses directly.
const DEFINITIONS: &[(&str, &str, &[&str])] = &[
    (
        "builtin_interfaces/Time",
        "int32 sec\nuint32 nanosec\n",
        &[],
    ),
    (
        "builtin_interfaces/Duration",
        "int32 sec\nuint32 nanosec\n",
        &[],
    ),
    (
        "std_msgs/Header",
        "builtin_interfaces/Time stamp\nstring frame_id\n",
        &["builtin_interfaces/Time"],
    ),
    (
        "std_msgs/ColorRGBA",
        "float32 r\nfloat32 g\nfloat32 b\nfloat32 a\n",
        &[],
    ),
    (
        "geometry_msgs/Vector3",
        "float64 x\nfloat64 y\nfloat64 z\n",
        &[],
    ),
    (
        "geometry_msgs/Point",
        "float64 x\nfloat64 y\nfloat64 z\n",
        &[],
    ),
    (
        "geometry_msgs/Quaternion",
        "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
        &[],
    ),
    (
        "geometry_msgs/Pose",
        "Point position\nQuaternion orientation\n",
        &["geometry_msgs/Point", "geometry_msgs/Quaternion"],
    ),
    (
        "geometry_msgs/PoseStamped",
        "std_msgs/Header header\nPose pose\n",
        &["std_msgs/Header", "geometry_msgs/Pose"],
    ),
    (
        "geometry_msgs/PoseWithCovariance",
        "Pose pose\nfloat64[36] covariance\n",
        &["geometry_msgs/Pose"],
    ),
    (
        "geometry_msgs/Twist",
        "Vector3 linear\nVector3 angular\n",
        &["geometry_msgs/Vector3"],
    ),
    (
        "geometry_msgs/TwistWithCovariance",
        "Twist twist\nfloat64[36] covariance\n",
        &["geometry_msgs/Twist"],
    ),
    (
        "geometry_msgs/TwistStamped",
        "std_msgs/Header header\nTwist twist\n",
        &["std_msgs/Header", "geometry_msgs/Twist"],
    ),
    (
        "geometry_msgs/Transform",
        "Vector3 translation\nQuaternion rotation\n",
        &["geometry_msgs/Vector3", "geometry_msgs/Quaternion"],
    ),
    (
        "geometry_msgs/TransformStamped",
        "std_msgs/Header header\nstring child_frame_id\nTransform transform\n",
        &["std_msgs/Header", "geometry_msgs/Transform"],
    ),
    (
        "sensor_msgs/Imu",
        "std_msgs/Header header\n\
         geometry_msgs/Quaternion orientation\n\
         float64[9] orientation_covariance\n\
         geometry_msgs/Vector3 angular_velocity\n\
         float64[9] angular_velocity_covariance\n\
         geometry_msgs/Vector3 linear_acceleration\n\
         float64[9] linear_acceleration_covariance\n",
        &[
            "std_msgs/Header",
            "geometry_msgs/Quaternion",
            "geometry_msgs/Vector3",
        ],
    ),
    (
        "sensor_msgs/NavSatStatus",
        "int8 STATUS_NO_FIX =  -1\nint8 STATUS_FIX =      0\nint8 STATUS_SBAS_FIX = 1\n\
         int8 STATUS_GBAS_FIX = 2\nint8 status\n\
         uint16 SERVICE_GPS =     1\nuint16 SERVICE_GLONASS = 2\nuint16 SERVICE_COMPASS = 4\n\
         uint16 SERVICE_GALILEO = 8\nuint16 service\n",
        &[],
    ),
    (
        "sensor_msgs/NavSatFix",
        "std_msgs/Header header\n\
         NavSatStatus status\n\
         float64 latitude\nfloat64 longitude\nfloat64 altitude\n\
         float64[9] position_covariance\n\
         uint8 COVARIANCE_TYPE_UNKNOWN = 0\nuint8 COVARIANCE_TYPE_APPROXIMATED = 1\n\
         uint8 COVARIANCE_TYPE_DIAGONAL_KNOWN = 2\nuint8 COVARIANCE_TYPE_KNOWN = 3\n\
         uint8 position_covariance_type\n",
        &["std_msgs/Header", "sensor_msgs/NavSatStatus"],
    ),
    // vinebench's own: what NavSatFix cannot say (the RTK status, satellites, DOPs, the
    // latency) and the fix in the world's east-north-up frame, bit for bit.
    (
        "vinebench_msgs/GnssEnu",
        "std_msgs/Header header\n\
         uint8 NO_FIX = 0\nuint8 SINGLE = 1\nuint8 FLOAT = 2\nuint8 FIXED = 3\nuint8 status\n\
         uint32 satellites\n\
         geometry_msgs/Point position\n\
         float64[3] position_variance\n\
         float64 hdop\nfloat64 vdop\n\
         builtin_interfaces/Duration latency\n",
        &[
            "std_msgs/Header",
            "geometry_msgs/Point",
            "builtin_interfaces/Duration",
        ],
    ),
    (
        "sensor_msgs/PointField",
        "uint8 INT8    = 1\nuint8 UINT8   = 2\nuint8 INT16   = 3\nuint8 UINT16  = 4\n\
         uint8 INT32   = 5\nuint8 UINT32  = 6\nuint8 FLOAT32 = 7\nuint8 FLOAT64 = 8\n\
         string name\nuint32 offset\nuint8  datatype\nuint32 count\n",
        &[],
    ),
    (
        "sensor_msgs/PointCloud2",
        "std_msgs/Header header\n\
         uint32 height\nuint32 width\n\
         PointField[] fields\n\
         bool    is_bigendian\nuint32  point_step\nuint32  row_step\nuint8[] data\n\
         bool is_dense\n",
        &["std_msgs/Header", "sensor_msgs/PointField"],
    ),
    (
        "sensor_msgs/LaserScan",
        "std_msgs/Header header\n\
         float32 angle_min\nfloat32 angle_max\nfloat32 angle_increment\n\
         float32 time_increment\nfloat32 scan_time\n\
         float32 range_min\nfloat32 range_max\n\
         float32[] ranges\nfloat32[] intensities\n",
        &["std_msgs/Header"],
    ),
    (
        "sensor_msgs/Image",
        "std_msgs/Header header\n\
         uint32 height\nuint32 width\n\
         string encoding\n\
         uint8 is_bigendian\nuint32 step\n\
         uint8[] data\n",
        &["std_msgs/Header"],
    ),
    (
        "sensor_msgs/RegionOfInterest",
        "uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify\n",
        &[],
    ),
    (
        "sensor_msgs/CameraInfo",
        "std_msgs/Header header\n\
         uint32 height\nuint32 width\n\
         string distortion_model\n\
         float64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\n\
         uint32 binning_x\nuint32 binning_y\n\
         RegionOfInterest roi\n",
        &["std_msgs/Header", "sensor_msgs/RegionOfInterest"],
    ),
    (
        "nav_msgs/Odometry",
        "std_msgs/Header header\nstring child_frame_id\n\
         geometry_msgs/PoseWithCovariance pose\ngeometry_msgs/TwistWithCovariance twist\n",
        &[
            "std_msgs/Header",
            "geometry_msgs/PoseWithCovariance",
            "geometry_msgs/TwistWithCovariance",
        ],
    ),
    (
        "nav_msgs/Path",
        "std_msgs/Header header\ngeometry_msgs/PoseStamped[] poses\n",
        &["std_msgs/Header", "geometry_msgs/PoseStamped"],
    ),
    (
        "sensor_msgs/CompressedImage",
        "std_msgs/Header header\nstring format\nuint8[] data\n",
        &["std_msgs/Header"],
    ),
    (
        "visualization_msgs/UVCoordinate",
        "float64 u\nfloat64 v\n",
        &[],
    ),
    (
        "visualization_msgs/MeshFile",
        "string filename\nuint8[] data\n",
        &[],
    ),
    (
        "visualization_msgs/Marker",
        "int32 ARROW=0\nint32 CUBE=1\nint32 SPHERE=2\nint32 CYLINDER=3\nint32 LINE_STRIP=4\n\
         int32 LINE_LIST=5\nint32 CUBE_LIST=6\nint32 SPHERE_LIST=7\nint32 POINTS=8\n\
         int32 TEXT_VIEW_FACING=9\nint32 MESH_RESOURCE=10\nint32 TRIANGLE_LIST=11\n\
         int32 ADD=0\nint32 MODIFY=0\nint32 DELETE=2\nint32 DELETEALL=3\n\
         std_msgs/Header header\n\
         string ns\nint32 id\nint32 type\nint32 action\n\
         geometry_msgs/Pose pose\ngeometry_msgs/Vector3 scale\nstd_msgs/ColorRGBA color\n\
         builtin_interfaces/Duration lifetime\nbool frame_locked\n\
         geometry_msgs/Point[] points\nstd_msgs/ColorRGBA[] colors\n\
         string texture_resource\nsensor_msgs/CompressedImage texture\n\
         UVCoordinate[] uv_coordinates\n\
         string text\n\
         string mesh_resource\nMeshFile mesh_file\nbool mesh_use_embedded_materials\n",
        &[
            "std_msgs/Header",
            "geometry_msgs/Pose",
            "geometry_msgs/Vector3",
            "std_msgs/ColorRGBA",
            "builtin_interfaces/Duration",
            "geometry_msgs/Point",
            "sensor_msgs/CompressedImage",
            "visualization_msgs/UVCoordinate",
            "visualization_msgs/MeshFile",
        ],
    ),
    (
        "visualization_msgs/MarkerArray",
        "Marker[] markers\n",
        &["visualization_msgs/Marker"],
    ),
    (
        "tf2_msgs/TFMessage",
        "geometry_msgs/TransformStamped[] transforms\n",
        &["geometry_msgs/TransformStamped"],
    ),
];

fn find(name: &str) -> (&'static str, &'static [&'static str]) {
    DEFINITIONS
        .iter()
        .find(|(n, _, _)| *n == name)
        .map(|&(_, text, deps)| (text, deps))
        .unwrap_or_else(|| panic!("no definition for {name}"))
}

/// The `ros2msg` schema data of `name` (`pkg/msg/Name` or `pkg/Name`): its definition, then
/// each dependency once, depth first.
pub(crate) fn schema(name: &str) -> String {
    let short = name.replace("/msg/", "/");
    let (text, deps) = find(&short);
    let mut out = text.to_owned();
    let mut seen = vec![short];
    let mut stack: Vec<&str> = deps.iter().rev().copied().collect();
    while let Some(dep) = stack.pop() {
        if seen.iter().any(|s| s == dep) {
            continue;
        }
        seen.push(dep.to_owned());
        let (text, deps) = find(dep);
        out.push_str(&"=".repeat(80));
        out.push_str(&format!("\nMSG: {dep}\n{text}"));
        stack.extend(deps.iter().rev());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::schema;

    #[test]
    fn a_schema_carries_every_dependency_once() {
        let s = schema("nav_msgs/msg/Odometry");
        for dep in [
            "std_msgs/Header",
            "builtin_interfaces/Time",
            "geometry_msgs/PoseWithCovariance",
            "geometry_msgs/Pose",
            "geometry_msgs/Point",
            "geometry_msgs/Quaternion",
            "geometry_msgs/TwistWithCovariance",
            "geometry_msgs/Twist",
            "geometry_msgs/Vector3",
        ] {
            assert_eq!(
                s.matches(&format!("\nMSG: {dep}\n")).count(),
                1,
                "{dep} once in\n{s}"
            );
        }
        assert!(s.starts_with("std_msgs/Header header\n"), "{s}");
    }

    #[test]
    fn camera_info_carries_its_region_of_interest() {
        let s = schema("sensor_msgs/msg/CameraInfo");
        assert!(s.starts_with("std_msgs/Header header\n"), "{s}");
        assert!(
            s.contains("\nfloat64[9] k\n") && s.contains("\nfloat64[12] p\n"),
            "{s}"
        );
        for dep in ["sensor_msgs/RegionOfInterest", "builtin_interfaces/Time"] {
            assert_eq!(
                s.matches(&format!("\nMSG: {dep}\n")).count(),
                1,
                "{dep} in\n{s}"
            );
        }
    }

    #[test]
    fn a_marker_array_carries_the_whole_marker() {
        let s = schema("visualization_msgs/msg/MarkerArray");
        assert!(s.starts_with("Marker[] markers\n"), "{s}");
        for dep in [
            "visualization_msgs/Marker",
            "std_msgs/Header",
            "builtin_interfaces/Time",
            "builtin_interfaces/Duration",
            "geometry_msgs/Pose",
            "geometry_msgs/Point",
            "geometry_msgs/Quaternion",
            "geometry_msgs/Vector3",
            "std_msgs/ColorRGBA",
            "sensor_msgs/CompressedImage",
            "visualization_msgs/UVCoordinate",
            "visualization_msgs/MeshFile",
        ] {
            assert_eq!(
                s.matches(&format!("\nMSG: {dep}\n")).count(),
                1,
                "{dep} once in\n{s}"
            );
        }
        assert!(
            s.contains("\nint32 LINE_LIST=5\n")
                && s.contains("\nbool mesh_use_embedded_materials\n"),
            "{s}"
        );
    }
}
