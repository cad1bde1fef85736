/* A C plugin that takes every message and does nothing: the C ABI's own cost per message,
 * measured beside a Rust and a Python no-op by host/benches/bridges.rs. */
#include <stddef.h>
#include <stdint.h>

#include "vinebench_plugin.h"

static int instance;

static void *create(const char *config_toml, const char *rig_toml) {
    (void)config_toml;
    (void)rig_toml;
    return &instance;
}

static void destroy(void *self) { (void)self; }

static const char *last_error(void *self) {
    (void)self;
    return "c-noop: no error";
}

#define IGNORE(name, type)                                                 \
    static int32_t name(void *self, const type *m, vb_pose *estimate) {    \
        (void)self;                                                        \
        (void)m;                                                           \
        (void)estimate;                                                    \
        return VB_NO_POSE;                                                 \
    }
IGNORE(on_imu, vb_imu)
IGNORE(on_wheel_odometry, vb_wheel_odometry)
IGNORE(on_point_cloud, vb_point_cloud)
IGNORE(on_laser_scan, vb_laser_scan)
IGNORE(on_rgbd, vb_rgbd_frame)

static int32_t finish(void *self, vb_output *out) {
    (void)self;
    out->trajectory = NULL;
    out->n_trajectory = 0;
    out->map_xyz = NULL;
    out->n_map_points = 0;
    out->grid = NULL;
    out->events_toml = "";
    return 0;
}

static const vb_plugin table = {
    .abi_version = VB_ABI_VERSION,
    .struct_size = sizeof(vb_plugin),
    .name = "c-noop",
    .version = "0.1.0",
    .requirements_toml = "sensors = [\"imu\", \"wheel_odometry\", \"lidar\", \"scan2d\", \"rgbd\"]\nmode = \"online\"\n",
    .create = create,
    .destroy = destroy,
    .last_error = last_error,
    .on_imu = on_imu,
    .on_wheel_odometry = on_wheel_odometry,
    .on_point_cloud = on_point_cloud,
    .on_laser_scan = on_laser_scan,
    .on_rgbd = on_rgbd,
    .finish = finish,
};

const vb_plugin *vinebench_plugin_v1(void) { return &table; }
