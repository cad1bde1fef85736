"""ORB-SLAM3 (Campos et al., "ORB-SLAM3: An Accurate Open-Source Library for Visual,
Visual-Inertial and Multi-Map SLAM", IEEE T-RO 37(6), 2021) as a vinebench system, through
the Python bridge: the real ORB-SLAM3 from `pyorbslam3` 0.1.1 (GPL-3.0, an optional
dependency in its own venv, never linked into vinebench), in RGB-D mode, or RGB-D-inertial
with `inertial = true`.

Parameters (all optional):
- `vocabulary`: the DBoW2 text vocabulary (default `../target/orbslam3-vocabulary.txt`,
  relative to the bench file). It is vinebench's own vocabulary
  (`plugins/orbslam2/vocabulary/vineyard-k10l6.dbow`, trained on vineyard frames of another
  world) exported by `orbslam2-vocabulary --export-dbow2-text`, not ORB-SLAM's `ORBvoc.txt`
  (trained on general images, 139 MB, downloaded from GitHub): a confound wherever place
  recognition is compared.
- `features` (1000), `scale_factor` (1.2), `levels` (8), `ini_th_fast` (20),
  `min_th_fast` (7), `th_depth` (40, in baselines), `baseline_m` (0.07732): ORB-SLAM3's
  RGB-D example settings for the TUM sequences (`Examples/RGB-D/TUM1.yaml`).
- `inertial` (false): RGB-D-inertial (`Sensor.IMU_RGBD`): every IMU sample between two
  frames goes with the later frame; the IMU's noise densities and random walks, rate and
  `IMU.T_b_c1` (imu_from_camera) come from the rig. It does not run with pyorbslam3 0.1.1
  here: the run on S1 of our world ends in a segmentation fault at the first frames, and a
  direct call (`track_rgbd` with two IMU rows) raises `RuntimeError: Operation not
  permitted`; the settings it writes load (ORB-SLAM3 prints them back).

The settings file is written from the first frame's size and intrinsics (depth in metres:
`RGBD.DepthMapFactor` 1). The online pose of each frame is `pose_wc` when valid; the final
trajectory is ORB-SLAM3's own `SaveTrajectoryTUM` after `shutdown()` (every frame, with the
loop closures' corrections; the frames it could not place while lost, which it writes again
under the last tracked frame's time, are left out). ORB-SLAM3 says only that the map changed (`map_changed()`: a loop
closure, a map merge or a global bundle adjustment), without which keyframes: each becomes a
`loop_closure_accepted` event at that frame's stamp without loop stamps, which the host judges
by the pose jump it causes. Tracking lost and recovered become events too.
"""

import os
import tempfile

import numpy as np
import pyorbslam3

from vinebench_frames import BaseFrame, isometry, mounting

DEFAULTS = {
    "vocabulary": "../target/orbslam3-vocabulary.txt",
    "features": 1000,
    "scale_factor": 1.2,
    "levels": 8,
    "ini_th_fast": 20,
    "min_th_fast": 7,
    "th_depth": 40.0,
    "baseline_m": 0.07732,
    "inertial": False,
}


def settings_yaml(p, width, height, intrinsics, fps, lens=(0.0, 0.0, 0.0, 0.0, 0.0)):
    """ORB-SLAM3's settings; `lens` the rig camera's plumb_bob [k1, k2, p1, p2, k3] (zero: a
    rectified image), which ORB-SLAM3 undistorts keypoints with."""
    fx, fy, cx, cy = intrinsics
    k1, k2, p1, p2, k3 = (float(v) for v in lens)
    # k3 only for a lens: ORB-SLAM3 reads a fifth coefficient where there is one, and a
    # rectified image's settings stay those of four zeros.
    k3_line = f"Camera1.k3: {k3!r}\n" if any((k1, k2, p1, p2, k3)) else ""
    return f"""%YAML:1.0
File.version: "1.0"
Camera.type: "PinHole"
Camera1.fx: {fx!r}
Camera1.fy: {fy!r}
Camera1.cx: {cx!r}
Camera1.cy: {cy!r}
Camera1.k1: {k1!r}
Camera1.k2: {k2!r}
Camera1.p1: {p1!r}
Camera1.p2: {p2!r}
{k3_line}Camera.width: {width}
Camera.height: {height}
Camera.fps: {int(round(fps))}
Camera.RGB: 1
Stereo.ThDepth: {float(p['th_depth'])!r}
Stereo.b: {float(p['baseline_m'])!r}
RGBD.DepthMapFactor: 1.0
ORBextractor.nFeatures: {int(p['features'])}
ORBextractor.scaleFactor: {float(p['scale_factor'])!r}
ORBextractor.nLevels: {int(p['levels'])}
ORBextractor.iniThFAST: {int(p['ini_th_fast'])}
ORBextractor.minThFAST: {int(p['min_th_fast'])}
Viewer.KeyFrameSize: 0.05
Viewer.KeyFrameLineWidth: 1.0
Viewer.GraphLineWidth: 0.9
Viewer.PointSize: 2.0
Viewer.CameraSize: 0.08
Viewer.CameraLineWidth: 3.0
Viewer.ViewpointX: 0.0
Viewer.ViewpointY: -0.7
Viewer.ViewpointZ: -1.8
Viewer.ViewpointF: 500.0
"""


def imu_yaml(imu, imu_from_camera):
    noise = imu.get("noise", {})
    rows = ", ".join(repr(float(v)) for v in imu_from_camera.ravel())
    return f"""IMU.T_b_c1: !!opencv-matrix
   rows: 4
   cols: 4
   dt: f
   data: [{rows}]
IMU.InsertKFsWhenLost: 0
IMU.NoiseGyro: {float(noise.get('gyro_noise_density', 1e-4))!r}
IMU.NoiseAcc: {float(noise.get('accel_noise_density', 1e-3))!r}
IMU.GyroWalk: {float(noise.get('gyro_bias_random_walk', 1e-6))!r}
IMU.AccWalk: {float(noise.get('accel_bias_random_walk', 1e-5))!r}
IMU.Frequency: {float(imu['rate_hz'])!r}
"""


class OrbSlam3:
    @staticmethod
    def requirements(params):
        return ["rgbd", "imu"] if params.get("inertial") else ["rgbd"]

    def __init__(self, params, rig):
        unknown = set(params) - set(DEFAULTS)
        if unknown:
            raise KeyError(f"unknown parameters {sorted(unknown)} (known: {', '.join(DEFAULTS)})")
        self.params = {**DEFAULTS, **params}
        base = os.environ.get("VINEBENCH_BENCH_DIR", os.getcwd())
        self.vocabulary = os.path.join(base, self.params["vocabulary"])
        if not os.path.isfile(self.vocabulary):
            raise FileNotFoundError(
                f"no ORB vocabulary at {self.vocabulary}: make it with "
                "`target/release/orbslam2-vocabulary --export-dbow2-text "
                "plugins/orbslam2/vocabulary/vineyard-k10l6.dbow target/orbslam3-vocabulary.txt`"
            )
        camera = next(s for s in rig["sensors"] if s["kind"] == "rgbd")
        self.fps = camera["rate_hz"]
        # The lens of a raw image (absent: rectified), as the rig's camera intrinsics give it.
        figures = camera.get("intrinsics", {})
        self.lens = [figures.get(k, 0.0) for k in ("k1", "k2", "p1", "p2", "k3")]
        self.base_from_camera = mounting(camera)
        self.base_pose = BaseFrame(camera)
        self.imu = next((s for s in rig["sensors"] if s["kind"] == "imu"), None)
        if self.params["inertial"] and self.imu is None:
            raise ValueError("inertial = true, but the rig has no IMU")
        self.samples = []  # IMU rows [t, gx, gy, gz, ax, ay, az] since the last frame
        self.slam = None
        self.lost = False
        self.stamps = []
        self.events = []
        self.folder = tempfile.mkdtemp(prefix="orbslam3-", dir=os.getcwd())

    def start(self, frame):
        path = os.path.join(self.folder, "settings.yaml")
        with open(path, "w") as f:
            f.write(
                settings_yaml(
                    self.params, frame.width, frame.height, frame.intrinsics, self.fps, self.lens
                )
            )
            if self.params["inertial"]:
                f.write(imu_yaml(self.imu, np.linalg.inv(mounting(self.imu)) @ self.base_from_camera))
        sensor = pyorbslam3.Sensor.IMU_RGBD if self.params["inertial"] else pyorbslam3.Sensor.RGBD
        self.slam = pyorbslam3.Slam(self.vocabulary, path, sensor)

    def on_imu(self, imu):
        if self.params["inertial"]:
            self.samples.append((imu.stamp_ns * 1e-9, *imu.gyro, *imu.accel))

    def on_rgbd(self, frame):
        if self.slam is None:
            self.start(frame)
        # ORB-SLAM3 takes the images as they are (RGB order, Camera.RGB = 1; depth in metres).
        if self.params["inertial"]:
            imu = np.array(self.samples, dtype=np.float64).reshape(-1, 7)
            self.samples = []
            result = self.slam.track_rgbd(frame.rgb, frame.depth, frame.stamp_ns * 1e-9, imu=imu)
        else:
            result = self.slam.track_rgbd(frame.rgb, frame.depth, frame.stamp_ns * 1e-9)
        self.stamps.append(frame.stamp_ns)
        state = result.state
        lost = state in (pyorbslam3.TrackingState.LOST, pyorbslam3.TrackingState.RECENTLY_LOST)
        if lost != self.lost and len(self.stamps) > 1:
            kind = "tracking_lost" if lost else "tracking_recovered"
            self.events.append({"stamp_ns": frame.stamp_ns, "kind": kind, "detail": f"ORB-SLAM3 state {state.name}"})
        self.lost = lost
        if self.slam.map_changed():
            self.events.append(
                {
                    "stamp_ns": frame.stamp_ns,
                    "kind": "loop_closure_accepted",
                    "detail": "ORB-SLAM3 map changed (a loop closure, a map merge or a global BA)",
                }
            )
        if not result.pose_valid:
            return None
        return frame.stamp_ns, self.base_pose(np.asarray(result.pose_wc, dtype=np.float64))

    def finish(self):
        if self.slam is None:
            return {"trajectory": [], "events": self.events}
        self.slam.shutdown()
        path = os.path.join(self.folder, "CameraTrajectory.txt")
        self.slam.save_trajectory_tum(path)
        by_second = {round(s * 1e-9, 6): s for s in self.stamps}
        trajectory = []
        with open(path) as f:
            for line in f:
                v = line.split()
                if len(v) != 8 or line.startswith("#"):
                    continue
                t = float(v[0])
                stamp = by_second.get(round(t, 6))
                if stamp is None:
                    stamp = int(round(t * 1e9))
                if trajectory and stamp <= trajectory[-1][0]:
                    # While tracking is lost, ORB-SLAM3 repeats the last tracked frame's
                    # time and relative pose for every frame it cannot place; those lines
                    # are no estimate of their own.
                    continue
                pose = self.base_pose(isometry([float(x) for x in v[1:4]], [float(x) for x in v[4:8]]))
                trajectory.append((stamp, pose))
        return {"trajectory": trajectory, "events": self.events}
