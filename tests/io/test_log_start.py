"""Opening a log that defines its own types, its overview and its poses need neither rosbags'
standard typestore (~65 ms of imports: io/typestore.py LazyTypestore) nor its deserialiser
for the poses (io/pose_msg.py)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from mrnc_eval.io.typestore import LazyTypestore, typestore_for

SAMPLES = Path(__file__).resolve().parents[2] / "sample_logs"
_PROBE = """
import sys
from mrnc_eval.io import open_log
from rosbags.typesys.store import Typestore
decoded = []
real = Typestore.deserialize_cdr
Typestore.deserialize_cdr = lambda self, raw, typ: decoded.append(typ) or real(self, raw, typ)
with open_log(sys.argv[1]) as lg:
    assert lg.topics
    assert lg.ground_truth().stamps.size > 100
    assert lg.wheel_odometry().stamps.size > 100
print(sorted(m for m in sys.modules if m.startswith("rosbags.typesys.stores.")))
print(sorted(set(decoded)))
"""


def test_sample_mcap_opens_without_the_standard_store_or_pose_deserialiser() -> None:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)}
    out = subprocess.run([sys.executable, "-c", _PROBE, str(SAMPLES / "circle_soft_ground.mcap")], env=env,
                         capture_output=True, text=True, check=True).stdout.splitlines()
    assert "rosbags.typesys.stores.ros2_humble" not in out[0]
    assert "nav_msgs/msg/Odometry" not in out[1]


def test_lazy_typestore_is_the_standard_one_when_read() -> None:
    lazy = LazyTypestore(ros1=True)
    assert lazy._store is None
    assert lazy.fielddefs == typestore_for(ros1=True).fielddefs
