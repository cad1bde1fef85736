"""The Python half of vinebench's Python plugin bridge (compiled into libpython_bridge.so).

The Rust half calls the functions below; they build the message objects a plugin class sees
(numpy arrays over the host's own buffers, no copies) and turn what the class returns into
plain tuples. Nothing here is part of a plugin author's API: see `vinebench_plugin.py` for
that contract, in words.
"""

import importlib
import sys
import tomllib

# A plugin's print() must not reach the worker's stdout, which carries its progress lines.
sys.stdout = sys.stderr

try:
    import numpy as np
except ImportError as e:  # pragma: no cover - the message is the point
    raise ImportError(
        "numpy is not importable: install it into the plugin's venv (the bridge hands "
        "messages over as numpy arrays)"
    ) from e

# plugin_api::LidarPoint, #[repr(C)]: five f32 and a u16, padded to 24 bytes.
POINT = np.dtype(
    {
        "names": ["x", "y", "z", "intensity", "time_s", "ring"],
        "formats": ["<f4", "<f4", "<f4", "<f4", "<f4", "<u2"],
        "offsets": [0, 4, 8, 12, 16, 20],
        "itemsize": 24,
    }
)

SENSOR_KINDS = ("imu", "wheel_odometry", "lidar", "scan2d", "rgbd")
EVENT_KINDS = (
    "loop_closure_accepted",
    "loop_closure_rejected",
    "tracking_lost",
    "tracking_recovered",
)


class Imu:
    """One IMU sample: specific force (m/s^2) and angular rate (rad/s) in the IMU frame;
    `orientation` is the world orientation (x, y, z, w) when the rig reports one, else None."""

    __slots__ = ("stamp_ns", "sensor", "accel", "gyro", "orientation")

    def __repr__(self):
        return f"Imu(stamp_ns={self.stamp_ns})"


class WheelOdometry:
    """Wheel odometry: body speeds and the integrated pose `odom_from_base` (4x4)."""

    __slots__ = ("stamp_ns", "sensor", "linear", "angular", "odom_from_base")

    def __repr__(self):
        return f"WheelOdometry(stamp_ns={self.stamp_ns})"


class PointCloud:
    """A lidar sweep in the sensor frame, stamped at its start. `points` is a structured
    array (fields x, y, z, intensity, time_s — the point's time after the stamp — and ring)
    over the host's buffer: read-only, valid during the call only (copy what you keep)."""

    __slots__ = ("stamp_ns", "sensor", "points")

    def xyz(self):
        """The points' coordinates as an (N, 3) float64 array (a copy)."""
        p = self.points
        return np.stack((p["x"], p["y"], p["z"]), axis=1).astype(np.float64)

    def __repr__(self):
        return f"PointCloud(stamp_ns={self.stamp_ns}, points={len(self.points)})"


class LaserScan:
    """A 2D scan as ROS's sensor_msgs/LaserScan; `ranges` and `intensities` are float32
    arrays over the host's buffers (read-only, valid during the call only)."""

    __slots__ = (
        "stamp_ns",
        "sensor",
        "angle_min",
        "angle_increment",
        "time_increment",
        "range_min",
        "range_max",
        "ranges",
        "intensities",
    )

    def __repr__(self):
        return f"LaserScan(stamp_ns={self.stamp_ns}, ranges={len(self.ranges)})"


class RgbdFrame:
    """A colour image (H, W, 3) uint8 RGB and its depth (H, W) float32 in metres (0: none),
    pixel for pixel, with pinhole intrinsics (fx, fy, cx, cy). Arrays are read-only views of
    the host's buffers, valid during the call only."""

    __slots__ = ("stamp_ns", "sensor", "width", "height", "rgb", "depth", "intrinsics")

    def __repr__(self):
        return f"RgbdFrame(stamp_ns={self.stamp_ns}, {self.width}x{self.height})"


def load_class(module, name):
    mod = importlib.import_module(module)
    try:
        return getattr(mod, name)
    except AttributeError:
        raise AttributeError(f"module {module!r} has no class {name!r}") from None


def requirements(cls, params_toml):
    """(sensor kinds, mode) from the class's `requirements(params)`."""
    ask = getattr(cls, "requirements", None)
    if ask is None:
        raise TypeError(f"{cls.__name__} has no requirements(params)")
    r = ask(tomllib.loads(params_toml))
    if isinstance(r, dict):
        sensors, mode = r.get("sensors", []), r.get("mode", "online")
    else:
        sensors, mode = r, "online"
    sensors = [str(s) for s in sensors]
    for s in sensors:
        if s not in SENSOR_KINDS:
            raise ValueError(f"unknown sensor kind {s!r} (one of {', '.join(SENSOR_KINDS)})")
    if mode not in ("online", "offline"):
        raise ValueError(f"mode must be 'online' or 'offline', not {mode!r}")
    return sensors, mode


def create(cls, params_toml, rig_toml):
    return cls(tomllib.loads(params_toml), tomllib.loads(rig_toml))


def _pose(value, what):
    """None, or (stamp_ns, the 12 numbers of a 4x4 or 3x4 transform's top three rows)."""
    if value is None:
        return None
    try:
        stamp, matrix = value
    except (TypeError, ValueError):
        raise TypeError(f"{what}: a pose is (stamp_ns, 4x4 map_from_base), got {value!r}") from None
    m = np.asarray(matrix, dtype=np.float64)
    if m.shape not in ((4, 4), (3, 4)):
        raise ValueError(f"{what}: a pose matrix is 4x4 or 3x4, got shape {m.shape}")
    return (int(stamp), tuple(m[:3, :].ravel().tolist()))


def _call(obj, method, message):
    f = getattr(obj, method, None)
    if f is None:
        return None
    return _pose(f(message), method)


def imu(obj, stamp_ns, sensor, accel, gyro, orientation):
    m = Imu()
    m.stamp_ns, m.sensor, m.accel, m.gyro, m.orientation = stamp_ns, sensor, accel, gyro, orientation
    return _call(obj, "on_imu", m)


def wheel_odometry(obj, stamp_ns, sensor, linear, angular, pose12):
    m = WheelOdometry()
    m.stamp_ns, m.sensor, m.linear, m.angular = stamp_ns, sensor, linear, angular
    t = np.eye(4)
    t[:3, :] = np.asarray(pose12).reshape(3, 4)
    m.odom_from_base = t
    return _call(obj, "on_wheel_odometry", m)


def point_cloud(obj, stamp_ns, sensor, points):
    m = PointCloud()
    m.stamp_ns, m.sensor = stamp_ns, sensor
    m.points = np.frombuffer(points, dtype=POINT)
    return _call(obj, "on_point_cloud", m)


def laser_scan(obj, stamp_ns, sensor, angles, limits, ranges, intensities):
    m = LaserScan()
    m.stamp_ns, m.sensor = stamp_ns, sensor
    m.angle_min, m.angle_increment, m.time_increment = angles
    m.range_min, m.range_max = limits
    m.ranges = np.frombuffer(ranges, dtype="<f4")
    m.intensities = np.frombuffer(intensities, dtype="<f4")
    return _call(obj, "on_laser_scan", m)


def rgbd(obj, stamp_ns, sensor, width, height, rgb, depth, intrinsics):
    m = RgbdFrame()
    m.stamp_ns, m.sensor, m.width, m.height, m.intrinsics = stamp_ns, sensor, width, height, intrinsics
    m.rgb = np.frombuffer(rgb, dtype=np.uint8).reshape(height, width, 3)
    m.depth = np.frombuffer(depth, dtype="<f4").reshape(height, width)
    return _call(obj, "on_rgbd", m)


def finish(obj):
    """(trajectory, events, map) as plain tuples from the class's finish() dict."""
    out = obj.finish()
    if out is None:
        out = {}
    if not isinstance(out, dict):
        raise TypeError(f"finish() returns a dict (trajectory, events, map), got {type(out).__name__}")
    unknown = set(out) - {"trajectory", "events", "map"}
    if unknown:
        raise ValueError(f"finish(): unknown keys {sorted(unknown)}")
    trajectory = []
    for p in out.get("trajectory", []):
        if p is None:
            raise TypeError("finish(): a trajectory entry is None, not (stamp_ns, map_from_base)")
        trajectory.append(_pose(p, "finish() trajectory"))
    events = []
    for e in out.get("events", []):
        kind = e["kind"]
        if kind not in EVENT_KINDS:
            raise ValueError(f"finish(): unknown event kind {kind!r} (one of {', '.join(EVENT_KINDS)})")
        stamps = e.get("loop_stamps_ns")
        if stamps is not None:
            stamps = (int(stamps[0]), int(stamps[1]))
        events.append((int(e["stamp_ns"]), kind, str(e.get("detail", "")), stamps))
    points = out.get("map")
    if points is not None:
        points = np.ascontiguousarray(np.asarray(points, dtype="<f4").reshape(-1, 3)).tobytes()
    return trajectory, events, points
