"""LIO-SAM-style LiDAR-inertial SLAM (pure computation: arrays and dataclasses in and out)."""
