"""KISS-ICP (Vizzo et al., "KISS-ICP: In Defense of Point-to-Point ICP -- Simple, Accurate,
and Robust Registration If Done the Right Way", IEEE RA-L 8(2), 2023) as a vinebench system,
through the Python bridge: the real KISS-ICP 1.3.0 from PyPI (its C++ core), fed the VLP-16
sweeps with each point's time. Lidar odometry only: no IMU, no loop closure.

Parameters (all optional): `max_range`, `min_range`, `deskew`, `voxel_size`,
`max_points_per_voxel`, `initial_threshold`, `min_motion_th`, `max_num_iterations`,
`convergence_criterion`, `max_num_threads` — KISS-ICP's own configuration keys, flat; what is
not given keeps KISS-ICP's default (max_range 100 m, voxel_size = max_range / 100, deskew on).
`configs/peers.toml` runs it twice: with the defaults, and with the vineyard configuration
(max_range 30 m, so voxels of 0.3 m by KISS-ICP's own rule).
"""

import numpy as np
from kiss_icp.config import KISSConfig
from kiss_icp.kiss_icp import KissICP

from vinebench_frames import BaseFrame

SECTIONS = {
    "data": ("max_range", "min_range", "deskew"),
    "mapping": ("voxel_size", "max_points_per_voxel"),
    "adaptive_threshold": ("initial_threshold", "min_motion_th"),
    "registration": ("max_num_iterations", "convergence_criterion", "max_num_threads"),
}


def config_from(params):
    """KISSConfig from the flat parameter table, with KISS-ICP's defaults and its rule
    voxel_size = max_range / 100 when no voxel size is given (kiss_icp.config.load_config)."""
    nested = {}
    known = {key: section for section, keys in SECTIONS.items() for key in keys}
    for key, value in params.items():
        if key not in known:
            raise KeyError(f"unknown parameter {key!r} (one of {', '.join(sorted(known))})")
        nested.setdefault(known[key], {})[key] = value
    config = KISSConfig(**nested)
    if config.mapping.voxel_size is None:
        config.mapping.voxel_size = float(config.data.max_range / 100.0)
    return config


class KissIcp:
    @staticmethod
    def requirements(params):
        return ["lidar"]

    def __init__(self, params, rig):
        self.config = config_from(params)
        self.odometry = KissICP(config=self.config)
        lidar = next(s for s in rig["sensors"] if s["kind"] == "lidar")
        self.base_frame = BaseFrame(lidar)
        self.trajectory = []

    def on_point_cloud(self, cloud):
        points = cloud.xyz()
        times = cloud.points["time_s"].astype(np.float64)
        span = float(times.max() - times.min()) if len(times) else 0.0
        # KISS-ICP deskews to the sweep's last point (its Preprocess: exp((s - 1) * omega)
        # with s the point's time normalised over the sweep), so the pose it estimates is at
        # the last point's time. A sweep taken from one pose (the paper's world) has no
        # spread of times: no deskew, the pose is at the stamp.
        if span > 0.0:
            self.odometry.register_frame(points, times)
            stamp = cloud.stamp_ns + int(round(float(times.max()) * 1e9))
        else:
            self.odometry.register_frame(points, np.array([]))
            stamp = cloud.stamp_ns
        # KISS-ICP's map frame is the lidar at the first sweep; ours is the base there.
        pose = self.base_frame(self.odometry.last_pose)
        self.trajectory.append((stamp, pose))
        return stamp, pose

    def finish(self):
        return {"trajectory": self.trajectory}
