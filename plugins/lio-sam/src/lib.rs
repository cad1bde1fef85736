//! LIO-SAM-style lidar-inertial SLAM (work in progress).
