"""Geometry kernel below `slam/`, `io/` and `evaluation/`: SE(3)/SO(3) on pose stacks
(`lie`), the SLAM's single-pose helpers (`se3`) and resampling trajectories at stamps
(`interpolate`). Pure numpy/scipy; imports only the base modules (`data`, `errors`)."""
