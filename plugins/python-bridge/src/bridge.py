"""The Python half of vinebench's Python plugin bridge (compiled into libpython_bridge.so).

The Rust half calls the functions below; they build the message objects a plugin class sees
(numpy arrays over the host's own buffers, no copies) and turn what the class returns into
plain tuples. Nothing here is part of a plugin author's API: the contract is
docs/plugin-contract.md (every message's fields as a Python class sees them), and
`vinebench_plugin.py` is its runnable example.

The layouts and names that the Rust side defines (the lidar point's fields and offsets, the
event kinds, the contract's revision) are not typed here: `configure` receives them from the
Rust half when the module is loaded, so there is one copy of each.
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

# Set by `configure` from the Rust half before any other call.
POINT = None  # numpy dtype of plugin_api::LidarPoint
SENSOR_KINDS = ()
EVENT_KINDS = ()
API_REVISION = 0


def configure(point_fields, point_size, sensor_kinds, event_kinds, api_revision):
    """The Rust half's layouts and registries: `point_fields` is [(name, numpy format,
    offset)] of plugin_api::LidarPoint (from `offset_of!`), `point_size` its size."""
    global POINT, SENSOR_KINDS, EVENT_KINDS, API_REVISION
    POINT = np.dtype(
        {
            "names": [f[0] for f in point_fields],
            "formats": [f[1] for f in point_fields],
            "offsets": [f[2] for f in point_fields],
            "itemsize": point_size,
        }
    )
    SENSOR_KINDS = tuple(sensor_kinds)
    EVENT_KINDS = tuple(event_kinds)
    API_REVISION = int(api_revision)


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


class Gnss:
    """A GNSS epoch (revision 5): `status` ("no_fix", "single", "float" or "fixed"),
    `satellites` used, `position` (east, north, up of the antenna from the datum, metres; NaN
    without a fix) and its `covariance` (3x3, m^2), the same fix as `latitude`, `longitude`
    (degrees) and `altitude` (ellipsoidal, m), and `hdop` (NaN under four satellites).
    Nothing is checked for the class: refuse a fix whose position is not finite or whose
    covariance is not symmetric positive definite."""

    __slots__ = (
        "stamp_ns",
        "sensor",
        "status",
        "satellites",
        "position",
        "covariance",
        "latitude",
        "longitude",
        "altitude",
        "hdop",
    )

    def __repr__(self):
        return f"Gnss(stamp_ns={self.stamp_ns}, status={self.status})"


def load_class(module, name):
    mod = importlib.import_module(module)
    try:
        return getattr(mod, name)
    except AttributeError:
        raise AttributeError(f"module {module!r} has no class {name!r}") from None


def requirements(cls, params_toml):
    """(sensor kinds, mode, can_localize) from the class's `requirements(params)`."""
    ask = getattr(cls, "requirements", None)
    if ask is None:
        raise TypeError(f"{cls.__name__} has no requirements(params)")
    r = ask(tomllib.loads(params_toml))
    can_localize = False
    if isinstance(r, dict):
        unknown = set(r) - {"sensors", "mode", "can_localize"}
        if unknown:
            raise ValueError(f"requirements: unknown keys {sorted(unknown)}")
        sensors, mode = r.get("sensors", []), r.get("mode", "online")
        can_localize = r.get("can_localize", False)
        if not isinstance(can_localize, bool):
            raise TypeError(f"requirements: can_localize is True or False, not {can_localize!r}")
    else:
        sensors, mode = r, "online"
    sensors = [str(s) for s in sensors]
    for s in sensors:
        if s not in SENSOR_KINDS:
            raise ValueError(f"unknown sensor kind {s!r} (one of {', '.join(SENSOR_KINDS)})")
    if mode not in ("online", "offline"):
        raise ValueError(f"mode must be 'online' or 'offline', not {mode!r}")
    return sensors, mode, can_localize


def create(cls, params_toml, rig_toml):
    return cls(tomllib.loads(params_toml), tomllib.loads(rig_toml))


def create_localizing(cls, params_toml, rig_toml, map_bytes, map_format, map_version, guess):
    """The class's `localize(params, rig, start)` (revision 4): `start` is a dict of the saved
    map's `bytes`, `format` and `version` and the `initial_guess` (None, or a dict of
    `map_from_base` (4x4), `sigma_xy` (m) and `sigma_yaw` (rad))."""
    localize = getattr(cls, "localize", None)
    if localize is None:
        raise TypeError(f"{cls.__name__} has no localize(params, rig, start)")
    initial_guess = None
    if guess is not None:
        rows, sigma_xy, sigma_yaw = guess
        m = np.eye(4)
        m[:3, :] = np.asarray(rows, dtype=np.float64).reshape(3, 4)
        initial_guess = {"map_from_base": m, "sigma_xy": sigma_xy, "sigma_yaw": sigma_yaw}
    start = {
        "bytes": bytes(map_bytes),
        "format": map_format,
        "version": map_version,
        "initial_guess": initial_guess,
    }
    return localize(tomllib.loads(params_toml), tomllib.loads(rig_toml), start)


POSE_STATUSES = ("localized", "searching")


def _pose_status(value, what):
    """None, or (stamp_ns, the 12 numbers of a 4x4 or 3x4 transform's top three rows,
    status): a message's answer, `(stamp_ns, map_from_base)` or, revision 4,
    `(stamp_ns, map_from_base, "localized" | "searching")`."""
    if value is None:
        return None
    try:
        if len(value) == 3:
            stamp, matrix, status = value
        else:
            (stamp, matrix), status = value, "localized"
    except (TypeError, ValueError):
        raise TypeError(
            f"{what}: a pose is (stamp_ns, 4x4 map_from_base[, status]), got {value!r}"
        ) from None
    if status not in POSE_STATUSES:
        raise ValueError(f"{what}: a pose's status is 'localized' or 'searching', not {status!r}")
    m = np.asarray(matrix, dtype=np.float64)
    if m.shape not in ((4, 4), (3, 4)):
        raise ValueError(f"{what}: a pose matrix is 4x4 or 3x4, got shape {m.shape}")
    return (int(stamp), tuple(m[:3, :].ravel().tolist()), status)


def _pose(value, what):
    """None, or (stamp_ns, the 12 numbers of a 4x4 or 3x4 transform's top three rows)."""
    p = _pose_status(value, what)
    return None if p is None else p[:2]


def _call(obj, method, message):
    f = getattr(obj, method, None)
    if f is None:
        return None
    return _pose_status(f(message), method)


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


def gnss(obj, stamp_ns, sensor, status, satellites, position, covariance, geodetic, hdop):
    m = Gnss()
    m.stamp_ns, m.sensor, m.status, m.satellites, m.hdop = stamp_ns, sensor, status, satellites, hdop
    m.position = np.array(position, dtype=np.float64)
    m.covariance = np.array(covariance, dtype=np.float64).reshape(3, 3)
    m.latitude, m.longitude, m.altitude = geodetic
    return _call(obj, "on_gnss", m)


def _relative_pose(value):
    """A loop's `loop_relative_pose` as a flat list: 7 numbers (x, y, z, qx, qy, qz, qw) as
    given, or the 12 numbers of a 4x4 / 3x4 transform's top three rows, which the Rust half
    turns into a pose as it does every other (`pose_from`); None stays None."""
    if value is None:
        return None
    m = np.asarray(value, dtype=np.float64)
    if m.shape == (7,):
        return m.tolist()
    if m.shape in ((4, 4), (3, 4)):
        return m[:3, :].ravel().tolist()
    raise ValueError(
        f"finish(): an event's loop_relative_pose is 7 numbers (x, y, z, qx, qy, qz, qw) "
        f"or a 4x4 transform, got shape {m.shape}"
    )


def _matches(value):
    """A loop's `loop_matches` as little-endian float32 bytes, 4 numbers a match (u, v in the
    current frame, u, v in the matched one, pixels); None stays None."""
    if value is None:
        return None
    m = np.asarray(value, dtype=np.float64)
    if m.size == 0:
        m = m.reshape(0, 4)
    if m.ndim != 2 or m.shape[1] != 4:
        raise ValueError(
            f"finish(): an event's loop_matches is an (N, 4) array of "
            f"[u_current, v_current, u_matched, v_matched], got shape {m.shape}"
        )
    if not np.isfinite(m).all():
        raise ValueError("finish(): an event's loop_matches are not all finite")
    return np.ascontiguousarray(m.astype("<f4")).tobytes()


def _grid(value):
    """An occupancy grid dict as (resolution, (x, y, yaw), width, height, cells bytes)."""
    if value is None:
        return None
    if not isinstance(value, dict):
        raise TypeError(f"finish(): grid is a dict (resolution, origin, cells), got {type(value).__name__}")
    unknown = set(value) - {"resolution", "origin", "cells"}
    if unknown:
        raise ValueError(f"finish(): unknown grid keys {sorted(unknown)}")
    cells = np.asarray(value["cells"])
    if cells.ndim != 2:
        raise ValueError(f"finish(): grid cells are a 2D array (rows, columns), got shape {cells.shape}")
    if cells.size and (cells.min() < -1 or cells.max() > 100):
        raise ValueError("finish(): grid cells are -1 (unknown) or 0..100 (occupancy)")
    origin = tuple(float(v) for v in value.get("origin", (0.0, 0.0, 0.0)))
    if len(origin) != 3:
        raise ValueError("finish(): grid origin is (x, y, yaw)")
    height, width = cells.shape
    data = np.ascontiguousarray(cells.astype(np.int8)).tobytes()
    return (float(value["resolution"]), origin, int(width), int(height), data)


def _saved_map(value):
    """(format, version, bytes) of finish()'s `saved_map` (revision 4), or None."""
    if value is None:
        return None
    if not isinstance(value, dict):
        raise TypeError(f"finish(): saved_map is a dict (format, version, bytes), got {type(value).__name__}")
    unknown = set(value) - {"format", "version", "bytes"}
    if unknown:
        raise ValueError(f"finish(): unknown saved_map keys {sorted(unknown)}")
    fmt, version, data = value.get("format"), value.get("version"), value.get("bytes")
    if not isinstance(fmt, str) or not fmt.strip():
        raise ValueError("finish(): saved_map's format is a non-empty string naming the format")
    if not isinstance(version, int) or not 0 <= version < 2**32:
        raise ValueError("finish(): saved_map's version is an int in 0 .. 2**32 - 1")
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise TypeError(f"finish(): saved_map's bytes are bytes, got {type(data).__name__}")
    return (fmt, version, bytes(data))


def finish(obj):
    """(trajectory, events, map, grid, saved_map) as plain tuples from the class's finish()
    dict."""
    out = obj.finish()
    if out is None:
        out = {}
    if not isinstance(out, dict):
        raise TypeError(
            f"finish() returns a dict (trajectory, events, map, grid, saved_map), got {type(out).__name__}"
        )
    unknown = set(out) - {"trajectory", "events", "map", "grid", "saved_map"}
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
        unknown = set(e) - {
            "stamp_ns", "kind", "detail", "loop_stamps_ns", "loop_relative_pose", "loop_matches"
        }
        if unknown:
            raise ValueError(f"finish(): unknown event keys {sorted(unknown)}")
        stamps = e.get("loop_stamps_ns")
        if stamps is not None:
            stamps = (int(stamps[0]), int(stamps[1]))
        relative = _relative_pose(e.get("loop_relative_pose"))
        matches = _matches(e.get("loop_matches"))
        events.append(
            (int(e["stamp_ns"]), kind, str(e.get("detail", "")), stamps, relative, matches)
        )
    points = out.get("map")
    if points is not None:
        points = np.ascontiguousarray(np.asarray(points, dtype="<f4").reshape(-1, 3)).tobytes()
    return trajectory, events, points, _grid(out.get("grid")), _saved_map(out.get("saved_map"))


def traceback_text(exc):
    """The whole traceback of `exc`, as Python prints it."""
    import traceback

    return "".join(traceback.format_exception(exc))
