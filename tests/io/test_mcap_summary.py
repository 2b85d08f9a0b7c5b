"""An MCAP file's header profile and summary read without the mcap library (io/mcap_summary.py)
against mcap's reader: the same schemas, channels (metadata too), statistics and chunk indexes
on the project's logs; None without a summary, as mcap says; Unreadable (mcap then reads the
file, with its own error) for a cut file, a footer pointing outside it, text that is not UTF-8."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from mrnc_eval.io import mcap_summary
from tests.io.test_io_roundtrip import write_sample

REPO = Path(__file__).resolve().parents[2]
SAMPLE = REPO / "sample_logs" / "circle_soft_ground.mcap"


def _theirs(path: Path) -> tuple[str, Any]:
    from mcap.reader import make_reader

    with path.open("rb") as fh:
        reader = make_reader(fh)
        return reader.get_header().profile, reader.get_summary()


def _same(ours: Any, theirs: Any, names: tuple[str, ...]) -> None:
    for name in names:
        assert getattr(ours, name) == getattr(theirs, name), name


def _compare(path: Path) -> int:
    profile, theirs = _theirs(path)
    assert mcap_summary.profile(path) == profile
    ours = mcap_summary.read(path)
    assert ours is not None
    assert theirs is not None
    assert list(ours.schemas) == list(theirs.schemas)
    for k, s in theirs.schemas.items():
        _same(ours.schemas[k], s, ("id", "name", "encoding", "data"))
    assert list(ours.channels) == list(theirs.channels)
    for k, c in theirs.channels.items():
        _same(ours.channels[k], c, ("id", "schema_id", "topic", "message_encoding", "metadata"))
    _same(ours.statistics, theirs.statistics, ("message_count", "schema_count", "channel_count", "attachment_count",
                                               "metadata_count", "chunk_count", "message_start_time",
                                               "message_end_time", "channel_message_counts"))
    assert len(ours.chunk_indexes) == len(theirs.chunk_indexes)
    for a, b in zip(ours.chunk_indexes, theirs.chunk_indexes, strict=True):
        _same(a, b, ("message_start_time", "message_end_time", "chunk_start_offset", "chunk_length",
                     "message_index_offsets", "message_index_length", "compression", "compressed_size",
                     "uncompressed_size"))
    return len(ours.chunk_indexes)


def test_the_sample_log_reads_as_mcaps_reader_reads_it() -> None:
    assert _compare(SAMPLE) > 10


def test_the_real_recording_reads_as_mcaps_reader_reads_it(real_ouster_mcap: Path) -> None:
    assert _compare(real_ouster_mcap) > 0


def _with_metadata(path: Path) -> None:
    """A non-ROS MCAP file with channel metadata, two schemas and no chunk compression."""
    from mcap.writer import CompressionType, Writer

    with path.open("wb") as fh:
        w = Writer(fh, compression=CompressionType.NONE)
        w.start(profile="", library="test")
        a = w.register_schema(name="A", encoding="jsonschema", data=b"{}")
        b = w.register_schema(name="B", encoding="jsonschema", data=b'{"type": "object"}')
        ca = w.register_channel(topic="/a", message_encoding="json", schema_id=a, metadata={"k": "v", "é": "x"})
        cb = w.register_channel(topic="/b", message_encoding="json", schema_id=b)
        for k in range(50):
            w.add_message(channel_id=ca if k % 3 else cb, log_time=k * 1000, publish_time=k * 1000, data=b"{}")
        w.finish()


def test_written_logs_read_as_mcaps_reader_reads_them(tmp_path: Path) -> None:
    write_sample(tmp_path / "log.mcap", "mcap")
    assert _compare(tmp_path / "log.mcap") > 0
    _with_metadata(tmp_path / "meta.mcap")
    _compare(tmp_path / "meta.mcap")
    assert mcap_summary.profile(tmp_path / "meta.mcap") == ""


def _footer_summary_start(data: bytearray) -> int:
    return len(data) - 8 - 20  # the footer's summary start: after its opcode and length


def test_no_summary_is_none_as_mcap_says(tmp_path: Path) -> None:
    data = bytearray(SAMPLE.read_bytes())
    at = _footer_summary_start(data)
    data[at:at + 8] = bytes(8)  # summary start 0: no summary
    path = tmp_path / "nosummary.mcap"
    path.write_bytes(bytes(data))
    assert _theirs(path)[1] is None
    assert mcap_summary.read(path) is None


def test_what_is_not_plainly_readable_is_left_to_mcap(tmp_path: Path) -> None:
    data = SAMPLE.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[:-10])
    outside = bytearray(data)
    at = _footer_summary_start(outside)
    outside[at:at + 8] = (len(data) + 5).to_bytes(8, "little")
    bad_topic = bytearray(data)
    topic_at = bytes(bad_topic).rindex(b"/gnss/fix")  # in the summary's channel record
    bad_topic[topic_at + 1] = 0xFF
    for name, content in (("outside.mcap", bytes(outside)), ("topic.mcap", bytes(bad_topic))):
        (tmp_path / name).write_bytes(content)
    for name in ("cut.mcap", "outside.mcap", "topic.mcap"):
        with pytest.raises(mcap_summary.Unreadable):
            mcap_summary.read(tmp_path / name)
        with pytest.raises(Exception):  # noqa: B017, PT011 - the negative control: mcap refuses each too
            _theirs(tmp_path / name)
    with pytest.raises(mcap_summary.Unreadable):
        mcap_summary.profile(_not_mcap(tmp_path))


def _not_mcap(tmp_path: Path) -> Path:
    path = tmp_path / "text.mcap"
    path.write_bytes(b"not an mcap file at all, just text")
    return path


def _peak_bytes(read: Any, path: Path) -> int:
    """Peak Python allocation of `read(path)`, which must raise Unreadable."""
    import tracemalloc

    tracemalloc.start()
    try:
        with pytest.raises(mcap_summary.Unreadable):
            read(path)
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_lengths_and_offsets_from_the_file_are_checked_before_reading(tmp_path: Path) -> None:
    """A header profile length of ~4 GiB is refused without allocating it; a summary start inside
    the header (rosbags refuses it: 'Invalid MCAP summary offset') is refused without reading the
    whole file as its summary."""
    data = SAMPLE.read_bytes()
    huge = bytearray(data)
    huge[17:21] = (0xFFFFFFF0).to_bytes(4, "little")  # the header's profile string length
    (tmp_path / "huge.mcap").write_bytes(bytes(huge))
    assert _peak_bytes(mcap_summary.profile, tmp_path / "huge.mcap") < 1_000_000
    early = bytearray(data)
    at = _footer_summary_start(early)
    early[at:at + 8] = (8).to_bytes(8, "little")  # the header record's offset
    (tmp_path / "early.mcap").write_bytes(bytes(early))
    assert _peak_bytes(mcap_summary.read, tmp_path / "early.mcap") < len(data) // 4
    assert mcap_summary.read(SAMPLE) is not None  # the negative control: the intact file reads
