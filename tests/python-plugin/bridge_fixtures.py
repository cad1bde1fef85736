"""Python plugins for the bridge's end-to-end tests (host/tests/e2e/python.rs) and its
per-message overhead benchmark (host/benches/bridges.rs)."""

import ctypes

import numpy as np

from vinebench_plugin import WheelOdometry


class Odometry(WheelOdometry):
    """The contract's example, failing on purpose when asked: `fault` = "raise" (a Python
    exception) or "segfault" (a crash in native code), after `after` messages; with `lidar`
    it also takes the lidar and describes the sweeps; reports a map and an event."""

    @staticmethod
    def requirements(params):
        return ["wheel_odometry", "lidar"] if params.get("lidar") else ["wheel_odometry"]

    def __init__(self, params, rig):
        super().__init__(params, rig)
        self.sweeps = []
        self.fault = params.get("fault", "none")
        self.after = params.get("after", 20)
        self.seen = 0
        self.rig_sensors = sorted(s["kind"] for s in rig["sensors"])

    def on_wheel_odometry(self, odom):
        self.seen += 1
        if self.seen > self.after:
            if self.fault == "raise":
                raise ValueError(f"deliberate error at {odom.stamp_ns} ns")
            if self.fault == "segfault":
                ctypes.string_at(0)
        return super().on_wheel_odometry(odom)

    def on_point_cloud(self, cloud):
        """Records what a sweep looks like from Python (count, rings, the last point's time,
        the farthest range); returns nothing."""
        p = cloud.points
        assert not p.flags.writeable, "the host's buffer must be read-only"
        rng = np.linalg.norm(cloud.xyz(), axis=1)
        self.sweeps.append(f"{len(p)},{int(p['ring'].max()) + 1},{float(p['time_s'].max()):.4f},{rng.max():.2f}")

    def finish(self):
        out = super().finish()
        out["map"] = np.array([p[1][:3, 3] for p in out["trajectory"][:3]])
        detail = f"python odometry: {len(out['trajectory'])} poses; rig {','.join(self.rig_sensors)}"
        if self.sweeps:
            detail += f"; sweeps {len(self.sweeps)}: " + " ".join(self.sweeps[:3])
        out["events"] = [{"stamp_ns": out["trajectory"][-1][0], "kind": "tracking_recovered", "detail": detail}]
        return out


class Keeper:
    """Keeps the first lidar sweep's points array: the bridge must refuse."""

    @staticmethod
    def requirements(params):
        return {"sensors": ["lidar"], "mode": "online"}

    def __init__(self, params, rig):
        self.kept = None

    def on_point_cloud(self, cloud):
        self.kept = cloud.points
        return None

    def finish(self):
        return {"trajectory": []}


class BufferKeeper:
    """Keeps the object behind the first sweep's array (not the array) and asks it for a
    view at the next sweep: the bridge must refuse (a BufferError), not hand out the freed
    memory."""

    @staticmethod
    def requirements(params):
        return ["lidar"]

    def __init__(self, params, rig):
        self.buffer = None

    def on_point_cloud(self, cloud):
        if self.buffer is None:
            self.buffer = cloud.points.base.obj
        else:
            np.frombuffer(self.buffer, dtype=np.uint8)
        return None

    def finish(self):
        return {"trajectory": []}


class Noop:
    """Takes every message and does nothing: the bridge's own cost per message."""

    @staticmethod
    def requirements(params):
        return ["imu", "wheel_odometry", "lidar", "scan2d", "rgbd"]

    def __init__(self, params, rig):
        pass

    def on_imu(self, m):
        return None

    def on_wheel_odometry(self, m):
        return None

    def on_point_cloud(self, m):
        return None

    def on_laser_scan(self, m):
        return None

    def on_rgbd(self, m):
        return None

    def finish(self):
        return {"trajectory": []}


class Conformance(WheelOdometry):
    """The Python door's conformance fixture (`vinebench check-plugin`): asks for every
    sensor, checks each message's fields against each other and the rig (point rings below
    the lidar's `rings`, image sizes from width and height, scan intensities beside ranges),
    answering a mismatch with an error; and returns a grid and a loop with its relative pose
    from finish(), so that both cross the door."""

    @staticmethod
    def requirements(params):
        return ["wheel_odometry", "imu", "lidar", "scan2d", "rgbd"]

    def __init__(self, params, rig):
        super().__init__(params, rig)
        lidar = [s for s in rig["sensors"] if s["kind"] == "lidar"]
        self.rings = lidar[0]["intrinsics"].get("rings", 0) if lidar else 0
        self.checked = 0

    def on_imu(self, imu):
        if not (np.all(np.isfinite(imu.accel)) and np.all(np.isfinite(imu.gyro))):
            raise ValueError(f"a non-finite IMU reading at {imu.stamp_ns} ns")
        self.checked += 1

    def on_point_cloud(self, cloud):
        p = cloud.points
        if len(p) and self.rings and int(p["ring"].max()) >= self.rings:
            raise ValueError("a point's ring beyond the rig's rings (layout?)")
        if len(p) and not (np.all(p["time_s"] >= 0) and np.all(p["time_s"] < 1)):
            raise ValueError("a point's time outside its sweep (layout?)")
        self.checked += 1

    def on_laser_scan(self, scan):
        if len(scan.intensities) not in (0, len(scan.ranges)):
            raise ValueError("a scan's intensities and ranges differ in number (layout?)")
        self.checked += 1

    def on_rgbd(self, frame):
        if frame.rgb.shape != (frame.height, frame.width, 3) or frame.depth.shape != (frame.height, frame.width):
            raise ValueError("a frame's images are not its width x height (layout?)")
        self.checked += 1

    def finish(self):
        out = super().finish()
        if self.trajectory:
            first, last = self.trajectory[0][0], self.trajectory[-1][0]
            out["events"] = [
                {
                    "stamp_ns": last,
                    "kind": "loop_closure_accepted",
                    "detail": f"{self.checked} other messages checked",
                    "loop_stamps_ns": [last, first],
                    "loop_relative_pose": np.linalg.inv(self.trajectory[0][1]) @ self.trajectory[-1][1],
                    "loop_matches": np.array([[10.0, 20.0, 12.5, 21.0], [300.0, 200.0, 290.0, 205.5]]),
                }
            ]
        out["grid"] = {
            "resolution": 0.5,
            "origin": (-1.0, -2.0, 0.0),
            "cells": np.array([[-1, 0, 100], [0, 50, 0]], dtype=np.int8),
        }
        return out


class Merger(WheelOdometry):
    """Dead reckoning whose final trajectory lays a stretch of its route onto another, as a
    false map merge does, while its online poses stay as they were (ORB-SLAM3's merge on S3
    of the paper's world left the online error at 8.0 m): the poses from `shift_from_s` on
    are moved by `shift_xy` (metres, in its odometry frame). With `event_s` it reports one
    accepted loop there without stamps (a map change, as ORB-SLAM3's bindings report a
    merge); without it, nothing. The judge of `runner::loops` must see the join either way
    (host/tests/e2e/joins.rs)."""

    @staticmethod
    def requirements(params):
        """With `camera` it takes the camera too (and ignores it), so that its run counts as
        a camera run whose frames the evaluation renders again."""
        return ["wheel_odometry", "rgbd"] if params.get("camera") else ["wheel_odometry"]

    def __init__(self, params, rig):
        super().__init__(params, rig)
        self.shift_from_ns = int(params.get("shift_from_s", 1e9) * 1e9)
        self.shift_xy = params.get("shift_xy", [0.0, 0.0])
        self.event_s = params.get("event_s")

    def on_rgbd(self, frame):
        return None

    def finish(self):
        trajectory = []
        for stamp, pose in self.trajectory:
            if stamp >= self.shift_from_ns:
                pose = pose.copy()
                pose[:2, 3] += self.shift_xy
            trajectory.append((stamp, pose))
        out = {"trajectory": trajectory}
        if self.event_s is not None:
            out["events"] = [
                {
                    "stamp_ns": int(self.event_s * 1e9),
                    "kind": "loop_closure_accepted",
                    "detail": "merged maps (no stamps)",
                }
            ]
        return out
