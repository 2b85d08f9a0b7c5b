"""Property-based fuzzing of the decoders at the reader boundary (issue 15): PointCloud2,
Imu and NavSatFix. Whatever the bytes or values, the result is either valid data (finite,
unit quaternions, plausible coordinates) or the reader's one typed error; never a NaN
passed on, never another exception."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from types import SimpleNamespace
from typing import Any, TypeVar

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mrnc_eval.data import ImuSeries
from mrnc_eval.errors import InputError
from mrnc_eval.io import open_log
from mrnc_eval.io.fast_imu import decode_imu_batch
from mrnc_eval.io.pointcloud import CloudFormatError, decode_cloud
from mrnc_eval.io.validate import ValidationConfig
from mrnc_eval.io.writers import LogWriter

T = TypeVar("T")

FUZZ = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
SLOW_FUZZ = settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
LIMITS = ValidationConfig()

wild = st.floats(allow_nan=True, allow_infinity=True, width=64)
point_fields = st.lists(
    st.builds(SimpleNamespace, name=st.sampled_from(["x", "y", "z", "t", "time", "timestamp", "ring", "intensity",
                                                     "reflectivity", "range"]),
              offset=st.integers(0, 40), datatype=st.integers(0, 9), count=st.integers(0, 2)),
    min_size=0, max_size=8)


@FUZZ
@given(fields=point_fields, step=st.integers(0, 48), height=st.integers(0, 3), width=st.integers(0, 5),
       row_step=st.integers(0, 200), big=st.booleans(), data=st.binary(max_size=400))
def test_pointcloud2_decodes_to_valid_points_or_a_format_error(fields, step, height, width, row_step, big,
                                                                data) -> None:
    msg = SimpleNamespace(fields=fields, height=height, width=width, point_step=step, row_step=row_step,
                          is_bigendian=big, data=np.frombuffer(data, dtype=np.uint8),
                          header=SimpleNamespace(frame_id="os_sensor"))
    try:
        sweep = decode_cloud(msg, 100.0)
    except CloudFormatError:
        return
    assert np.isfinite(sweep.points).all()
    assert (np.abs(sweep.points).sum(axis=1) > 0).all()  # no-return points removed
    assert sweep.point_time is None or sweep.point_time.shape[0] == sweep.points.shape[0]


@FUZZ
@given(raws=st.lists(st.binary(min_size=0, max_size=400), min_size=1, max_size=4), ros1=st.booleans())
def test_fast_imu_decoding_of_any_bytes_gives_a_batch_or_none(raws: list[bytes], ros1: bool) -> None:
    batch = decode_imu_batch(raws, ros1)
    if batch is not None:
        assert batch.acc.shape == (len(raws), 3)
        assert batch.orientation.shape == (len(raws), 4)


def _vectors(n: int, k: int) -> st.SearchStrategy[np.ndarray]:
    plain = st.floats(-50.0, 50.0)
    return st.lists(st.lists(st.one_of(plain, plain, plain, wild), min_size=k, max_size=k), min_size=n,
                    max_size=n).map(lambda v: np.asarray(v, float))


def _read_or_refused(path: Path, topic: str, read: Callable[[Any], T]) -> T | None:
    """The stream as `read` returns it from the log, or None when the reader refused it, naming `topic`."""
    try:
        with open_log(path) as lg:
            return read(lg)
    except InputError as err:
        refused_topic = err.topic
        assert refused_topic == topic
        return None


@st.composite
def imu_streams(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    n = draw(st.integers(5, 40))
    quat = draw(st.one_of(st.none(), _vectors(n, 4)))
    return draw(_vectors(n, 3)), draw(_vectors(n, 3)), quat


@SLOW_FUZZ
@given(stream=imu_streams())
def test_imu_stream_is_valid_or_refused(tmp_path: Path, stream) -> None:
    acc, gyro, quat = stream
    n = acc.shape[0]
    path = tmp_path / "imu.mcap"
    path.unlink(missing_ok=True)
    with LogWriter(path, "mcap") as w:
        w.write_imu("/imu", ImuSeries(1.0 + np.arange(n) / 100.0, acc, gyro, quat, frame_id="imu"))
    imu = _read_or_refused(path, "/imu", lambda lg: lg.imu())
    if imu is None:
        return
    assert np.isfinite(imu.acc).all()
    assert np.isfinite(imu.gyro).all()
    assert (np.abs(imu.acc) <= LIMITS.max_abs_acceleration_mps2).all()
    assert (np.abs(imu.gyro) <= LIMITS.max_abs_angular_rate_rad_s).all()
    if imu.orientation_xyzw is not None:
        np.testing.assert_allclose(np.linalg.norm(imu.orientation_xyzw, axis=1), 1.0, atol=1e-9)
    dropped = n - imu.stamps.size
    assert dropped <= LIMITS.max_bad_fraction * n


@st.composite
def fixes(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray]:
    n = draw(st.integers(3, 30))
    coordinate = st.one_of(st.floats(-95.0, 95.0), st.floats(-200.0, 200.0), st.floats(-1e4, 1e4), wild)
    lla = draw(st.lists(st.tuples(coordinate, coordinate, coordinate), min_size=n, max_size=n))
    status = draw(st.lists(st.integers(-1, 2), min_size=n, max_size=n))
    return np.asarray(lla, float), np.asarray(status, int)


@SLOW_FUZZ
@given(data=fixes())
def test_navsatfix_stream_is_valid_or_refused(tmp_path: Path, data) -> None:
    lla, status = data
    n = lla.shape[0]
    path = tmp_path / "gnss.mcap"
    path.unlink(missing_ok=True)
    with LogWriter(path, "mcap") as w:
        w.write_navsatfix("/fix", 1.0 + np.arange(n) * 0.2, lla, np.tile(np.eye(3).ravel(), (n, 1)), status)
    g = _read_or_refused(path, "/fix", lambda lg: lg.gnss())
    if g is None:
        return
    assert (np.abs(g.lla[:, 0]) <= 90).all()
    assert (np.abs(g.lla[:, 1]) <= 180).all()
    assert np.isfinite(g.enu).all()
