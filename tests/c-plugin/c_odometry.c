/*
 * A vinebench plugin in C (include/vinebench_plugin.h): dead reckoning from the wheel
 * encoders, the same midpoint integration as the Rust `wheel-odometry` baseline with
 * `yaw_source = "wheels"`, so that the host's tests can compare the two ABIs' outputs byte
 * for byte. It reports one event, a map of its first three positions, and can be told to
 * fail (parameters `fault = "create" | "error" | "segfault"`, after `after` messages).
 *
 * Built by host/build.rs for the end-to-end tests: cc -shared -fPIC -ffp-contract=off (and
 * once more with -DC_ODOMETRY_ABI_VERSION=99, a library the host must refuse).
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
    char events[256];
    char error[128];
    int fault; /* 0 none, 2 error, 3 segfault */
    long after;
    long seen;
} odometry;

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
    if (!strstr(rig_toml, "kind = \"wheel_odometry\"")) {
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
    return VB_POSE;
}

static int32_t finish(void *self, vb_output *out) {
    odometry *o = self;
    if (o->n == 0) {
        snprintf(o->error, sizeof o->error, "c-odometry: no wheel odometry received");
        return VB_ERROR;
    }
    snprintf(o->events, sizeof o->events,
             "[[events]]\nstamp_ns = %lld\nkind = \"tracking_recovered\"\n"
             "detail = \"c-odometry: %zu poses from C\"\n",
             (long long)o->poses[0].stamp_ns, o->n);
    out->trajectory = o->poses;
    out->n_trajectory = o->n;
    out->map_xyz = o->map;
    out->n_map_points = o->n < 3 ? o->n : 3;
    out->grid = NULL;
    out->events_toml = o->events;
    return 0;
}

/* The tests also build it claiming another ABI version, which the host must refuse. */
#ifndef C_ODOMETRY_ABI_VERSION
#define C_ODOMETRY_ABI_VERSION VB_ABI_VERSION
#endif

static const vb_plugin table = {
    .abi_version = C_ODOMETRY_ABI_VERSION,
    .struct_size = sizeof(vb_plugin),
    .name = "c-odometry",
    .version = "0.1.0",
    .requirements_toml = "sensors = [\"wheel_odometry\"]\nmode = \"online\"\n",
    .create = create,
    .destroy = destroy,
    .last_error = last_error,
    .on_wheel_odometry = on_wheel_odometry,
    .finish = finish,
};

const vb_plugin *vinebench_plugin_v1(void) { return &table; }
