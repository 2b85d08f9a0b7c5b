"""Overview of ROS 1 bags from their indexes, decompressing only what is asked for.

The ROS 1 counterpart of io/mcap_index.py. rosbags has already read every chunk's index
(time, chunk, offset of each message) when it opened the bag; this walks those entries in
the order rosbags reads them (per bag: connections merged by time, ties in the order asked;
bags merged by time) and decompresses each chunk only up to the last bytes wanted, so the
clouds closing the chunks stay compressed. Anything unexpected raises IndexUnusable and the
caller reads the bag in full.
"""

from __future__ import annotations

import heapq
import struct
from collections.abc import Iterator, Sequence
from itertools import groupby, repeat
from typing import Any, BinaryIO

from mrnc_eval.io.chunk_prefix import WHOLE, ChunkPrefix, IndexUnusable

_MSGDATA, _CHUNK, _CONNECTION = 2, 5, 7  # ROS 1 bag record ops


def overview(conns: Sequence[tuple[str, Any]], wants: dict[str, int]) -> Iterator[tuple[str, int, bytes]]:
    """(topic, record time ns, data) of every message of `conns` ((topic, rosbags connection),
    in the order the full read asks for them); data as io/mcap_index.overview gives it."""
    ordered = sorted(conns, key=lambda tc: id(tc[1].owner))  # as rosbags' AnyReader groups them
    streams = [_bag_messages(owner, [c for _t, c in group], {c.id: t for t, c in conns if c.owner is owner}, wants)
               for owner, group in groupby(ordered, key=lambda tc: tc[1].owner)]
    yield from heapq.merge(*streams, key=lambda m: m[1])


def _bag_messages(bag: Any, conns: list[Any], topics: dict[int, str],
                  wants: dict[str, int]) -> Iterator[tuple[str, int, bytes]]:
    """One bag's messages in rosbags' order (its IndexData compare by time only)."""
    entries = heapq.merge(*[zip(bag.indexes[c.id], repeat(c.id)) for c in conns], key=lambda ec: ec[0])
    with open(bag.path, "rb") as fh:
        chunk: ChunkPrefix | None = None
        chunk_pos = -1
        for entry, conn_id in entries:
            topic = topics[conn_id]
            want = wants.get(topic, 0)
            if not want:
                yield topic, entry.time, b""
                continue
            if entry.chunk_pos != chunk_pos:
                chunk, chunk_pos = _open_chunk(fh, entry.chunk_pos), entry.chunk_pos
            assert chunk is not None
            yield topic, entry.time, _message(chunk, entry.offset, conn_id, entry.time, want)


def _open_chunk(fh: BinaryIO, pos: int) -> ChunkPrefix:
    fh.seek(pos)
    head = fh.read(4)
    if len(head) != 4:
        raise IndexUnusable("truncated chunk")
    header = fh.read(struct.unpack("<I", head)[0])
    fields = _fields(header)
    size_field = fh.read(4)
    if fields.get("op") != bytes([_CHUNK]) or len(size_field) != 4 or len(fields.get("size", b"")) != 4:
        raise IndexUnusable("no chunk record at an indexed position")
    (size,), (compressed_size,) = struct.unpack("<I", fields["size"]), struct.unpack("<I", size_field)
    return ChunkPrefix(fh, pos + 4 + len(header) + 4, compressed_size, size,
                       fields.get("compression", b"").decode("utf-8", "replace"))


def _message(chunk: ChunkPrefix, pos: int, conn_id: int, time_ns: int, want: int) -> bytes:
    """The data of the message record at `pos` (after any connection records, as rosbags reads)."""
    while True:
        buf = chunk.ensure(pos + 4)
        (header_len,) = struct.unpack_from("<I", buf, pos)
        buf = chunk.ensure(pos + 4 + header_len + 4)
        fields = _fields(bytes(buf[pos + 4:pos + 4 + header_len]))
        (data_len,) = struct.unpack_from("<I", buf, pos + 4 + header_len)
        start = pos + 4 + header_len + 4
        if fields.get("op") != bytes([_CONNECTION]):
            break
        pos = start + data_len
    if fields.get("op") != bytes([_MSGDATA]) or fields.get("conn") != struct.pack("<I", conn_id) or \
            len(fields.get("time", b"")) != 8:
        raise IndexUnusable("index points at another record")
    sec, nsec = struct.unpack("<II", fields["time"])
    if sec * 10**9 + nsec != time_ns:
        raise IndexUnusable("index time differs from the record's")
    n = data_len if want == WHOLE else min(want, data_len)
    buf = chunk.ensure(start + n)
    return bytes(buf[start:start + n])


def _fields(header: bytes) -> dict[str, bytes]:
    """A ROS 1 record header: fields of u32 length + b"name=value"."""
    out: dict[str, bytes] = {}
    pos = 0
    while pos + 4 <= len(header):
        (n,) = struct.unpack_from("<I", header, pos)
        name, sep, value = header[pos + 4:pos + 4 + n].partition(b"=")
        if not sep:
            raise IndexUnusable("malformed record header")
        out[name.decode("ascii", "replace")] = value
        pos += 4 + n
    return out
