"""The contract of a SLAM system hosted by vinebench's Python bridge, as a base class and a
runnable example. The contract is one for all three doors (Rust, C, Python):
docs/plugin-contract.md is its table, with every message's fields as a Python class sees them
(`imu.gyro`, `odom.linear`, `cloud.points["ring"]`, ...), the event kinds and the versions.

Name the class in a bench file (see plugins/python-bridge/src/lib.rs for every key):

    [[plugins]]
    name = "python-bridge"
    label = "my-odometry"
    [plugins.params]
    module = "vinebench_plugin"                # this file
    class = "WheelOdometry"
    path = "../plugins/python-bridge/python"   # relative to the bench file
    venv = "../target/my-venv"                 # a venv of /usr/bin/python3 with numpy

Lifecycle (the same as a Rust plugin's `SlamSystem`):

1. `requirements(params)` (static): the sensor kinds to stream, of "imu",
   "wheel_odometry", "lidar", "scan2d", "rgbd", "gnss" (revision 5), as a list or as
   {"sensors": [...], "mode": "online" | "offline"}.
2. `__init__(params, rig)`: `params` is the bench file's table without the bridge's keys
   (module, class, path, venv); `rig` the sensor rig as a dict ({"sensors": [{name, kind,
   rate_hz, base_from_sensor_xyz, base_from_sensor_xyzw, intrinsics, noise}, ...]}).
3. One method per sensor kind, called in time order: `on_imu`, `on_wheel_odometry`,
   `on_point_cloud`, `on_laser_scan`, `on_rgbd`, `on_gnss` (revision 5; a fix may be
   absent or broken: check `gnss.status`, that `gnss.position` is finite and
   `gnss.covariance` positive definite) (absent methods are not called). Each
   returns None or `(stamp_ns, map_from_base)` with a 4x4 (or 3x4) transform: the host
   records these as the online trajectory. The messages' arrays are read-only numpy views
   of the host's buffers, valid during the call only: keep copies, not the arrays (a class
   that keeps one fails its run with a line saying so).
4. `finish()`: a dict with `trajectory` (a list of `(stamp_ns, map_from_base)`), optional
   `saved_map` (revision 4: `{"format": str, "version": int, "bytes": bytes}`, the map to
   localise in later, which the host keeps as the run's `map.bin`), optional
   `events` (dicts with `stamp_ns`, `kind` — "loop_closure_accepted",
   "loop_closure_rejected", "tracking_lost", "tracking_recovered" or "gnss_rejected" —
   `detail`, and for a
   loop closure `loop_stamps_ns` = [current, matched] and optionally `loop_relative_pose`,
   matched_from_current as [x, y, z, qx, qy, qz, qw] or a 4x4, and `loop_matches`, the
   matched keypoints as an (N, 4) array of [u_current, v_current, u_matched, v_matched]
   pixels of the colour frames at the two stamps, which the report draws), optional `map` ((N, 3)
   points) and optional `grid` ({"resolution": metres, "origin": (x, y, yaw), "cells": an
   (rows, columns) array of -1 unknown or 0..100 occupancy, row 0 at the origin}).

Localisation in a saved map (revision 4): a class whose `requirements` answer a dict with
`"can_localize": True` may be started by `localize(params, rig, start)` (static) instead of
`__init__`, `start` a dict of the saved map's `bytes`, `format` and `version` and the
`initial_guess` (None: the start is unknown; else `{"map_from_base": 4x4, "sigma_xy": m,
"sigma_yaw": rad}`). Its message methods then answer `(stamp_ns, map_from_base, status)`,
status "localized" or "searching" (a pair means "localized").

Times are integer nanoseconds, lengths metres, the base frame x forward, z up. An exception
fails the run with its `Type: message` line, and its whole traceback goes to the run's
`worker.log`; print() goes there too. Check a class with
`vinebench check-plugin BENCH.toml` before submitting it. The bridge can
tell when Python code keeps an array, not when a C extension keeps a raw pointer to one:
an extension must copy what it keeps (ORB-SLAM3 does, into its frames' keypoints).
"""

import math

import numpy as np


class SlamSystem:
    """The base a hosted class may derive from (the bridge calls methods by name, so deriving
    is optional): every method the bridge may call, with what it does when absent."""

    #: The contract revision this class was written for (docs/plugin-contract.md).
    API_REVISION = 5

    @staticmethod
    def requirements(params):
        """The sensor kinds to stream for these parameters (required)."""
        raise NotImplementedError

    def __init__(self, params, rig):
        pass

    # on_imu(imu), on_wheel_odometry(odom), on_point_cloud(cloud), on_laser_scan(scan),
    # on_rgbd(frame), on_gnss(gnss): define those of the sensors you ask for; each returns
    # None or (stamp_ns, 4x4 map_from_base).

    def finish(self):
        """The final trajectory and the rest (required)."""
        raise NotImplementedError


class WheelOdometry(SlamSystem):
    """Dead reckoning from the wheel speeds (midpoint rule), the smallest useful system.

    It also shows the localisation calls (revision 4), as the C door's `c_odometry.c` does:
    it saves its final x, y and yaw as an "odometry-end" version 1 map, and started from one
    it integrates from the initial guess (else the origin), "searching" for its first 10
    poses."""

    SEARCHING_POSES = 10

    @staticmethod
    def requirements(params):
        return {"sensors": ["wheel_odometry"], "can_localize": True}

    def __init__(self, params, rig):
        self.state = None  # (stamp_ns, x, y, yaw)
        self.trajectory = []
        self.localizing = False
        self.start = (0.0, 0.0, 0.0)

    @staticmethod
    def localize(params, rig, start):
        if (start["format"], start["version"], len(start["bytes"])) != ("odometry-end", 1, 24):
            raise ValueError("not an odometry-end version 1 map of 24 bytes")
        system = WheelOdometry(params, rig)
        system.localizing = True
        guess = start["initial_guess"]
        if guess is not None:
            m = guess["map_from_base"]
            system.start = (m[0, 3], m[1, 3], math.atan2(m[1, 0], m[0, 0]))
        return system

    def on_wheel_odometry(self, odom):
        if not (math.isfinite(odom.linear) and math.isfinite(odom.angular)):
            raise ValueError(f"non-finite wheel speeds at {odom.stamp_ns} ns")
        if self.state is None:
            self.state = (odom.stamp_ns, *self.start)
        else:
            last, x, y, yaw = self.state
            dt = (odom.stamp_ns - last) * 1e-9
            dyaw = odom.angular * dt
            mid = yaw + 0.5 * dyaw
            x += odom.linear * dt * math.cos(mid)
            y += odom.linear * dt * math.sin(mid)
            self.state = (odom.stamp_ns, x, y, yaw + dyaw)
        stamp, x, y, yaw = self.state
        pose = np.eye(4)
        c, s = math.cos(yaw), math.sin(yaw)
        pose[:2, :2] = [[c, -s], [s, c]]
        pose[:2, 3] = [x, y]
        self.trajectory.append((stamp, pose))
        if self.localizing:
            searching = len(self.trajectory) <= self.SEARCHING_POSES
            return stamp, pose, "searching" if searching else "localized"
        return stamp, pose

    def finish(self):
        if self.state is None:
            return {"trajectory": self.trajectory}
        _, x, y, yaw = self.state
        end = np.array([x, y, yaw], dtype="<f8").tobytes()
        return {
            "trajectory": self.trajectory,
            "saved_map": {"format": "odometry-end", "version": 1, "bytes": end},
        }
