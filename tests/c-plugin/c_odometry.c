/*
 * A vinebench plugin in C (include/vinebench_plugin.h): dead reckoning from the wheel
 * encoders, the same midpoint integration as the Rust `wheel-odometry` baseline with
 * `yaw_source = "wheels"`, so that the host's tests can compare the two ABIs' outputs byte
 * for byte. It reports one event, a map of its first three positions, and can be told to
 * fail (parameters `fault = "create" | "error" | "segfault"`, after `after` messages).
 *
 * It is also the C door's conformance fixture (`vinebench check-plugin`): with
 * `sensors = "all"` its `requirements_for` (revision 2) asks for every sensor, and each
 * callback checks the message's fields against each other and against the typed rig it got
 * through `create_with` (point rings below the lidar's `rings`, colour and depth sizes from
 * width and height, scan intensities beside ranges), answering a mismatch with an error: a
 * layout that differs from the host's fails the route check. Non-finite wheel speeds are
 * answered with an error, not integrated.
 *
 * Revision 4 (localisation in a saved map), so that the door's new calls have a C user: it
 * saves a map, "odometry-end" version 1, its final x, y and yaw (three little-endian doubles),
 * and started from such a map (`create_with` with `info->map`) it integrates from the
 * initial guess (else from the origin), answering VB_POSE_SEARCHING for its first 10 poses
 * and VB_POSE after; a map of another format, version or size is refused.
 *
 * Built by host/build.rs for the end-to-end tests: cc -shared -fPIC -ffp-contract=off (and
 * once more with -DC_ODOMETRY_ABI_VERSION=99, a library the host must refuse, and once with
 * -DC_ODOMETRY_REVISION_1, a table of revision 1's size whose later fields must be unread).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "vinebench_plugin.h"

typedef struct {
    double x, y, yaw;
    int64_t last_ns;
    int have_last;
    vb_pose *poses;
    size_t n, cap;
    float map[9];
    char events[640];
    char error[128];
    int fault; /* 0 none, 2 error, 3 segfault */
    long after;
    long seen;
    double rings; /* the rig's lidar rings (typed rig), 0: unknown */
    long checked; /* messages of other sensors checked */
    int localizing; /* started from a saved map (revision 4) */
    unsigned char saved[24]; /* the map finish saves: final x, y, yaw */
} odometry;

#define SEARCHING_POSES 10

static char create_error[128];

/* `key = "value"` or `key = number` of a flat TOML table: a plain search, enough here. */
static const char *value_of(const char *toml, const char *key) {
    const char *p = strstr(toml, key);
    if (!p) return NULL;
    p = strchr(p, '=');
    if (!p) return NULL;
    p++;
    while (*p == ' ' || *p == '"') p++;
    return p;
}

static void *create(const char *config_toml, const char *rig_toml) {
    if (!rig_toml || !strstr(rig_toml, "kind = \"wheel_odometry\"")) {
        snprintf(create_error, sizeof create_error, "c-odometry: the rig has no wheel odometry");
        return NULL;
    }
    const char *fault = value_of(config_toml, "fault");
    if (fault && strncmp(fault, "create", 6) == 0) {
        snprintf(create_error, sizeof create_error, "c-odometry: refused to start (fault = create)");
        return NULL;
    }
    odometry *o = calloc(1, sizeof *o);
    if (!o) {
        snprintf(create_error, sizeof create_error, "c-odometry: out of memory");
        return NULL;
    }
    if (fault && strncmp(fault, "error", 5) == 0) o->fault = 2;
    if (fault && strncmp(fault, "segfault", 8) == 0) o->fault = 3;
    const char *after = value_of(config_toml, "after");
    o->after = after ? strtol(after, NULL, 10) : 0;
    return o;
}

/* Revision 2: the rig typed. */
static void *create_with(const vb_create_info *info) {
    if (info->abi_revision < 2 || !info->rig) {
        snprintf(create_error, sizeof create_error, "c-odometry: create_with without a typed rig");
        return NULL;
    }
    if (!vb_rig_first(info->rig, "wheel_odometry")) {
        snprintf(create_error, sizeof create_error, "c-odometry: the rig has no wheel odometry");
        return NULL;
    }
    if (info->abi_revision >= 4 && info->map) {
        if (!info->map_format || strcmp(info->map_format, "odometry-end") != 0 ||
            info->map_format_version != 1 || info->map_len != 24) {
            snprintf(create_error, sizeof create_error,
                     "c-odometry: not an odometry-end version 1 map of 24 bytes");
            return NULL;
        }
    }
    odometry *o = create(info->config_toml, info->rig_toml);
    if (o) vb_sensor_intrinsic(vb_rig_first(info->rig, "lidar"), "rings", &o->rings);
    if (o && info->abi_revision >= 4 && info->map) {
        o->localizing = 1;
        if (info->initial_guess) {
            const vb_pose *g = &info->initial_guess->map_from_base;
            const double *q = g->rotation_xyzw;
            o->x = g->translation[0];
            o->y = g->translation[1];
            o->yaw = atan2(2.0 * (q[3] * q[2] + q[0] * q[1]), 1.0 - 2.0 * (q[1] * q[1] + q[2] * q[2]));
        }
    }
    return o;
}

static const char *requirements_for(const char *config_toml) {
    const char *sensors = value_of(config_toml, "sensors");
    if (sensors && strncmp(sensors, "all", 3) == 0)
        return "sensors = [\"wheel_odometry\", \"imu\", \"lidar\", \"scan2d\", \"rgbd\"]\n"
               "mode = \"online\"\ncan_localize = true\n";
    return "sensors = [\"wheel_odometry\"]\nmode = \"online\"\ncan_localize = true\n";
}

static int32_t refuse(odometry *o, const char *what, int64_t stamp_ns) {
    snprintf(o->error, sizeof o->error, "c-odometry: %s at %lld ns", what, (long long)stamp_ns);
    return VB_ERROR;
}

static int32_t on_imu(void *self, const vb_imu *m, vb_pose *estimate) {
    (void)estimate;
    odometry *o = self;
    for (int i = 0; i < 3; i++)
        if (!isfinite(m->accel_mps2[i]) || !isfinite(m->gyro_rps[i]))
            return refuse(o, "a non-finite IMU reading", m->stamp_ns);
    o->checked++;
    return VB_NO_POSE;
}

static int32_t on_point_cloud(void *self, const vb_point_cloud *m, vb_pose *estimate) {
    (void)estimate;
    odometry *o = self;
    if (m->sensor_len == 0 || !m->sensor) return refuse(o, "a cloud without its sensor", m->stamp_ns);
    if (m->n_points > 0 && !m->points) return refuse(o, "a cloud's points are NULL", m->stamp_ns);
    for (size_t i = 0; i < m->n_points; i++) {
        const vb_lidar_point *p = &m->points[i];
        if (o->rings > 0 && p->ring >= o->rings)
            return refuse(o, "a point's ring beyond the rig's rings (layout?)", m->stamp_ns);
        if (!(p->time_s >= 0.0f && p->time_s < 1.0f))
            return refuse(o, "a point's time outside its sweep (layout?)", m->stamp_ns);
    }
    o->checked++;
    return VB_NO_POSE;
}

static int32_t on_laser_scan(void *self, const vb_laser_scan *m, vb_pose *estimate) {
    (void)estimate;
    odometry *o = self;
    if (m->n_ranges > 0 && !m->ranges_m) return refuse(o, "a scan's ranges are NULL", m->stamp_ns);
    if (m->n_intensities != 0 && m->n_intensities != m->n_ranges)
        return refuse(o, "a scan's intensities and ranges differ in number (layout?)", m->stamp_ns);
    if (!(m->range_max_m > m->range_min_m)) return refuse(o, "a scan's range limits", m->stamp_ns);
    o->checked++;
    return VB_NO_POSE;
}

static int32_t on_rgbd(void *self, const vb_rgbd_frame *m, vb_pose *estimate) {
    (void)estimate;
    odometry *o = self;
    size_t pixels = (size_t)m->width * m->height;
    if (m->rgb_len != 3 * pixels || m->depth_len != pixels)
        return refuse(o, "a frame's colour or depth size is not its width x height (layout?)",
                      m->stamp_ns);
    if (pixels > 0 && (!m->rgb || !m->depth_m)) return refuse(o, "a frame's images are NULL", m->stamp_ns);
    if (!(m->intrinsics[0] > 0.0 && m->intrinsics[1] > 0.0))
        return refuse(o, "a frame's focal lengths (layout?)", m->stamp_ns);
    o->checked++;
    return VB_NO_POSE;
}

static void destroy(void *self) {
    odometry *o = self;
    if (!o) return;
    free(o->poses);
    free(o);
}

static const char *last_error(void *self) {
    return self ? ((odometry *)self)->error : create_error;
}

/* map_from_base of the base at (x, y, yaw), as nalgebra's from_euler_angles(0, 0, yaw)
 * computes its quaternion. */
static vb_pose pose_of(const odometry *o, int64_t stamp_ns) {
    double sr = sin(0.0 * 0.5), cr = cos(0.0 * 0.5);
    double sp = sin(0.0 * 0.5), cp = cos(0.0 * 0.5);
    double sy = sin(o->yaw * 0.5), cy = cos(o->yaw * 0.5);
    vb_pose p = {stamp_ns, {o->x, o->y, 0.0}, {0.0, 0.0, 0.0, 1.0}};
    p.rotation_xyzw[3] = cr * cp * cy + sr * sp * sy;
    p.rotation_xyzw[0] = sr * cp * cy - cr * sp * sy;
    p.rotation_xyzw[1] = cr * sp * cy + sr * cp * sy;
    p.rotation_xyzw[2] = cr * cp * sy - sr * sp * cy;
    return p;
}

static int32_t on_wheel_odometry(void *self, const vb_wheel_odometry *m, vb_pose *estimate) {
    odometry *o = self;
    o->seen++;
    if (o->fault && o->seen > o->after) {
        if (o->fault == 3) {
            volatile int *nowhere = NULL;
            *nowhere = 1;
        }
        snprintf(o->error, sizeof o->error, "c-odometry: deliberate error at %lld ns",
                 (long long)m->stamp_ns);
        return VB_ERROR;
    }
    if (!isfinite(m->linear_mps) || !isfinite(m->angular_rps))
        return refuse(o, "non-finite wheel speeds", m->stamp_ns);
    if (o->have_last) {
        double dt = (double)(m->stamp_ns - o->last_ns) * 1e-9;
        double dyaw = m->angular_rps * dt;
        double mid = o->yaw + 0.5 * dyaw;
        o->x += m->linear_mps * dt * cos(mid);
        o->y += m->linear_mps * dt * sin(mid);
        o->yaw += dyaw;
    }
    o->last_ns = m->stamp_ns;
    o->have_last = 1;
    if (o->n == o->cap) {
        size_t cap = o->cap ? 2 * o->cap : 1024;
        vb_pose *grown = realloc(o->poses, cap * sizeof *grown);
        if (!grown) {
            snprintf(o->error, sizeof o->error, "c-odometry: out of memory");
            return VB_ERROR;
        }
        o->poses = grown;
        o->cap = cap;
    }
    if (o->n < 3) {
        o->map[3 * o->n] = (float)o->x;
        o->map[3 * o->n + 1] = (float)o->y;
        o->map[3 * o->n + 2] = 0.0f;
    }
    o->poses[o->n++] = pose_of(o, m->stamp_ns);
    *estimate = o->poses[o->n - 1];
    return o->localizing && o->n <= SEARCHING_POSES ? VB_POSE_SEARCHING : VB_POSE;
}

static int32_t finish(void *self, vb_output *out) {
    odometry *o = self;
    if (o->n == 0) {
        snprintf(o->error, sizeof o->error, "c-odometry: no wheel odometry received");
        return VB_ERROR;
    }
    /* A loop candidate of the last pose to the first, refused (counted, not judged), with
     * matched keypoints (revision 3's optional `loop_matches`): the field crosses the door. */
    const vb_pose *first = &o->poses[0], *last = &o->poses[o->n - 1];
    snprintf(o->events, sizeof o->events,
             "[[events]]\nstamp_ns = %lld\nkind = \"tracking_recovered\"\n"
             "detail = \"c-odometry: %zu poses from C\"\n"
             "[[events]]\nstamp_ns = %lld\nkind = \"loop_closure_rejected\"\n"
             "detail = \"c-odometry: last pose to first, refused\"\n"
             "loop_stamps_ns = [%lld, %lld]\n"
             "loop_matches = [[10.0, 20.0, 12.5, 21.0], [300.0, 200.0, 290.0, 205.5]]\n",
             (long long)first->stamp_ns, o->n, (long long)last->stamp_ns,
             (long long)last->stamp_ns, (long long)first->stamp_ns);
    out->trajectory = o->poses;
    out->n_trajectory = o->n;
    out->map_xyz = o->map;
    out->n_map_points = o->n < 3 ? o->n : 3;
    out->grid = NULL;
    out->events_toml = o->events;
    double end[3] = {o->x, o->y, o->yaw};
    memcpy(o->saved, end, sizeof end); /* little-endian hosts only, as the tests run */
    out->saved_map = o->saved;
    out->saved_map_len = sizeof o->saved;
    out->saved_map_format = "odometry-end";
    out->saved_map_version = 1;
    return 0;
}

/* The tests also build it claiming another ABI version, which the host must refuse. */
#ifndef C_ODOMETRY_ABI_VERSION
#define C_ODOMETRY_ABI_VERSION VB_ABI_VERSION
#endif

/* Built with -DC_ODOMETRY_REVISION_1, the table claims revision 1's size: the host must read
 * neither `requirements_for` nor `create_with`, though they are set. */
#ifdef C_ODOMETRY_REVISION_1
#define C_ODOMETRY_TABLE_SIZE VB_PLUGIN_SIZE_REVISION_1
#else
#define C_ODOMETRY_TABLE_SIZE sizeof(vb_plugin)
#endif

static const vb_plugin table = {
    .abi_version = C_ODOMETRY_ABI_VERSION,
    .struct_size = C_ODOMETRY_TABLE_SIZE,
    .name = "c-odometry",
    .version = "0.1.0",
    .requirements_toml = "sensors = [\"wheel_odometry\"]\nmode = \"online\"\ncan_localize = true\n",
    .create = create,
    .destroy = destroy,
    .last_error = last_error,
    .on_imu = on_imu,
    .on_wheel_odometry = on_wheel_odometry,
    .on_point_cloud = on_point_cloud,
    .on_laser_scan = on_laser_scan,
    .on_rgbd = on_rgbd,
    .finish = finish,
    .requirements_for = requirements_for,
    .create_with = create_with,
};

const vb_plugin *vinebench_plugin_v1(void) { return &table; }
