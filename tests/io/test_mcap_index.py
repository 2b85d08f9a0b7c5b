"""The overview pass of an MCAP log or a ROS 1 bag reads its indexes and decompresses only the
small topics' bytes: a SLAM-style read decompresses each cloud's chunk once (in the sweep
stream), and the overview equals what reading the whole file gives (stamps, cached messages,
counts, health)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from mrnc_eval.io import bag_index, mcap_index, open_log
from mrnc_eval.io import messages as M
from mrnc_eval.io.chunk_prefix import PREFETCH_BYTES, IndexUnusable, will_read
from mrnc_eval.io.writers import LogWriter
from tests.io.test_io_roundtrip import write_sample

CLOUD_STAMPS = [1.0, 1.1, 1.1, 1.05, 1.2, 1.3]  # header stamps in arrival order: a duplicate and a late cloud


def _multi_chunk_log(path: Path, compression: str = "lz4") -> None:
    """Clouds of 1.5 MB (each closes a 1 MiB chunk) between IMU messages, record times tied
    across topics, a duplicate and an out-of-order header stamp in both streams (MCAP or ROS 1
    by the suffix; `compression`: of the ROS 1 chunks)."""
    rng = np.random.default_rng(3)
    h, w = 64, 512
    ros1 = path.suffix == ".bag"
    w_ = LogWriter(path, "bag" if ros1 else "mcap", ros1_compression=compression)
    clouds = w_._conn("/ouster/points", "sensor_msgs/msg/PointCloud2")
    imu = w_._conn("/ouster/imu", "sensor_msgs/msg/Imu")
    for k, stamp in enumerate(CLOUD_STAMPS):
        t_rec = int((1.0 + 0.1 * k) * 1e9)
        for j in range(10):
            t_imu = 1.0 + 0.1 * k + 0.01 * j - (0.015 if j == 4 else 0.0) - (0.01 if j == 7 else 0.0)
            msg = M.imu(w_.ts, t_imu, "os_imu", (0.0, 0.0, 9.81 + j), (0.0, 0.0, 0.1), None, ros1)
            w_._writer.write(imu, t_rec + j * 10_000_000, w_._serialize(msg, "sensor_msgs/msg/Imu"))
        xyz = rng.uniform(-20, 20, (h, w, 3)).astype(np.float32)
        t_ns = np.repeat((np.arange(w, dtype=np.uint32) * 195_000)[None, :], h, axis=0)
        fields = (np.ones((h, w), np.uint32), np.ones((h, w), np.uint16), np.ones((h, w), np.float32),
                  np.ones((h, w), np.uint16))
        cloud = M.ouster_cloud(w_.ts, stamp, "os_sensor", xyz, t_ns, *fields, ros1=ros1)
        w_._writer.write(clouds, t_rec, w_._serialize(cloud, "sensor_msgs/msg/PointCloud2"))  # tied with an IMU
    w_.close()


def _overview(path: Path | str, monkeypatch: pytest.MonkeyPatch, *, indexed: bool) -> dict[str, Any]:
    """What the overview pass leaves behind, read from the indexes or (indexed=False) from the whole file."""
    used: list[int] = []
    ros1 = str(path).endswith(".bag")

    def counted(*args: Any, real: Any = bag_index.overview if ros1 else mcap_index.overview, **kwargs: Any) -> Any:
        if not indexed:
            raise IndexUnusable("disabled by the test")
        used.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr("mrnc_eval.io.bag_index.overview" if ros1 else "mrnc_eval.io.overview.mcap_overview", counted)
    with open_log(path) as lg:
        out = {"topics": lg.topics, "stamps": {t: lg.stamps(t) for t in lg.topic_types()},
               "cache": lg.source.cache, "health": lg.health_notes(), "imu": lg.imu().stamps}
    assert bool(used) == indexed
    return out


def _same(a: dict[str, Any], b: dict[str, Any]) -> None:
    assert a["topics"] == b["topics"]
    assert a["cache"] == b["cache"]
    assert a["health"] == b["health"]
    np.testing.assert_array_equal(a["imu"], b["imu"])
    assert a["stamps"].keys() == b["stamps"].keys()
    for topic in a["stamps"]:
        np.testing.assert_array_equal(a["stamps"][topic], b["stamps"][topic])


@pytest.mark.parametrize("suffix", [".mcap", ".bag"])
@pytest.mark.parametrize("case", ["multi_chunk", "sample", "split"])
def test_indexed_overview_equals_reading_the_whole_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                         case: str, suffix: str) -> None:
    fmt = suffix.lstrip(".")
    a, b = tmp_path / f"a{suffix}", tmp_path / f"b{suffix}"
    if case == "multi_chunk":
        _multi_chunk_log(a)
        log: str | Path = a
    elif case == "sample":
        write_sample(a, fmt, duplicate_imu=True)
        log = a
    else:
        _multi_chunk_log(a)
        write_sample(b, fmt)
        log = f"{a},{b}"
    fast = _overview(log, monkeypatch, indexed=True)
    _same(fast, _overview(log, monkeypatch, indexed=False))
    if case == "multi_chunk":  # the stream's defects are still seen
        points = next(t for t in fast["topics"] if t.topic == "/ouster/points")
        assert (points.count, points.duplicates, points.out_of_order) == (6, 1, 1)
        imu = next(t for t in fast["topics"] if t.topic == "/ouster/imu")
        assert imu.out_of_order > 0


def _sweep_read(path: Path) -> None:
    """What `slam` reads: topics, the IMU, then the sweeps."""
    with open_log(path) as lg:
        assert lg.topics
        assert lg.imu().stamps.size == 9 * len(CLOUD_STAMPS)  # one duplicate a cloud dropped
        swept = [s.stamp for s in lg.sweeps()]
    assert swept == pytest.approx([1.0, 1.1, 1.2, 1.3])


def test_slam_read_decompresses_each_mcap_chunk_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Every chunk holds a cloud, and each is decompressed in full once, by the sweep stream
    (io/mcap_stream.py; the overview used to decompress them all too), never by the library."""
    from mcap.reader import make_reader
    from rosbags.rosbag2 import storage_mcap

    from mrnc_eval.io import mcap_stream

    _multi_chunk_log(tmp_path / "a.mcap")
    with (tmp_path / "a.mcap").open("rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None
    assert len(summary.chunk_indexes) == len(CLOUD_STAMPS)  # the log is what the test means: one cloud a chunk
    decompressed: list[int] = []
    by_library: list[int] = []
    real, real_library = mcap_stream._decompress, storage_mcap.DECOMPRESSORS["zstd"]

    def counting(source: Any, chunk: Any, plain: Any) -> Any:
        decompressed.append(chunk.size)
        return real(source, chunk, plain)

    def counting_library(data: bytes, size: int) -> bytes:
        by_library.append(size)
        return real_library(data, size)

    monkeypatch.setattr(mcap_stream, "_decompress", counting)
    monkeypatch.setitem(storage_mcap.DECOMPRESSORS, "zstd", counting_library)
    _sweep_read(tmp_path / "a.mcap")
    assert len(decompressed) == len(CLOUD_STAMPS)
    assert sorted(decompressed) == sorted(ci.uncompressed_size for ci in summary.chunk_indexes)
    assert not by_library


@pytest.mark.parametrize("compression", ["lz4", "bz2"])
def test_slam_read_decompresses_each_bag_chunk_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                    compression: str) -> None:
    from rosbags.rosbag1 import reader as bag_reader

    _multi_chunk_log(tmp_path / "a.bag", compression)
    decompressed: list[int] = []
    real = bag_reader.decompressors[compression]

    def counting(data: bytes) -> bytes:
        decompressed.append(len(data))
        return real(data)

    monkeypatch.setitem(bag_reader.decompressors, compression, counting)
    with open_log(tmp_path / "a.bag") as lg:
        n_chunks = len(lg.source.src._reader.readers[0].chunks)  # type: ignore[union-attr]
    assert n_chunks == len(CLOUD_STAMPS)  # one cloud a chunk (the chunk of the last one also ends the bag)
    decompressed.clear()
    _sweep_read(tmp_path / "a.bag")
    assert len(decompressed) == n_chunks


def test_unchunked_mcap_is_read_in_full(tmp_path: Path) -> None:
    """No chunk index: the overview reads the file itself and gives what a chunked copy gives."""
    from mcap.writer import Writer

    infos = {}
    for chunked in (True, False):
        p = tmp_path / f"c{chunked}.mcap"
        with p.open("wb") as fh:
            w = Writer(fh, use_chunking=chunked)
            w.start(profile="", library="test")
            sid = w.register_schema(name="Note", encoding="jsonschema", data=b"{}")
            cid = w.register_channel(topic="/notes", message_encoding="json", schema_id=sid)
            for k in (3, 1, 2, 2):
                w.add_message(channel_id=cid, log_time=k, publish_time=k, data=b"{}")
            w.finish()
        with open_log(p) as lg:
            infos[chunked] = (lg.topics, lg.stamps("/notes"))
    assert infos[True][0] == infos[False][0]
    np.testing.assert_array_equal(infos[True][1], infos[False][1])
    np.testing.assert_array_equal(infos[True][1], np.array([1, 2, 2, 3]) * 1e-9)


def _corrupt_first_index_entry(path: Path, field: int, value: int) -> None:
    """Set the first message index entry of the first chunk: field 0 its log time, 1 its offset."""
    from mcap.reader import make_reader

    with path.open("rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None
    ci = min(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    at = min(ci.message_index_offsets.values()) + 9 + 2 + 4 + 8 * field  # opcode, length, channel, array length
    data = bytearray(path.read_bytes())
    data[at:at + 8] = value.to_bytes(8, "little")
    path.write_bytes(bytes(data))


@pytest.mark.parametrize(("field", "problem"), [(1, "points at another record"), (0, "outside its chunk")])
def test_mcap_index_that_disagrees_is_not_used(tmp_path: Path, field: int, problem: str) -> None:
    """A message index entry pointing between records, or at a time outside its chunk: the
    index pass refuses the file (IndexUnusable) and the overview is the full read's."""
    good, bad = tmp_path / "good.mcap", tmp_path / "bad.mcap"
    _multi_chunk_log(good)
    bad.write_bytes(good.read_bytes())
    _corrupt_first_index_entry(bad, field, 5 if field else 2**62)
    wants = {"/ouster/imu": -1, "/ouster/points": 12}
    assert mcap_index.overview(good, wants, 10**9).topic.size == len(CLOUD_STAMPS) * 11
    with pytest.raises(IndexUnusable, match=problem):
        mcap_index.overview(bad, wants, 10**9)
    with open_log(good) as a, open_log(bad) as b:
        assert a.topics == b.topics
        for topic in a.topic_types():
            np.testing.assert_array_equal(a.stamps(topic), b.stamps(topic))


def test_mcap_header_too_short_names_file_and_topic(tmp_path: Path) -> None:
    """An IMU message too short for its header stamp: the index pass leaves it to the full read,
    which names the file, the topic and the problem."""
    from mrnc_eval.errors import InputError

    path = tmp_path / "short.mcap"
    w_ = LogWriter(path, "mcap")
    imu = w_._conn("/imu", "sensor_msgs/msg/Imu")
    raw = w_._serialize(M.imu(w_.ts, 1.0, "imu", (0.0, 0.0, 9.81), (0.0, 0.0, 0.0), None, False), "sensor_msgs/msg/Imu")
    w_._writer.write(imu, 1_000_000_000, raw)
    w_._writer.write(imu, 1_010_000_000, bytes(raw)[:10])
    w_.close()
    with pytest.raises(InputError, match="too short for a header") as err, open_log(path) as lg:
        _ = lg.topics
    assert "/imu" in str(err.value)
    assert "short.mcap" in str(err.value)


def test_first_message_is_the_full_reads_first(tmp_path: Path) -> None:
    """io/mcap_index.first_message gives each topic's first message as the library's read does
    (record times tied across topics and chunks, a late IMU message), None for an empty topic."""
    _multi_chunk_log(tmp_path / "a.mcap")
    write_sample(tmp_path / "b.mcap", "mcap", duplicate_imu=True)
    for path in (tmp_path / "a.mcap", tmp_path / "b.mcap"):
        with open_log(path) as lg:
            for topic in lg.topic_types():
                want = next((bytes(raw) for _topic, _t, raw in lg.source.iterate([topic])), None)
                assert mcap_index.first_message(path, topic) == want, topic
                assert lg.source.first_raw(topic) == want, topic
            assert mcap_index.first_message(path, "/not/there") is None


def test_overview_in_batches_and_over_budget(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Chunks read one batch each (bounded memory) give what one batch gives; whole messages over
    the budget are all dropped (counted, none held), their heads still read."""
    _multi_chunk_log(tmp_path / "a.mcap")
    whole = _overview(tmp_path / "a.mcap", monkeypatch, indexed=True)
    monkeypatch.setattr(mcap_index, "_BATCH_BYTES", 1)
    _same(whole, _overview(tmp_path / "a.mcap", monkeypatch, indexed=True))
    wants = {"/ouster/imu": -1, "/ouster/points": 12}
    full = mcap_index.overview(tmp_path / "a.mcap", wants, 10**9)
    tight = mcap_index.overview(tmp_path / "a.mcap", wants, full.kept - 1)
    assert not full.dropped
    assert all(d is not None for d, t in zip(full.data, full.topic, strict=True) if full.topics[t] == "/ouster/imu")
    assert tight.dropped
    assert all(d is None for d in tight.data)
    np.testing.assert_array_equal(tight.head, full.head)
    np.testing.assert_array_equal(tight.log_time, full.log_time)


def test_two_zstd_chunk_prefixes_read_in_turn_give_their_own_bytes(tmp_path: Path) -> None:
    """Each prefix has a zstd context of its own: decompressobjs of one shared context share its
    state, and two chunks read in turn (or from two threads) then corrupt each other."""
    import os

    import zstandard

    from mrnc_eval.io.chunk_prefix import ChunkPrefix

    plain = [os.urandom(200_000) + bytes([65 + k]) * 300_000 for k in range(2)]
    packed = [zstandard.ZstdCompressor(level=3).compress(p) for p in plain]
    path = tmp_path / "chunks.bin"
    path.write_bytes(packed[0] + packed[1])
    with path.open("rb") as fh:
        prefixes = [ChunkPrefix(fh, 0, len(packed[0]), len(plain[0]), "zstd"),
                    ChunkPrefix(fh, len(packed[0]), len(packed[1]), len(plain[1]), "zstd")]
        for n in range(20_000, 500_001, 20_000):  # each a little further, in turn
            for prefix in prefixes:
                prefix.ensure(n)
        assert [bytes(p.ensure(500_000)[:500_000]) for p in prefixes] == plain


def test_overview_tells_the_kernel_every_range_it_reads_first(tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                                              ) -> None:
    """From a cold page cache the overview's reads (each chunk's head and message index) are queued
    together: each range it reads is advised (POSIX_FADV_WILLNEED) before the first is read."""
    import os

    if not hasattr(os, "posix_fadvise"):
        pytest.skip("no posix_fadvise on this platform")
    path = tmp_path / "multi.mcap"
    _multi_chunk_log(path)
    events: list[tuple[str, int, int]] = []
    real_advise, real_index = os.posix_fadvise, mcap_index._index_records

    def advise(fd: int, offset: int, length: int, advice: int) -> None:
        assert advice == os.POSIX_FADV_WILLNEED
        events.append(("advise", offset, length))
        real_advise(fd, offset, length, advice)

    def index_records(fh: Any, ci: Any, topics: Any) -> Any:
        events.append(("read", ci.chunk_start_offset + ci.chunk_length, ci.message_index_length))
        return real_index(fh, ci, topics)

    monkeypatch.setattr(os, "posix_fadvise", advise)
    monkeypatch.setattr(mcap_index, "_index_records", index_records)
    with path.open("rb") as fh:
        chunks, topics = mcap_index.chunk_indexes(fh)
    mcap_index.overview(path, {t: mcap_index.HEAD for t in topics.values()}, 1 << 30)
    reads = [e[1:] for e in events if e[0] == "read"]
    first_read = next(k for k, e in enumerate(events) if e[0] == "read")
    advised = {e[1:] for e in events[:first_read]}
    assert len(reads) == len(chunks) > 3
    assert set(reads) <= advised
    assert {(ci.chunk_start_offset, PREFETCH_BYTES) for ci in chunks} <= advised


def test_advice_on_something_that_is_not_a_file_is_ignored() -> None:
    import io

    will_read(io.BytesIO(b"x" * 100), [(0, 10)])  # no fileno: nothing happens, nothing raised


def test_an_open_mcap_log_reads_its_summary_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The opening, the roles, the overview and the sweep stream share one read of the file's
    summary (a ROS 2 MCAP file: the one it is opened from, io/ros2_mcap.py)."""
    from mrnc_eval.io import log_source, mcap_stream

    path = tmp_path / "multi.mcap"
    _multi_chunk_log(path)
    calls: list[str] = []
    real, real_summary = mcap_index.chunk_indexes, log_source.read_summary

    def counted(fh: Any) -> Any:
        calls.append("chunk_indexes")
        return real(fh)

    def counted_summary(p: Path) -> Any:
        calls.append("read_summary")
        return real_summary(p)

    monkeypatch.setattr(mcap_index, "chunk_indexes", counted)
    monkeypatch.setattr(mcap_stream, "chunk_indexes", counted)
    monkeypatch.setattr(log_source, "read_summary", counted_summary)
    with open_log(path) as lg:
        assert lg.source.first_raw("/ouster/imu") is not None
        assert lg.duration_s > 0
        assert len(list(lg.sweeps())) == len(CLOUD_STAMPS) - 2  # the duplicate and the late cloud skipped
    assert len(calls) == 1


@pytest.mark.parametrize("length", [2**62, 2**33, 91])
def test_message_index_longer_than_the_file_is_refused_before_it_is_read(tmp_path: Path, length: int) -> None:
    """A chunk index whose message index length runs past the end of the file (a crafted summary):
    IndexUnusable (the full read then reports the file), not a MemoryError from allocating it."""
    from types import SimpleNamespace

    path = tmp_path / "x.mcap"
    path.write_bytes(bytes(100))
    with path.open("rb") as fh:
        with pytest.raises(IndexUnusable, match="truncated message index"):
            mcap_index.read_message_index(fh, SimpleNamespace(chunk_start_offset=10, chunk_length=0,
                                                              message_index_length=length), {})
        assert mcap_index.read_message_index(fh, SimpleNamespace(
            chunk_start_offset=10, chunk_length=0, message_index_length=90, message_start_time=0,
            message_end_time=0), {}) == []  # the same file, a length that fits: read (zero padding)


def test_chunk_compression_name_longer_than_its_index_says_is_refused_before_it_is_read(tmp_path: Path) -> None:
    """A chunk record whose compression name length (u32) disagrees with its index (a crafted 2**31):
    IndexUnusable naming the disagreement, the name never read (a read of its length would allocate it
    first). Negative control: the index's own length ("lz4", 3) goes on to the next check (the file
    ends there: truncated chunk)."""
    import struct
    from types import SimpleNamespace

    def head(name_len: int) -> Path:
        path = tmp_path / f"h{name_len}.mcap"
        path.write_bytes(b"\x06" + bytes(8) + struct.pack("<QQQII", 0, 0, 100, 0, name_len) + b"lz4")
        return path

    ci = SimpleNamespace(chunk_start_offset=0, compression="lz4", uncompressed_size=100, compressed_size=0)
    asked: list[int] = []
    with head(2**31).open("rb") as raw:
        real_read = raw.read

        def read(n: int = -1) -> bytes:
            asked.append(n)
            return real_read(n)

        fh = SimpleNamespace(seek=raw.seek, read=read, tell=raw.tell, fileno=raw.fileno)
        with pytest.raises(IndexUnusable, match="disagrees with its index"):
            mcap_index.read_chunk_head(fh, ci)  # type: ignore[arg-type]
    assert max(asked) < 100
    with head(3).open("rb") as fh3, pytest.raises(IndexUnusable, match="truncated chunk"):
        mcap_index.read_chunk_head(fh3, ci)
