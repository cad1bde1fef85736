#!/usr/bin/env python3
"""Independent check of a run's results.mcap (written beside metrics.json when vinebench
scores a run) with Foxglove's MCAP reader and ROS 2 CDR decoder (the `mcap` and
`mcap-ros2-support` packages, pinned in requirements.txt).

Decodes every message and checks each topic's schema name and encodings, that every header
is in frame `map`, that the two paths (nav_msgs/Path) are single messages, not empty, with
stamps strictly increasing and unit quaternions, logged at the first ground-truth stamp as
are the map and the loops, that `/estimate/pose` repeats the estimate path pose by pose at
each pose's own stamp, the map's PointCloud2 layout (x, y, z FLOAT32 at 0, 4, 8, point_step
12, one row, little-endian, dense, finite), and that every loop marker is a LINE_LIST of 2
points in namespace true_loops (green) or false_loops (red), ids 0, 1, ... in each; log
times never go back. Prints a JSON summary: the `vinebench` metadata, per topic its schema
and count, per path its pose count, stamp, first and last pose, the number of map points,
the loop markers per namespace; with --poses also every pose of both paths, the map's first
point and every marker's two ends, so a caller can compare them with the run's own files.

Usage: check_results.py [--poses] FILE.mcap
       (exit 0 and JSON on stdout; exit 1 and a reason on stderr)
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
        f"check_results.py: {e}; install tests/mcap/requirements.txt "
        "(source scripts/setup.sh puts a virtual environment with it first on PATH)"
    )

EXPECTED = {
    "/groundtruth/path": "nav_msgs/msg/Path",
    "/estimate/path": "nav_msgs/msg/Path",
    "/estimate/pose": "geometry_msgs/msg/PoseStamped",
    "/map": "sensor_msgs/msg/PointCloud2",
    "/loops": "visualization_msgs/msg/MarkerArray",
}
REQUIRED = ["/groundtruth/path", "/estimate/path", "/estimate/pose", "/loops"]
# Topics holding one message, logged at the first ground-truth stamp.
ONE_SHOT = ["/groundtruth/path", "/estimate/path", "/map", "/loops"]
FRAME = "map"
# name, offset, datatype (FLOAT32 = 7), count
MAP_FIELDS = [("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1)]
LINE_LIST = 5
COLORS = {"true_loops": [0.0, 1.0, 0.0, 1.0], "false_loops": [1.0, 0.0, 0.0, 1.0]}
EPOCH_NS = 1_700_000_000 * 10**9


def fail(message):
    sys.exit(f"check_results.py: {message}")


def stamp_ns(header):
    return header.stamp.sec * 10**9 + header.stamp.nanosec - EPOCH_NS


def check_frame(topic, header):
    if header.frame_id != FRAME:
        fail(f"{topic}: frame_id {header.frame_id!r}, expected {FRAME!r}")


def pose_values(topic, stamped):
    """A PoseStamped as {stamp_ns, position, orientation}, its frame and quaternion checked."""
    check_frame(topic, stamped.header)
    p, q = stamped.pose.position, stamped.pose.orientation
    norm = math.sqrt(q.x**2 + q.y**2 + q.z**2 + q.w**2)
    if abs(norm - 1.0) > 1e-9:
        fail(f"{topic}: quaternion of norm {norm} at {stamp_ns(stamped.header)} ns")
    return {
        "stamp_ns": stamp_ns(stamped.header),
        "position": [p.x, p.y, p.z],
        "orientation": [q.x, q.y, q.z, q.w],
    }


def check_path(topic, msg):
    check_frame(topic, msg.header)
    poses = [pose_values(topic, p) for p in msg.poses]
    if not poses:
        fail(f"{topic}: no pose")
    stamps = [p["stamp_ns"] for p in poses]
    for a, b in zip(stamps, stamps[1:]):
        if b <= a:
            fail(f"{topic}: stamp {b} ns after {a} ns")
    return poses


def check_cloud(msg):
    check_frame("/map", msg.header)
    fields = [(f.name, f.offset, f.datatype, f.count) for f in msg.fields]
    if fields != MAP_FIELDS:
        fail(f"/map fields {fields}, expected {MAP_FIELDS}")
    if msg.height != 1 or not msg.is_dense or msg.is_bigendian or msg.point_step != 12:
        fail(
            f"/map height {msg.height}, is_dense {msg.is_dense}, "
            f"is_bigendian {msg.is_bigendian}, point_step {msg.point_step}"
        )
    if msg.row_step != msg.width * 12 or len(msg.data) != msg.row_step:
        fail(f"/map row_step {msg.row_step}, width {msg.width}, {len(msg.data)} bytes")
    values = struct.unpack(f"<{3 * msg.width}f", bytes(msg.data))
    if not all(math.isfinite(v) for v in values):
        fail("/map has a non-finite coordinate but says it is dense")
    return {"points": msg.width, "first_point": list(values[:3]) if values else None}


def check_markers(msg):
    markers = []
    next_id = {ns: 0 for ns in COLORS}
    for m in msg.markers:
        check_frame("/loops", m.header)
        if m.ns not in COLORS:
            fail(f"/loops: marker namespace {m.ns!r}, expected one of {sorted(COLORS)}")
        color = [m.color.r, m.color.g, m.color.b, m.color.a]
        if (
            m.type != LINE_LIST
            or m.action != 0
            or len(m.points) != 2
            or color != COLORS[m.ns]
            or not m.scale.x > 0
            or m.id != next_id[m.ns]
        ):
            fail(
                f"/loops: marker {m.ns}/{m.id} type {m.type}, action {m.action}, "
                f"{len(m.points)} points, colour {color}, width {m.scale.x}; expected a "
                f"LINE_LIST of 2 points coloured {COLORS[m.ns]}, id {next_id[m.ns]}"
            )
        next_id[m.ns] += 1
        markers.append({"ns": m.ns, "id": m.id, "ends": [[p.x, p.y, p.z] for p in m.points]})
    return markers


def main(path, with_poses):
    summary = {"file": path, "profile": None, "metadata": {}, "topics": {}}
    last_log_time = -1
    one_shot_times = {}
    paths = {}
    pose_messages = []  # (log time, pose) of /estimate/pose
    cloud = None
    markers = None
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary["profile"] = reader.get_header().profile
        for record in reader.iter_metadata():
            summary["metadata"][record.name] = dict(record.metadata)
        for schema, channel, message, msg in reader.iter_decoded_messages(log_time_order=False):
            topic = channel.topic
            if topic not in EXPECTED:
                fail(f"unexpected topic {topic}")
            if schema.name != EXPECTED[topic] or schema.encoding != "ros2msg":
                fail(f"{topic}: schema {schema.name} ({schema.encoding}), expected {EXPECTED[topic]}")
            if channel.message_encoding != "cdr":
                fail(f"{topic}: message encoding {channel.message_encoding}")
            if message.log_time < last_log_time:
                fail(f"{topic}: log time {message.log_time} before {last_log_time}")
            last_log_time = message.log_time
            entry = summary["topics"].setdefault(topic, {"schema": schema.name, "count": 0})
            entry["count"] += 1
            if topic in ONE_SHOT:
                if entry["count"] > 1:
                    fail(f"{topic}: more than one message")
                one_shot_times[topic] = message.log_time - EPOCH_NS
            if topic in ("/groundtruth/path", "/estimate/path"):
                paths[topic] = {"stamp_ns": stamp_ns(msg.header), "poses": check_path(topic, msg)}
            elif topic == "/estimate/pose":
                pose_messages.append((message.log_time - EPOCH_NS, pose_values(topic, msg)))
            elif topic == "/map":
                cloud = check_cloud(msg)
            elif topic == "/loops":
                markers = check_markers(msg)
    for topic in REQUIRED:
        if topic not in summary["topics"]:
            fail(f"no {topic}")
    first_ns = paths["/groundtruth/path"]["poses"][0]["stamp_ns"]
    for topic, log_time in one_shot_times.items():
        if log_time != first_ns:
            fail(f"{topic} logged at {log_time} ns, not at the first ground-truth stamp {first_ns} ns")
    for topic in paths:
        if paths[topic]["stamp_ns"] != first_ns:
            fail(f"{topic} stamped {paths[topic]['stamp_ns']} ns, expected {first_ns} ns")
    estimate = paths["/estimate/path"]["poses"]
    if [p for _, p in pose_messages] != estimate:
        fail(
            f"/estimate/pose ({len(pose_messages)} messages) differs from /estimate/path "
            f"({len(estimate)} poses)"
        )
    for log_time, p in pose_messages:
        if log_time != p["stamp_ns"]:
            fail(f"/estimate/pose stamped {p['stamp_ns']} ns logged at {log_time} ns")

    summary["paths"] = {}
    for topic, path_ in paths.items():
        poses = path_["poses"]
        summary["paths"][topic] = {
            "poses": len(poses),
            "stamp_ns": path_["stamp_ns"],
            "first": poses[0],
            "last": poses[-1],
        }
        if with_poses:
            summary["paths"][topic]["all"] = poses
    summary["map"] = None
    if cloud is not None:
        summary["map"] = {"points": cloud["points"]}
        if with_poses:
            summary["map"]["first_point"] = cloud["first_point"]
    summary["loops"] = {ns: sum(1 for m in markers if m["ns"] == ns) for ns in COLORS}
    if with_poses:
        summary["loop_markers"] = markers
    json.dump(summary, sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    args = sys.argv[1:]
    with_poses = "--poses" in args
    files = [a for a in args if a != "--poses"]
    if len(files) != 1 or len(args) - len(files) > 1:
        fail("usage: check_results.py [--poses] FILE.mcap")
    main(files[0], with_poses)
