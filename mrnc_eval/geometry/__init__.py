"""Geometry kernel below `slam/`, `io/` and `evaluation/`: SE(3)/SO(3) on pose stacks
(`lie`), the SLAM's single-pose helpers (`se3`), resampling trajectories at stamps
(`interpolate`) and closed-form point-set fits (`point_fit`: Umeyama, yaw). Pure numpy/scipy;
imports only the base modules (`data`, `errors`)."""
