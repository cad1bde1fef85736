"""Frames of the rig for the adapters: a sensor's mounting `base_from_sensor` as a 4x4
matrix, and a sensor pose re-expressed as the base's (map_from_base = base_from_sensor ·
sensor_pose · sensor_from_base, so that the map frame is the base at the first pose)."""

import numpy as np


def isometry(xyz, xyzw):
    """The 4x4 transform of a translation and a unit quaternion (x, y, z, w)."""
    x, y, z, w = xyzw
    t = np.eye(4)
    t[:3, :3] = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    t[:3, 3] = xyz
    return t


def mounting(sensor):
    """`base_from_sensor` of a rig sensor (a dict of the rig)."""
    return isometry(sensor["base_from_sensor_xyz"], sensor["base_from_sensor_xyzw"])


class BaseFrame:
    """Moves poses of a sensor's own odometry (its frame at the start as the map) to the
    base's."""

    def __init__(self, sensor):
        self.base_from_sensor = mounting(sensor)
        self.sensor_from_base = np.linalg.inv(self.base_from_sensor)

    def __call__(self, sensor_pose):
        return self.base_from_sensor @ sensor_pose @ self.sensor_from_base
