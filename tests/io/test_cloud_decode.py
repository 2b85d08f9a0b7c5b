"""The sweep stream's fast paths give what the slow ones give: io/_cloud.c's gather the arrays of
numpy's decode, io/cloud_msg.py's parse the fields of rosbags' deserialiser, io/mcap_stream.py the
messages of the library's read (and its errors on a damaged chunk)."""

from __future__ import annotations

import struct
import tracemalloc
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

from mrnc_eval.errors import InputError
from mrnc_eval.io import messages as M
from mrnc_eval.io import open_log, pointcloud
from mrnc_eval.io.cloud_msg import CloudMessage, Field, Header, Stamp, parse_cloud
from mrnc_eval.io.typestore import typestore_for
from tests.c_build import build_extension
from tests.io.test_mcap_index import CLOUD_STAMPS, _multi_chunk_log

SOURCE = Path(pointcloud.__file__).with_name("_cloud.c")
ARRAYS = ("points", "point_time", "ring", "column", "intensity", "reflectivity")


@pytest.fixture(scope="module")
def cloud_c(tmp_path_factory: pytest.TempPathFactory) -> ModuleType:
    """io/_cloud.c built from the source under test (as setup.py builds it)."""
    return build_extension(SOURCE, "mrnc_eval.io._cloud", tmp_path_factory.mktemp("cloud"),
                           ("-O3", "-march=native", "-ffp-contract=off"))


# (name, datatype) of each layout's fields after x, y, z (float32 at 0, 4, 8)
LAYOUTS = {
    "ouster": [("intensity", 7), ("t", 6), ("reflectivity", 4), ("ring", 4)],
    "velodyne": [("intensity", 7), ("ring", 4), ("time", 7)],
    "ring_u8_intensity_u16": [("ring", 2), ("intensity", 4), ("t", 6)],
    "intensity_f64_no_ring": [("intensity", 8), ("reflectivity", 2)],
    "no_time": [("ring", 4)],
    "timestamp_numpy_only": [("timestamp", 8), ("ring", 4)],
}


def _cloud(layout: str, height: int, width: int, pad: int, rng: np.random.Generator) -> CloudMessage:
    """A random cloud: some no-returns (zeros, NaN, inf), large and negative values, padded rows."""
    sizes = {1: 1, 2: 1, 3: 2, 4: 2, 5: 4, 6: 4, 7: 4, 8: 8}
    fields, offset = [Field(name=c, offset=4 * k, datatype=7, count=1) for k, c in enumerate("xyz")], 12
    for name, datatype in LAYOUTS[layout]:
        fields.append(Field(name=name, offset=offset, datatype=datatype, count=1))
        offset += sizes[datatype]
    step = offset + 3  # unaligned fields after an odd gap
    n = height * width
    recs = rng.integers(0, 256, size=(n, step), dtype=np.uint8)  # every field random bits...
    xyz = rng.normal(scale=30.0, size=(n, 3)).astype(np.float32)
    xyz[rng.random(n) < 0.2] = 0.0
    xyz[rng.random(n) < 0.02, 1] = np.nan
    xyz[rng.random(n) < 0.02, 2] = np.inf
    xyz[rng.random(n) < 0.02] = np.float32(3e38)  # finite, but |x| + |y| overflows: a no-return in float32
    recs[:, :12] = xyz.view(np.uint8).reshape(n, 12)  # ...but x, y, z
    for f in fields:
        if f.name in ("t", "timestamp", "time"):
            vals = {6: rng.integers(0, 100_000_000, n).astype("<u4"), 7: rng.random(n).astype("<f4") * 0.1,
                    8: 1.7e9 + rng.random(n) * 0.1}[f.datatype]
            recs[:, f.offset:f.offset + sizes[f.datatype]] = np.asarray(vals).view(np.uint8).reshape(n, -1)
    raw = rng.integers(0, 256, size=(height, width * step + pad), dtype=np.uint8)  # the rows' padding random too
    raw[:, :width * step] = recs.reshape(height, width * step)
    return CloudMessage(header=Header(stamp=Stamp(sec=1_700_000_000, nanosec=5), frame_id="os_sensor"),
                        height=height, width=width, fields=fields, is_bigendian=False, point_step=step,
                        row_step=width * step + pad, data=raw.reshape(-1), is_dense=False)


def _arrays(cloud: CloudMessage) -> dict[str, Any]:
    with np.errstate(all="ignore"):  # random bits: casts overflow, NaNs add up (numpy warns, C does not)
        sweep = pointcloud.decode_cloud(cloud, 1_700_000_000.0)
    return {name: getattr(sweep, name) for name in ARRAYS}


def _same_bits(a: dict[str, Any], b: dict[str, Any]) -> bool:
    for name in ARRAYS:
        x, y = a[name], b[name]
        if (x is None) != (y is None):
            return False
        if x is not None and (x.dtype != y.dtype or x.shape != y.shape or not x.flags.c_contiguous
                              or x.tobytes() != y.tobytes()):
            return False
    return True


@pytest.mark.parametrize("layout", sorted(LAYOUTS))
@pytest.mark.parametrize(("height", "width", "pad"), [(16, 64, 0), (16, 64, 7), (1, 500, 0)])
def test_c_gather_gives_numpys_arrays(cloud_c: ModuleType, monkeypatch: pytest.MonkeyPatch, layout: str,
                                      height: int, width: int, pad: int) -> None:
    cloud = _cloud(layout, height, width, pad, np.random.default_rng([sorted(LAYOUTS).index(layout), height, pad]))
    monkeypatch.setattr(pointcloud, "_gather_c", None)
    by_numpy = _arrays(cloud)
    calls: list[int] = []
    monkeypatch.setattr(pointcloud, "_gather_c", lambda *a: calls.append(1) or cloud_c.gather(*a))
    by_c = _arrays(cloud)
    assert len(calls) == (0 if layout == "timestamp_numpy_only" else 1)  # the C path ran where it applies
    assert height * width * 0.6 < len(by_c["points"]) < height * width * 0.9  # ~25 % no-returns dropped
    assert _same_bits(by_c, by_numpy)
    # negative control: the comparison sees one flipped bit of one kept point's intensity or time
    key = "intensity" if by_c["intensity"] is not None else "points"
    changed = {**by_c, key: by_c[key].copy()}
    changed[key].view(np.uint8)[0] ^= 1
    assert not _same_bits(changed, by_numpy)


def test_c_gather_refuses_outputs_that_do_not_fit(cloud_c: ModuleType) -> None:
    data = np.zeros(10 * 16, np.uint8)
    points = np.empty((10, 3), np.float32)
    with pytest.raises(ValueError, match="does not fit"):
        cloud_c.gather(data, (1, 10, 16, 160), (0, 4, 8), points, ((0, 14, 7, np.empty(10, np.float32)),))
    with pytest.raises(ValueError, match="do not add up"):
        cloud_c.gather(data[:-1], (1, 10, 16, 160), (0, 4, 8), points, ())
    with pytest.raises(ValueError, match="does not fit"):
        cloud_c.gather(data, (1, 10, 16, 160), (0, 4, 8), points, ((0, 12, 7, np.empty(9, np.float32)),))
    # sizes whose products overflow 64 bits (they once wrapped to pass the checks: a crash)
    big = 1 << 32
    with pytest.raises(ValueError, match="do not add up"):
        cloud_c.gather(data, (big, big, 4, 1 << 34), (0, 0, 0), points, ())
    with pytest.raises(ValueError, match="does not fit"):  # an offset near the largest size
        cloud_c.gather(data, (1, 10, 16, 160), (0, 4, 8), points, ((0, (1 << 63) - 2, 7, np.empty(10, np.float32)),))


@pytest.mark.parametrize("ros1", [False, True])
def test_parse_cloud_equals_rosbags(ros1: bool) -> None:
    ts = typestore_for(ros1=ros1)
    rng = np.random.default_rng(5)
    h, w = 8, 32
    msg = M.ouster_cloud(ts, 1234.5678, "os_sénsor", rng.normal(size=(h, w, 3)), np.zeros((h, w), np.uint32),
                         np.ones((h, w), np.uint32), np.ones((h, w), np.uint16), rng.random((h, w)),
                         np.ones((h, w), np.uint16), ros1=ros1, seq=7)
    raw = bytes(ts.serialize_ros1(msg, "sensor_msgs/msg/PointCloud2") if ros1 else
                ts.serialize_cdr(msg, "sensor_msgs/msg/PointCloud2"))
    parsed = parse_cloud(memoryview(raw), ros1=ros1)
    ref = ts.deserialize_ros1(raw, "sensor_msgs/msg/PointCloud2") if ros1 else \
        ts.deserialize_cdr(raw, "sensor_msgs/msg/PointCloud2")
    assert parsed is not None
    assert (parsed.header.stamp.sec, parsed.header.stamp.nanosec, parsed.header.frame_id) == \
        (ref.header.stamp.sec, ref.header.stamp.nanosec, ref.header.frame_id)
    assert (parsed.height, parsed.width, parsed.is_bigendian, parsed.point_step, parsed.row_step, parsed.is_dense) \
        == (ref.height, ref.width, ref.is_bigendian, ref.point_step, ref.row_step, ref.is_dense)
    assert [(f.name, f.offset, f.datatype, f.count) for f in parsed.fields] == \
        [(f.name, f.offset, f.datatype, f.count) for f in ref.fields]
    assert parsed.data.tobytes() == np.asarray(ref.data).tobytes()
    # what it does not read (cut short, one byte too many, big-endian CDR, a bad string) goes to the library
    assert parse_cloud(raw[:-1], ros1=ros1) is None
    assert parse_cloud(raw + b"\0" * (1 if ros1 else 4), ros1=ros1) is None
    if not ros1:
        assert parse_cloud(b"\0\0" + raw[2:], ros1=False) is None
    bad = bytearray(raw)
    struct.pack_into("<I", bad, 12, 10**6)  # frame_id's length (after the stamp) beyond the message
    assert parse_cloud(bytes(bad), ros1=ros1) is None


def test_parse_cloud_never_raises_on_damaged_bytes() -> None:
    ts = typestore_for(ros1=False)
    msg = M.ouster_cloud(ts, 1.0, "os", np.ones((2, 4, 3)), np.zeros((2, 4), np.uint32), np.ones((2, 4)),
                         np.ones((2, 4)), np.ones((2, 4)), np.ones((2, 4)), ros1=False)
    raw = bytes(ts.serialize_cdr(msg, "sensor_msgs/msg/PointCloud2"))
    rng = np.random.default_rng(0)
    for _ in range(300):
        bad = bytearray(raw[:int(rng.integers(0, len(raw) + 1))])
        for pos in rng.integers(0, max(len(bad), 1), 3):
            if bad:
                bad[int(pos)] = int(rng.integers(0, 256))
        parse_cloud(bytes(bad), ros1=bool(rng.integers(0, 2)))  # a message or None, never an exception


def _streams(path: Path) -> tuple[list[tuple[int, bytes]], list[tuple[int, bytes]], bool]:
    """The clouds' (time, bytes) through io/mcap_stream.py and through the library, and whether the
    direct read was planned."""
    from mrnc_eval.io.chunk_prefix import IndexUnusable
    from mrnc_eval.io.mcap_stream import TopicStream

    try:
        TopicStream(path, "/ouster/points").close()
        planned = True
    except IndexUnusable:
        planned = False
    with open_log(path) as lg:
        fast = [(t, bytes(raw)) for t, raw in lg.source.stream("/ouster/points")]
        slow = [(t, bytes(raw)) for t, raw in lg.source.raw("/ouster/points")]
    return fast, slow, planned


def test_mcap_stream_gives_the_librarys_messages(tmp_path: Path) -> None:
    _multi_chunk_log(tmp_path / "a.mcap")
    fast, slow, planned = _streams(tmp_path / "a.mcap")
    assert planned
    assert len(fast) == len(CLOUD_STAMPS)
    assert fast == slow


def test_overlapping_chunks_are_read_through_the_library(tmp_path: Path) -> None:
    from mcap.writer import CompressionType, Writer

    ts = typestore_for(ros1=False)
    path = tmp_path / "o.mcap"
    with path.open("wb") as fh:
        w = Writer(fh, chunk_size=1, compression=CompressionType.ZSTD)  # a chunk per message
        w.start(profile="ros2", library="test")
        sid = w.register_schema(name="sensor_msgs/msg/PointCloud2", encoding="ros2msg",
                                data=_pointcloud2_definition().encode())
        cid = w.register_channel(topic="/ouster/points", message_encoding="cdr", schema_id=sid)
        for k in (1, 3, 2, 4):
            msg = M.ouster_cloud(ts, float(k), "os", np.full((2, 4, 3), float(k)), np.zeros((2, 4), np.uint32),
                                 np.ones((2, 4)), np.ones((2, 4)), np.ones((2, 4)), np.ones((2, 4)), ros1=False)
            w.add_message(channel_id=cid, log_time=k * 10**9, publish_time=k * 10**9,
                          data=bytes(ts.serialize_cdr(msg, "sensor_msgs/msg/PointCloud2")))
        w.finish()
    fast, slow, planned = _streams(path)
    assert not planned  # the order would need a merge: read by the library
    assert fast == slow
    assert [t for t, _ in fast] == [1 * 10**9, 2 * 10**9, 3 * 10**9, 4 * 10**9]


def _pointcloud2_definition() -> str:
    return str(typestore_for(ros1=False).generate_msgdef("sensor_msgs/msg/PointCloud2", ros_version=2)[0])


def _chunk_offsets(path: Path) -> list[Any]:
    from mcap.reader import make_reader

    with path.open("rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None
    return sorted(summary.chunk_indexes, key=lambda ci: ci.chunk_start_offset)


def _cloud_index_entry(path: Path, ci: Any) -> int:
    """File position of the clouds' first (log time, offset) entry in a chunk's message index."""
    from mcap.reader import make_reader

    with path.open("rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None
    cloud = next(cid for cid, ch in summary.channels.items() if ch.topic == "/ouster/points")
    return int(ci.message_index_offsets[cloud]) + 15  # opcode, length, channel u16, entries' length u32


def _declare_chunk_size(data: bytearray, ci: Any, size: int) -> None:
    """Write `size` as the chunk's uncompressed size in its record and its index (CRC zeroed)."""
    struct.pack_into("<Q", data, ci.chunk_start_offset + 25, size)
    struct.pack_into("<I", data, ci.chunk_start_offset + 33, 0)
    at = data.find(struct.pack("<QQQ", ci.message_start_time, ci.message_end_time, ci.chunk_start_offset)) + 32
    at += 4 + struct.unpack_from("<I", data, at)[0] + 8  # the message index offsets, their length
    at += 4 + struct.unpack_from("<I", data, at)[0]  # the compression's name
    struct.pack_into("<Q", data, at + 8, size)  # after the compressed size


@pytest.mark.parametrize("damage", ["crc", "compressed", "message_index", "size"])
def test_damaged_chunk_is_an_input_error(tmp_path: Path, damage: str) -> None:
    path = tmp_path / "a.mcap"
    _multi_chunk_log(path)
    ci = _chunk_offsets(path)[2]
    data = bytearray(path.read_bytes())
    if damage == "crc":  # the chunk's CRC field
        data[ci.chunk_start_offset + 9 + 24] ^= 0xFF
    elif damage == "compressed":  # a byte in the middle of the compressed records
        data[ci.chunk_start_offset + ci.chunk_length // 2] ^= 0x10
    elif damage == "size":  # a chunk that claims 1 GiB: refused before anything that size is allocated
        _declare_chunk_size(data, ci, 1 << 30)
    else:  # the cloud's entry in the message index after the chunk: its offset moved by 16 bytes
        at = _cloud_index_entry(path, ci)
        struct.pack_into("<Q", data, at + 8, struct.unpack_from("<Q", data, at + 8)[0] + 16)
    path.write_bytes(bytes(data))
    tracemalloc.start()
    try:
        with open_log(path) as lg, pytest.raises(InputError) as err:
            for _ in lg.sweeps():
                pass
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 200e6  # no buffer of the declared size
    assert str(path) in str(err.value)
    assert ("disagrees with its message index" if damage == "message_index" else "damaged") in str(err.value)
