#!/usr/bin/env python3
"""Independent check of a `vinebench record` file with Foxglove's MCAP reader and ROS 2 CDR
decoder (the `mcap` and `mcap-ros2-support` packages, pinned in requirements.txt).

Decodes every message, checks each topic's schema name and encodings, the PointCloud2
layout LIO-SAM expects (x, y, z, intensity FLOAT32, ring UINT16, time FLOAT32), the camera's
images (rgb8 and 32FC1, packed little-endian rows) and camera info (plumb_bob, zero d,
identity r, p = [k | 0]), that each camera frame is a colour image, a depth image and a
camera info of one stamp and size, frame ids and the static transforms, and prints a JSON
summary: per topic the count and the first message's main values (for the camera topics
also every header stamp), so a caller can compare them with the simulator's own.

Usage: check_mcap.py FILE.mcap   (exit 0 and JSON on stdout; exit 1 and a reason on stderr)
"""

import json
import math
import struct
import sys

try:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
except ImportError as e:  # never pass silently without the decoder
    sys.exit(
        f"check_mcap.py: {e}; install tests/mcap/requirements.txt "
        "(source scripts/setup.sh puts a virtual environment with it first on PATH)"
    )

EXPECTED = {
    "/tf_static": ("tf2_msgs/msg/TFMessage", None),
    "/ground_truth": ("geometry_msgs/msg/PoseStamped", "map"),
    "/ground_truth/twist": ("geometry_msgs/msg/TwistStamped", "map"),
    "/imu": ("sensor_msgs/msg/Imu", "imu_link"),
    "/odom": ("nav_msgs/msg/Odometry", "odom"),
    "/scan_front": ("sensor_msgs/msg/LaserScan", "laser_front"),
    "/scan_back": ("sensor_msgs/msg/LaserScan", "laser_back"),
    "/points": ("sensor_msgs/msg/PointCloud2", "velodyne"),
    "/camera/color/image_raw": ("sensor_msgs/msg/Image", "camera_color_optical_frame"),
    "/camera/depth/image_raw": ("sensor_msgs/msg/Image", "camera_color_optical_frame"),
    "/camera/color/camera_info": ("sensor_msgs/msg/CameraInfo", "camera_color_optical_frame"),
}
# The camera's topics in the order each frame is written, and the images' encoding and
# bytes per pixel.
CAMERA_TOPICS = ["/camera/color/image_raw", "/camera/depth/image_raw", "/camera/color/camera_info"]
IMAGE_ENCODING = {"/camera/color/image_raw": ("rgb8", 3), "/camera/depth/image_raw": ("32FC1", 4)}
# name, offset, datatype (FLOAT32 = 7, UINT16 = 4), count
POINT_FIELDS = [
    ("x", 0, 7, 1),
    ("y", 4, 7, 1),
    ("z", 8, 7, 1),
    ("intensity", 12, 7, 1),
    ("ring", 16, 4, 1),
    ("time", 20, 7, 1),
]
EPOCH_NS = 1_700_000_000 * 10**9


def fail(message):
    sys.exit(f"check_mcap.py: {message}")


def stamp_ns(header):
    return header.stamp.sec * 10**9 + header.stamp.nanosec - EPOCH_NS


def xyz(v):
    return [v.x, v.y, v.z]


def xyzw(q):
    return [q.x, q.y, q.z, q.w]


def first_values(topic, msg, log_time):
    """The values the Rust test compares with the live stream."""
    if topic == "/tf_static":
        return {
            t.child_frame_id: {
                "parent": t.header.frame_id,
                "translation": xyz(t.transform.translation),
                "rotation": xyzw(t.transform.rotation),
            }
            for t in msg.transforms
        }
    out = {"stamp_ns": stamp_ns(msg.header), "log_time_ns": log_time - EPOCH_NS}
    if topic == "/ground_truth":
        out |= {"position": xyz(msg.pose.position), "orientation": xyzw(msg.pose.orientation)}
    elif topic == "/ground_truth/twist":
        out |= {"linear": xyz(msg.twist.linear), "angular": xyz(msg.twist.angular)}
    elif topic == "/imu":
        out |= {
            "angular_velocity": xyz(msg.angular_velocity),
            "linear_acceleration": xyz(msg.linear_acceleration),
            "orientation_covariance0": msg.orientation_covariance[0],
        }
    elif topic == "/odom":
        out |= {
            "child_frame_id": msg.child_frame_id,
            "position": xyz(msg.pose.pose.position),
            "orientation": xyzw(msg.pose.pose.orientation),
            "linear_x": msg.twist.twist.linear.x,
            "angular_z": msg.twist.twist.angular.z,
        }
    elif topic in ("/scan_front", "/scan_back"):
        out |= {
            "angle_min": msg.angle_min,
            "angle_increment": msg.angle_increment,
            "time_increment": msg.time_increment,
            "scan_time": msg.scan_time,
            "samples": len(msg.ranges),
            "first_finite_range": next((r for r in msg.ranges if math.isfinite(r)), None),
        }
    elif topic == "/points":
        x, y, z, intensity, ring, time = struct.unpack_from("<4fH2xf", bytes(msg.data), 0)
        out |= {
            "width": msg.width,
            "first_point": {
                "x": x, "y": y, "z": z, "intensity": intensity, "ring": ring, "time": time,
            },
        }
    elif topic in IMAGE_ENCODING:
        out |= {
            "frame_id": msg.header.frame_id,
            "height": msg.height,
            "width": msg.width,
            "encoding": msg.encoding,
            "is_bigendian": msg.is_bigendian,
            "step": msg.step,
            "data_len": len(msg.data),
        }
        data = bytes(msg.data)
        if topic == "/camera/color/image_raw":
            out["byte_sum"] = sum(data)
        else:
            depth = struct.unpack(f"<{len(data) // 4}f", data)
            centre = (msg.height // 2) * msg.width + msg.width // 2
            valid = next((i for i, z in enumerate(depth) if z > 0 and math.isfinite(z)), None)
            out |= {
                "zero_pixels": depth.count(0.0),
                "nan_pixels": sum(1 for z in depth if z != z),
                "first_valid_pixel": valid,
                # Bits, not numbers: JSON has no NaN, and bits compare exactly.
                "sample_bits": {
                    i: struct.unpack_from("<I", data, 4 * i)[0]
                    for i in (0, centre, valid, len(depth) - 1)
                    if i is not None
                },
            }
    elif topic == "/camera/color/camera_info":
        out |= {
            "frame_id": msg.header.frame_id,
            "height": msg.height,
            "width": msg.width,
            "distortion_model": msg.distortion_model,
            "d": list(msg.d),
            "k": list(msg.k),
            "r": list(msg.r),
            "p": list(msg.p),
        }
    return out


def check_image(topic, msg):
    encoding, bytes_per_pixel = IMAGE_ENCODING[topic]
    if (
        msg.encoding != encoding
        or msg.is_bigendian != 0
        or msg.step != msg.width * bytes_per_pixel
        or len(msg.data) != msg.step * msg.height
        or msg.width == 0
        or msg.height == 0
    ):
        fail(
            f"{topic}: {msg.encoding} {msg.width} x {msg.height}, step {msg.step}, "
            f"is_bigendian {msg.is_bigendian}, {len(msg.data)} bytes; expected {encoding}, "
            f"step {bytes_per_pixel} x width, little-endian, step x height bytes"
        )


def check_camera_info(msg):
    k, p = list(msg.k), list(msg.p)
    fx, cx, fy, cy = k[0], k[2], k[4], k[5]
    pinhole = [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0]
    if (
        msg.distortion_model != "plumb_bob"
        or list(msg.d) != [0.0] * 5
        or list(msg.r) != [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
        or k != pinhole
        or p != [fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0]
        or not (fx > 0 and fy > 0)
    ):
        fail(
            f"camera info {msg.distortion_model} d {list(msg.d)} k {k} r {list(msg.r)} p {p}; "
            "expected plumb_bob, five zeros, a pinhole k, identity r, p = [k | 0]"
        )


def check_camera_frames(frames):
    """Each frame: colour, depth and camera info, one after another, of one stamp and size."""
    for i in range(0, len(frames), 3):
        frame = frames[i : i + 3]
        topics = [f[0] for f in frame]
        if topics != CAMERA_TOPICS:
            fail(f"camera frame {i // 3}: topics {topics}, expected {CAMERA_TOPICS}")
        if len({f[1:] for f in frame}) != 1:
            fail(f"camera frame {i // 3}: stamps, log times and sizes differ: {frame}")


def check_cloud(msg):
    fields = [(f.name, f.offset, f.datatype, f.count) for f in msg.fields]
    if fields != POINT_FIELDS:
        fail(f"/points fields {fields}, expected {POINT_FIELDS}")
    if msg.height != 1 or not msg.is_dense or msg.is_bigendian or msg.point_step != 24:
        fail(
            f"/points height {msg.height}, is_dense {msg.is_dense}, "
            f"is_bigendian {msg.is_bigendian}, point_step {msg.point_step}"
        )
    if msg.row_step != msg.width * 24 or len(msg.data) != msg.row_step:
        fail(f"/points row_step {msg.row_step}, width {msg.width}, {len(msg.data)} bytes")


def main(path):
    summary = {"file": path, "profile": None, "topics": {}}
    last_log_time = -1
    camera_frames = []  # (topic, stamp, log time, width, height) of each camera message
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary["profile"] = reader.get_header().profile
        for schema, channel, message, msg in reader.iter_decoded_messages(log_time_order=False):
            topic = channel.topic
            if topic not in EXPECTED:
                fail(f"unexpected topic {topic}")
            schema_name, frame = EXPECTED[topic]
            if schema.name != schema_name or schema.encoding != "ros2msg":
                fail(f"{topic}: schema {schema.name} ({schema.encoding}), expected {schema_name}")
            if channel.message_encoding != "cdr":
                fail(f"{topic}: message encoding {channel.message_encoding}")
            if message.log_time < last_log_time:
                fail(f"{topic}: log time {message.log_time} before {last_log_time}")
            last_log_time = message.log_time
            if frame is not None and msg.header.frame_id != frame:
                fail(f"{topic}: frame_id {msg.header.frame_id!r}, expected {frame!r}")
            if topic == "/points":
                check_cloud(msg)
            elif topic in IMAGE_ENCODING:
                check_image(topic, msg)
            elif topic == "/camera/color/camera_info":
                check_camera_info(msg)
            entry = summary["topics"].setdefault(
                topic, {"schema": schema.name, "count": 0, "first": None}
            )
            if entry["first"] is None:
                entry["first"] = first_values(topic, msg, message.log_time)
            entry["count"] += 1
            if topic in CAMERA_TOPICS:
                stamp = stamp_ns(msg.header)
                camera_frames.append(
                    (topic, stamp, message.log_time - EPOCH_NS, msg.width, msg.height)
                )
                entry.setdefault("stamps_ns", []).append(stamp)
    check_camera_frames(camera_frames)
    if "/tf_static" not in summary["topics"]:
        fail("no /tf_static")
    json.dump(summary, sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    if len(sys.argv) != 2:
        fail("usage: check_mcap.py FILE.mcap")
    main(sys.argv[1])
