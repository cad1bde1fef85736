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
 * The contract is the same through all three doors (this header, the Rust `SlamSystem`
 * trait, the Python bridge's classes): docs/plugin-contract.md is its one table, with every
 * call, every message field as each language sees it, the event kinds, and where a door
 * cannot have something and why.
 *
 * Lifecycle, in this order (the same as the Rust `SlamSystem`):
 *   1. `requirements_for(config_toml)` where the table has it (revision 2), else
 *      `requirements_toml`, is read before anything else: which sensors to stream;
 *   2. `create_with(info)` where the table has it (revision 2), else `create`, with the
 *      plugin's parameter table (the TOML the user wrote, verbatim) and the sensor rig (as
 *      TOML text and, through `create_with`, as the typed `vb_rig` with the `vb_rig_*`
 *      accessors below: every sensor's name, kind, rate, mount and datasheet figures);
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
 * Versioning (docs/plugin-contract.md, "Versions"): `abi_version` is the major version;
 * the host refuses a table of another one. Within it, the contract only grows by appending,
 * and VB_ABI_REVISION counts the additions:
 *   - `vb_plugin` gains fields at its end; the plugin's `struct_size` (sizeof(vb_plugin) of
 *     the header it was built with) tells the host which it has, so an older plugin's
 *     missing fields count as NULL, and a newer plugin's extra fields are not read;
 *   - a message struct the host fills may gain fields at its end; a plugin reads a field of
 *     revision r only when `info->abi_revision >= r` (`create_with`);
 *   - `vb_output` may gain fields at its end; the host zeroes it before `finish`, so a
 *     field an older plugin does not know stays 0 / NULL: absent.
 * Revision 1: everything not marked otherwise. Revision 2: `requirements_for`,
 * `create_with` with `vb_create_info` and the typed `vb_rig`. Revision 3: an event's
 * `loop_matches` (in `events_toml`; no layout changed). Revision 4: localisation in a saved
 * map: `can_localize` in the requirements, `vb_output`'s `saved_map*` fields, the map and
 * `initial_guess` in `vb_create_info`, and VB_POSE_SEARCHING. Revision 5: GNSS: the
 * sensor kind "gnss", `vb_gnss`, `on_gnss` and the event kind "gnss_rejected".
 *
 * Localisation (revision 4): a plugin whose requirements say `can_localize = true` may save
 * its map at `finish` (`saved_map*`: opaque bytes in a format it names and versions; the
 * host writes them as the run folder's `map.bin`) and be created again from those bytes:
 * `create_with` then gets `info->map` (non-NULL, `map_len` bytes, valid for the call only:
 * copy what you keep), `map_format`, `map_format_version` and, where the run gives one,
 * `initial_guess` (else the start is unknown: global localisation). A plugin that localises
 * in a 2D occupancy grid gets the host's format "vinebench-grid" version 1: little-endian
 * resolution_m (double), origin x, y, yaw (3 doubles), width, height (uint32), then
 * width * height int8 cells (-1 unknown, 0 free .. 100 occupied, row-major from the origin).
 * Every pose returned then carries the system's belief: VB_POSE (localised) or
 * VB_POSE_SEARCHING (a pose, but still searching where it is in the map).
 */
#ifndef VINEBENCH_PLUGIN_H
#define VINEBENCH_PLUGIN_H

#include <stddef.h>
#include <stdint.h>
#include <string.h>

#ifdef __cplusplus
extern "C" {
#endif

#define VB_ABI_VERSION 1u
#define VB_ABI_REVISION 5u

/* Return values of the message callbacks and of `finish`. */
#define VB_NO_POSE 0  /* handled; no estimate with this message */
#define VB_POSE 1     /* handled; `*estimate` holds map_from_base at some stamp */
#define VB_ERROR (-1) /* failed; `last_error(self)` says why */
/* Revision 4: handled; `*estimate` holds map_from_base, but the system is still searching
 * where it is in its map (localisation mode); VB_POSE there means localised. */
#define VB_POSE_SEARCHING 2

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

/* Revision 5: the quality of a GNSS fix (`vb_gnss.status`), best last. */
#define VB_GNSS_NO_FIX 0u /* no fix: the position is NaN */
#define VB_GNSS_SINGLE 1u /* single-point (code) solution: metres */
#define VB_GNSS_FLOAT 2u  /* RTK, float ambiguities: decimetres */
#define VB_GNSS_FIXED 3u  /* RTK, fixed ambiguities: centimetres */

/* Revision 5: one GNSS epoch of the rig's "gnss" sensor (its mount is the antenna's lever
 * arm from the base), stamped at the epoch, delivered after the receiver's latency.
 * `position_enu_m` is east, north, up of the antenna from the datum (the gnss sensor's
 * intrinsics `datum_latitude_deg`, `datum_longitude_deg`, `datum_altitude_m`), with its
 * reported covariance (row-major 3 x 3, m^2); the same fix in WGS-84 as
 * sensor_msgs/NavSatFix has it. Without a fix the position and geodetic fields are NaN
 * and the covariance zeros. Nothing is checked for the plugin: refuse a fix whose position
 * is not finite or whose covariance is not symmetric positive definite (with a
 * "gnss_rejected" event), never trust it. */
typedef struct vb_gnss {
    int64_t stamp_ns;
    uint32_t status;     /* VB_GNSS_* */
    uint32_t satellites; /* used: above the mask and in view */
    double position_enu_m[3];
    double covariance_enu_m2[9];
    double latitude_deg;
    double longitude_deg;
    double altitude_m; /* ellipsoidal */
    double hdop;       /* NaN under four satellites */
} vb_gnss;

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
    /* Events as TOML `[[events]]` tables with `stamp_ns`, `kind` (one of the registry's
     * names, docs/plugin-contract.md "Event kinds": "loop_closure_accepted",
     * "loop_closure_rejected", "tracking_lost", "tracking_recovered", "gnss_rejected"),
     * `detail`, and for a loop closure `loop_stamps_ns = [current, matched]` and optionally
     * `loop_relative_pose = [x, y, z, qx, qy, qz, qw]` (matched_from_current) and
     * `loop_matches = [[u_current, v_current, u_matched, v_matched], ...]` (pixels of the
     * colour frames at the two stamps; revision 3); NULL or "": none. An unknown kind fails
     * the run with a line naming it. */
    const char *events_toml;
    /* Revision 4: the map to localise in later, `saved_map_len` opaque bytes (NULL: none),
     * in the format named by `saved_map_format` (NUL-terminated, e.g. "my-slam-keyframes")
     * of version `saved_map_version`. */
    const uint8_t *saved_map;
    size_t saved_map_len;
    const char *saved_map_format;
    uint32_t saved_map_version;
} vb_output;

/* Revision 4: where the robot starts in the map, with its uncertainty. */
typedef struct vb_initial_guess {
    vb_pose map_from_base;
    double sigma_xy_m;    /* standard deviation of x and of y, metres */
    double sigma_yaw_rad; /* standard deviation of the heading, radians */
} vb_initial_guess;

/* Revision 2: the rig, typed. One datasheet figure of a sensor, e.g. {"fx", 525.0}. */
typedef struct vb_param {
    const char *key; /* NUL-terminated */
    double value;
} vb_param;

/* One sensor of the rig: the fields of the rig TOML's `[[sensors]]` table. */
typedef struct vb_sensor {
    const char *name; /* NUL-terminated, e.g. "lidar", "camera", "scan_front" */
    const char *kind; /* "imu", "wheel_odometry", "lidar", "scan2d", "rgbd" or "gnss" (rev. 5) */
    double rate_hz;
    double base_from_sensor_xyz[3];  /* metres */
    double base_from_sensor_xyzw[4]; /* unit quaternion (x, y, z, w) */
    const vb_param *intrinsics;      /* geometry, e.g. rings, columns, fx, width */
    size_t n_intrinsics;
    const vb_param *noise; /* noise as a datasheet gives it, e.g. range_sigma_m */
    size_t n_noise;
} vb_sensor;

typedef struct vb_rig {
    const vb_sensor *sensors;
    size_t n_sensors;
} vb_rig;

/* What `create_with` gets; valid for the call only (copy what you keep). */
typedef struct vb_create_info {
    uint32_t struct_size;  /* sizeof(vb_create_info) in the host's header */
    uint32_t abi_revision; /* the host's VB_ABI_REVISION: which appended fields exist */
    const char *config_toml; /* the plugin's parameter table, verbatim (NUL-terminated) */
    const char *rig_toml;    /* the rig as TOML text, as `create` gets it */
    const vb_rig *rig;       /* the same rig, typed */
    /* Revision 4 (read only when abi_revision >= 4): NULL, or the saved map to localise in
     * (localisation mode; see "Localisation" above). */
    const uint8_t *map;
    size_t map_len;
    const char *map_format; /* NUL-terminated; NULL when `map` is */
    uint32_t map_format_version;
    const vb_initial_guess *initial_guess; /* NULL: the start is unknown */
} vb_create_info;

/* The sensor called `name`, or NULL. */
static inline const vb_sensor *vb_rig_sensor(const vb_rig *rig, const char *name) {
    for (size_t i = 0; rig && i < rig->n_sensors; i++)
        if (strcmp(rig->sensors[i].name, name) == 0) return &rig->sensors[i];
    return NULL;
}

/* The first sensor of `kind` ("lidar", "rgbd", ...), or NULL. */
static inline const vb_sensor *vb_rig_first(const vb_rig *rig, const char *kind) {
    for (size_t i = 0; rig && i < rig->n_sensors; i++)
        if (strcmp(rig->sensors[i].kind, kind) == 0) return &rig->sensors[i];
    return NULL;
}

/* Looks `key` up among `n` params: 1 and `*value` set if present, else 0. */
static inline int vb_param_get(const vb_param *params, size_t n, const char *key,
                               double *value) {
    for (size_t i = 0; params && i < n; i++)
        if (strcmp(params[i].key, key) == 0) {
            if (value) *value = params[i].value;
            return 1;
        }
    return 0;
}

/* A sensor's intrinsic (geometry) figure `key`: 1 and `*value` set if present, else 0. */
static inline int vb_sensor_intrinsic(const vb_sensor *s, const char *key, double *value) {
    return s ? vb_param_get(s->intrinsics, s->n_intrinsics, key, value) : 0;
}

/* A sensor's noise figure `key`: 1 and `*value` set if present, else 0. */
static inline int vb_sensor_noise(const vb_sensor *s, const char *key, double *value) {
    return s ? vb_param_get(s->noise, s->n_noise, key, value) : 0;
}

typedef struct vb_plugin {
    uint32_t abi_version; /* VB_ABI_VERSION */
    uint32_t struct_size; /* sizeof(vb_plugin) */
    const char *name;     /* short name the host finds it by, e.g. "my-slam" */
    const char *version;
    /* TOML: `sensors = [...]` of "imu", "wheel_odometry", "lidar", "scan2d", "rgbd", "gnss",
     * `mode = "online"` or "offline", and (revision 4) `can_localize = true` for a plugin
     * that `create_with` can start from a saved map. */
    const char *requirements_toml;

    /* NULL or the new system; NULL: `last_error(NULL)` says why. */
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

    /* 0 on success with `*output` filled, VB_ERROR on failure. The host zeroes `*output`
     * before the call. */
    int32_t (*finish)(void *self, vb_output *output);

    /* Revision 2 (each may be NULL, and is absent from a table whose `struct_size` ends
     * before it). */
    /* The requirements for this parameter table, TOML as `requirements_toml`, for a plugin
     * whose sensors depend on its parameters; valid until the plugin's next call. NULL:
     * failed, `last_error(NULL)` says why. Absent or NULL function: `requirements_toml`. */
    const char *(*requirements_for)(const char *config_toml);
    /* Creates the system as `create` does, with the rig also typed. Where present the host
     * calls it instead of `create` (which may then be NULL). */
    void *(*create_with)(const vb_create_info *info);

    /* Revision 5 (may be NULL; absent from a table whose `struct_size` ends before it). */
    /* A GNSS epoch, for a plugin whose requirements list "gnss". */
    int32_t (*on_gnss)(void *self, const vb_gnss *gnss, vb_pose *estimate);
} vb_plugin;

/* sizeof(vb_plugin) of revision 1, for hosts and tests: a table of at least this size. */
#define VB_PLUGIN_SIZE_REVISION_1 offsetof(vb_plugin, requirements_for)

/* The one symbol a plugin library exports. */
const vb_plugin *vinebench_plugin_v1(void);

#ifdef __cplusplus
}
#endif

#endif /* VINEBENCH_PLUGIN_H */
