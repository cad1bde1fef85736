#!/usr/bin/env python3
"""Write a seeded ground-truth / estimate pair of N poses as TUM files.

Usage: gen_pair.py N OUT_DIR   ->  OUT_DIR/gt.tum, OUT_DIR/est.tum

Ground truth: 100 Hz along rows of a vineyard-like path; estimate: the same stamps with
±3 ms jitter, 3 cm position noise, 0.5° rotation noise and a slow drift, in another frame.
"""
import os
import sys

import numpy as np


def quat_from_yaw_pitch_roll(yaw, pitch, roll):
    cy, sy = np.cos(yaw / 2), np.sin(yaw / 2)
    cp, sp = np.cos(pitch / 2), np.sin(pitch / 2)
    cr, sr = np.cos(roll / 2), np.sin(roll / 2)
    w = cr * cp * cy + sr * sp * sy
    x = sr * cp * cy - cr * sp * sy
    y = cr * sp * cy + sr * cp * sy
    z = cr * cp * sy - sr * sp * cy
    return np.stack([x, y, z, w], axis=1)


def write_tum(path, t, xyz, q):
    data = np.column_stack([t, xyz, q])
    np.savetxt(path, data, fmt="%.17g", delimiter=" ", header="timestamp tx ty tz qx qy qz qw")


def main():
    if len(sys.argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    n, out = int(sys.argv[1]), sys.argv[2]
    os.makedirs(out, exist_ok=True)
    rng = np.random.default_rng(7)
    t = 1000.0 + np.arange(n) / 100.0
    s = 0.01 * t
    xyz = np.column_stack([18 * np.sin(s) + 0.05 * t, 3 * np.sin(0.5 * s) + 0.3 * s, 0.1 * np.sin(0.7 * t)])
    yaw = np.unwrap(np.arctan2(np.gradient(xyz[:, 1]), np.gradient(xyz[:, 0])))
    q = quat_from_yaw_pitch_roll(yaw, 0.03 * np.cos(0.9 * t), 0.02 * np.sin(1.3 * t))
    write_tum(os.path.join(out, "gt.tum"), t, xyz, q)

    drift = np.cumsum(rng.normal(0, 1e-4, size=(n, 3)), axis=0)
    c, s2 = np.cos(0.7), np.sin(0.7)
    rot = np.array([[c, -s2, 0], [s2, c, 0], [0, 0, 1]])
    est_xyz = (xyz + drift + rng.normal(0, 0.03, size=(n, 3))) @ rot.T + np.array([5.0, -3.0, 0.5])
    est_q = quat_from_yaw_pitch_roll(
        yaw + 0.7 + rng.normal(0, np.radians(0.5), n),
        0.03 * np.cos(0.9 * t) + rng.normal(0, np.radians(0.5), n),
        0.02 * np.sin(1.3 * t) + rng.normal(0, np.radians(0.5), n),
    )
    est_t = t + rng.uniform(-0.003, 0.003, n)
    write_tum(os.path.join(out, "est.tum"), est_t, est_xyz, est_q)
    return 0


if __name__ == "__main__":
    sys.exit(main())
