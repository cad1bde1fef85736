/*
 * vinebench_plugin.h: the C ABI of a vinebench SLAM plugin, for systems written in C, C++
 * or anything that can export a C function. A plugin is a shared library exporting
 *
 *     const vb_plugin *vinebench_plugin_v1(void);
 *
 * which returns a table of plain C data and function pointers, valid while the library is
 * loaded. The host loads it like a Rust plugin (by `name` from the search path or by `path`
 * in a bench file) and runs it the same way: in a worker process of its own, under the
 * run's timeout and memory limit; a crash (segfault, abort, exit) costs that run only.
 *
 * Lifecycle, in this order (the same as the Rust `SlamSystem`):
 *   1. `requirements_toml` is read before anything else: which sensors to stream;
 *   2. `create` with the plugin's parameter table (the TOML the user wrote, verbatim) and
 *      the sensor rig (TOML: every sensor's name, kind, rate, mount and datasheet figures);
 *   3. the message callbacks, in order of availability (a lidar sweep arrives at its end,
 *      stamped at its start), one call at a time from one thread;
 *   4. `finish` once, after the last message: the final trajectory, map, grid and events;
 *   5. `destroy`.
 *
 * Conventions: time in integer nanoseconds since the start of the run; SI units; poses are
 * `map_from_base` (`a_from_b`: maps points in frame b to frame a); quaternions (x, y, z, w).
 * Every pointer the host passes is valid for the duration of the call only: copy what you
 * keep. Every pointer the plugin returns (errors, finish's output) must stay valid until
 * the plugin's next call or `destroy`.
 *
 * Errors: a callback returns VB_ERROR and then `last_error(self)` names the problem on one
 * line; `create` returns NULL and `last_error(NULL)` says why. The host fails the run with
 * that message.
 *
 * Versioning: the host accepts a table whose `abi_version` equals VB_ABI_VERSION. Later
 * versions only append fields at the end of `vb_plugin` (the host reads `struct_size` to
 * know which it has) and may add optional message fields at the end of a message struct.
 */
#ifndef VINEBENCH_PLUGIN_H
#define VINEBENCH_PLUGIN_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define VB_ABI_VERSION 1u

/* Return values of the message callbacks and of `finish`. */
#define VB_NO_POSE 0  /* handled; no estimate with this message */
#define VB_POSE 1     /* handled; `*estimate` holds map_from_base at some stamp */
#define VB_ERROR (-1) /* failed; `last_error(self)` says why */

/* A stamped rigid transform `a_from_b` (which frames is said where it is used). */
typedef struct vb_pose {
    int64_t stamp_ns;
    double translation[3];
    double rotation_xyzw[4]; /* unit quaternion (x, y, z, w) */
} vb_pose;

/* One IMU reading in the IMU frame: specific force (about +9.81 m/s^2 up at rest) and
 * angular rate; `orientation_xyzw` is world_from_imu where the IMU reports one (the rig's
 * IMU then has `reports_orientation = 1` among its intrinsics), else all zeros. */
typedef struct vb_imu {
    int64_t stamp_ns;
    double accel_mps2[3];
    double gyro_rps[3];
    double orientation_xyzw[4];
} vb_imu;

/* Wheel odometry: forward speed and yaw rate of the base from the encoders, and the pose
 * integrated from them (`odom_from_base`, starting at the identity). */
typedef struct vb_wheel_odometry {
    int64_t stamp_ns;
    double linear_mps;
    double angular_rps;
    vb_pose odom_from_base;
} vb_wheel_odometry;

/* One lidar return in the sensor frame. */
typedef struct vb_lidar_point {
    float x, y, z;
    float intensity; /* calibrated reflectivity, 0-255 */
    float time_s;    /* firing time after the cloud's stamp */
    uint16_t ring;   /* beam index from the lowest (0) upwards */
} vb_lidar_point;

/* One revolution of a spinning lidar, stamped at the start of the sweep. `sensor` is the
 * sensor's name in the rig (UTF-8, `sensor_len` bytes, not NUL-terminated). */
typedef struct vb_point_cloud {
    int64_t stamp_ns;
    const char *sensor;
    size_t sensor_len;
    const vb_lidar_point *points;
    size_t n_points;
} vb_point_cloud;

/* A planar scan laid out like ROS sensor_msgs/LaserScan (no return: +inf). */
typedef struct vb_laser_scan {
    int64_t stamp_ns;
    const char *sensor;
    size_t sensor_len;
    float angle_min_rad;
    float angle_increment_rad;
    float time_increment_s;
    float range_min_m;
    float range_max_m;
    const float *ranges_m;
    size_t n_ranges;
    const float *intensities;
    size_t n_intensities;
} vb_laser_scan;

/* An RGB-D frame: RGB8 row-major (`width * height * 3` bytes), depth in metres row-major
 * (0: invalid), pinhole intrinsics [fx, fy, cx, cy] in pixels. */
typedef struct vb_rgbd_frame {
    int64_t stamp_ns;
    const char *sensor;
    size_t sensor_len;
    uint32_t width;
    uint32_t height;
    const uint8_t *rgb;
    size_t rgb_len;
    const float *depth_m;
    size_t depth_len;
    double intrinsics[4];
} vb_rgbd_frame;

/* A 2D occupancy grid (ROS map_server convention): cells row-major from the origin corner,
 * 0 free .. 100 occupied, -1 unknown; origin [x, y, yaw] of cell (0, 0)'s corner. */
typedef struct vb_grid {
    double resolution_m;
    double origin[3];
    uint32_t width;
    uint32_t height;
    const int8_t *cells; /* width * height */
} vb_grid;

/* What `finish` returns; owned by the plugin until `destroy`. */
typedef struct vb_output {
    const vb_pose *trajectory; /* the final trajectory, map_from_base */
    size_t n_trajectory;
    const float *map_xyz; /* map points in the map frame, x y z each; NULL: no map */
    size_t n_map_points;
    const vb_grid *grid; /* NULL: no grid */
    /* Events as TOML `[[events]]` tables with `stamp_ns`, `kind` ("loop_closure_accepted",
     * "loop_closure_rejected", "tracking_lost", "tracking_recovered"), `detail`, and for a
     * loop closure `loop_stamps_ns = [current, matched]` and optionally
     * `loop_relative_pose = [x, y, z, qx, qy, qz, qw]` (matched_from_current); NULL or "":
     * none. */
    const char *events_toml;
} vb_output;

typedef struct vb_plugin {
    uint32_t abi_version; /* VB_ABI_VERSION */
    uint32_t struct_size; /* sizeof(vb_plugin) */
    const char *name;     /* short name the host finds it by, e.g. "my-slam" */
    const char *version;
    /* TOML: `sensors = [...]` of "imu", "wheel_odometry", "lidar", "scan2d", "rgbd", and
     * `mode = "online"` or "offline". */
    const char *requirements_toml;

    void *(*create)(const char *config_toml, const char *rig_toml);
    void (*destroy)(void *self);
    /* The last error of `self` (NULL: of `create`), one line, UTF-8. */
    const char *(*last_error)(void *self);

    /* Each may be NULL: the messages of that kind are then ignored. */
    int32_t (*on_imu)(void *self, const vb_imu *imu, vb_pose *estimate);
    int32_t (*on_wheel_odometry)(void *self, const vb_wheel_odometry *odom, vb_pose *estimate);
    int32_t (*on_point_cloud)(void *self, const vb_point_cloud *cloud, vb_pose *estimate);
    int32_t (*on_laser_scan)(void *self, const vb_laser_scan *scan, vb_pose *estimate);
    int32_t (*on_rgbd)(void *self, const vb_rgbd_frame *frame, vb_pose *estimate);

    /* 0 on success with `*output` filled, VB_ERROR on failure. */
    int32_t (*finish)(void *self, vb_output *output);
} vb_plugin;

/* The one symbol a plugin library exports. */
const vb_plugin *vinebench_plugin_v1(void);

#ifdef __cplusplus
}
#endif

#endif /* VINEBENCH_PLUGIN_H */
