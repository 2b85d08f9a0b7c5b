"""Log and trajectory readers (ROS 1 bag, ROS 2 sqlite3/MCAP, TUM/KITTI/EuRoC) and writers."""

from mrnc_eval.io.reader import LogReader, TopicInfo, open_log

__all__ = ["LogReader", "TopicInfo", "open_log"]
