#!/usr/bin/env python3
"""Independent check of a `vinebench record` file with Foxglove's MCAP reader and ROS 2 CDR
decoder (the `mcap` and `mcap-ros2-support` packages, pinned in requirements.txt).

Decodes every message, checks each topic's schema name and encodings, the PointCloud2
layout LIO-SAM expects (x, y, z, intensity FLOAT32, ring UINT16, time FLOAT32), frame ids
and the static transforms, and prints a JSON summary: per topic the count and the first
message's main values, so a caller can compare them with the simulator's own.

Usage: check_mcap.py FILE.mcap   (exit 0 and JSON on stdout; exit 1 and a reason on stderr)
"""

import json
import math
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
}
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
        import struct

        x, y, z, intensity, ring, time = struct.unpack_from("<4fH2xf", bytes(msg.data), 0)
        out |= {
            "width": msg.width,
            "first_point": {
                "x": x, "y": y, "z": z, "intensity": intensity, "ring": ring, "time": time,
            },
        }
    return out


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
            entry = summary["topics"].setdefault(
                topic, {"schema": schema.name, "count": 0, "first": None}
            )
            if entry["first"] is None:
                entry["first"] = first_values(topic, msg, message.log_time)
            entry["count"] += 1
    if "/tf_static" not in summary["topics"]:
        fail("no /tf_static")
    json.dump(summary, sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    if len(sys.argv) != 2:
        fail("usage: check_mcap.py FILE.mcap")
    main(sys.argv[1])
