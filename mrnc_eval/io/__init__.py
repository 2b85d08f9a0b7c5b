"""Log and trajectory readers (ROS 1 bag, ROS 2 sqlite3/MCAP, plain MCAP, TUM/KITTI/EuRoC)."""
