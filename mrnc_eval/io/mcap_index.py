"""Overview of an MCAP file from its indexes, decompressing only what is asked for.

LogReader's overview pass needs every message's log time, the whole of the small topics'
messages and the first bytes (the header stamp) of the point clouds. A recorder closes a
chunk when a message overflows it, so a cloud usually sits last in its chunk: the chunk
index and message index records (outside the compressed data) say where each message
starts, and each chunk is decompressed only up to the end of the last bytes wanted (about
17 kB of a 6.3 MB chunk on an OS0-128 x 1024 log). The clouds are decompressed once, by the
sweep stream.

Messages come in the order rosbags and the mcap library read them: by log time, then by
chunk position in the file, then by position in the chunk. Anything the indexes cannot vouch
for (no summary or statistics, messages outside indexed chunks, an index that disagrees with
the record it points at, an unknown compression, unreadable bytes) raises IndexUnusable: the
caller then reads the log in full, as before, and gets that reader's own error if the file is
broken. Chunk CRCs are not checked here (they cover the whole chunk); the sweep stream checks
those of the chunks it reads.
"""

from __future__ import annotations

import heapq
import struct
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from mrnc_eval.io.chunk_prefix import WHOLE, ChunkPrefix, IndexUnusable
from mrnc_eval.io.library_errors import data_errors

_MESSAGE = 0x05
_MESSAGE_INDEX = 0x07
_RECORD_HEAD = 9 + 22  # opcode u8, length u64; channel u16, sequence u32, log time u64, publish time u64
_INDEX_ENTRY = np.dtype([("log_time", "<u8"), ("offset", "<u8")])


def overview(path: Path, wants: dict[str, int]) -> Iterator[tuple[str, int, bytes]]:
    """(topic, log time ns, data) for every message, in log order; `data` is the whole message
    (wants[topic] == WHOLE) or its first wants[topic] bytes (fewer if the message is shorter)."""
    with path.open("rb") as fh:
        chunks, topics = chunk_indexes(fh)
        sources = [_chunk_messages(fh, ci, topics, wants) for ci in chunks]
        for _t, _chunk, position, topic, log_time, data in heapq.merge(*sources):
            if position >= 0:  # not a chunk's opening marker
                yield topic, log_time, data


def chunk_indexes(fh: BinaryIO) -> tuple[list[Any], dict[int, str]]:
    """The chunk indexes (by file position) and channel id -> topic, from the summary section."""
    from mcap.reader import make_reader

    try:
        summary = make_reader(fh).get_summary()
    except data_errors() as err:  # the full read reports what is wrong with the file
        raise IndexUnusable(str(err)) from err
    if summary is None or summary.statistics is None or not summary.chunk_indexes:
        raise IndexUnusable("no summary, statistics or chunk index")
    indexed = sum(_index_bytes(ci) for ci in summary.chunk_indexes) // 16
    if any(not ci.message_index_offsets for ci in summary.chunk_indexes) or \
            indexed != summary.statistics.message_count:  # some messages outside indexed chunks
        raise IndexUnusable("messages not all in indexed chunks")
    topics = {cid: ch.topic for cid, ch in summary.channels.items()}
    return sorted(summary.chunk_indexes, key=lambda ci: ci.chunk_start_offset), topics


def _index_bytes(ci: Any) -> int:
    """Bytes of index entries in a chunk's message index records (15 bytes of record head each)."""
    return int(ci.message_index_length) - 15 * len(ci.message_index_offsets)


def _chunk_messages(fh: BinaryIO, ci: Any, topics: dict[int, str],
                    wants: dict[str, int]) -> Iterator[tuple[int, int, int, str, int, bytes]]:
    """Merge keys and messages of one chunk: first an opening marker at the chunk's start time
    (so nothing is read before the merge reaches the chunk), then its messages by log time."""
    yield ci.message_start_time, ci.chunk_start_offset, -1, "", 0, b""
    entries = read_message_index(fh, ci, topics)
    prefix = _Prefix(fh, ci)
    out = []
    for channel, log_time, offset in entries:
        topic = topics[channel]
        want = wants.get(topic, 0)
        data = prefix.message(offset, channel, log_time, want) if want else b""
        out.append((log_time, ci.chunk_start_offset, offset, topic, log_time, data))
    out.sort()  # by log time, then position in the chunk (a stable sort of the records by time)
    yield from out


def read_message_index(fh: BinaryIO, ci: Any, topics: dict[int, str]) -> list[tuple[int, int, int]]:
    """(channel, log time, offset in the uncompressed chunk) of every message of the chunk."""
    fh.seek(ci.chunk_start_offset + ci.chunk_length)
    block = fh.read(ci.message_index_length)
    if len(block) != ci.message_index_length:
        raise IndexUnusable("truncated message index")
    out: list[tuple[int, int, int]] = []
    pos = 0
    while pos < len(block):
        opcode, length = struct.unpack_from("<BQ", block, pos)
        if opcode == _MESSAGE_INDEX:
            channel, size = struct.unpack_from("<HI", block, pos + 9)
            if channel not in topics or size % 16 or 6 + size > length:
                raise IndexUnusable("malformed message index")
            table = np.frombuffer(block, _INDEX_ENTRY, size // 16, pos + 15)
            out += [(channel, int(t), int(o)) for t, o in table.tolist()]
        pos += 9 + length
    if any(not ci.message_start_time <= t <= ci.message_end_time for _c, t, _o in out):
        raise IndexUnusable("message outside its chunk's time range")  # rosbags would drop it
    return out


@dataclass(frozen=True, kw_only=True)
class ChunkHead:
    """A chunk record's head: where its records start and how they are stored."""

    data_at: int  # file offset of the (compressed) records
    compressed_size: int  # bytes
    size: int  # bytes once decompressed
    crc: int  # CRC-32 of the decompressed records (0: none written)
    compression: str  # "", "zstd" or "lz4"


def read_chunk_head(fh: BinaryIO, ci: Any) -> ChunkHead:
    """The chunk record at `ci`'s (a ChunkIndex's) offset, checked against that index;
    IndexUnusable when it is not a chunk, is cut short or disagrees with the index."""
    fh.seek(ci.chunk_start_offset)
    head = fh.read(9 + 28 + 4)
    if len(head) != 41 or head[0] != 0x06:
        raise IndexUnusable("no chunk record at an indexed position")
    _start, _end, size, crc, name_len = struct.unpack_from("<QQQII", head, 9)
    compression = fh.read(name_len).decode("utf-8", "replace")
    size_field = fh.read(8)
    if len(size_field) != 8:
        raise IndexUnusable("truncated chunk")
    (compressed_size,) = struct.unpack("<Q", size_field)
    if compression != ci.compression or size != ci.uncompressed_size or compressed_size != ci.compressed_size:
        raise IndexUnusable("chunk record disagrees with its index")
    return ChunkHead(data_at=fh.tell(), compressed_size=compressed_size, size=size, crc=crc, compression=compression)


class _Prefix:
    """A chunk's records, decompressed only as far as they are read."""

    def __init__(self, fh: BinaryIO, ci: Any) -> None:
        h = read_chunk_head(fh, ci)
        self._chunk = ChunkPrefix(fh, h.data_at, h.compressed_size, h.size, h.compression)

    def message(self, offset: int, channel: int, log_time: int, want: int) -> bytes:
        """The message data at `offset` (all of it, or its first `want` bytes)."""
        buf = self._chunk.ensure(offset + _RECORD_HEAD)
        opcode, length, rec_channel, _seq, rec_time = struct.unpack_from("<BQHIQ", buf, offset)
        if opcode != _MESSAGE or rec_channel != channel or rec_time != log_time or length < 22:
            raise IndexUnusable("message index points at another record")
        n = length - 22 if want == WHOLE else min(want, length - 22)
        buf = self._chunk.ensure(offset + _RECORD_HEAD + n)
        return bytes(buf[offset + _RECORD_HEAD:offset + _RECORD_HEAD + n])
