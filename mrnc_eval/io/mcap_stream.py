"""One topic's messages of an MCAP file read straight from its chunks: the sweep stream's reader.

The reading libraries copy every message twice on the way out (rosbags: the record, then its
payload) and rosbags' zstd call does not use the frame's known size (about twice zstd's own
time on a 6.3 MB chunk). Here each chunk holding the topic is read once, decompressed in one
call into a buffer of its known size, its CRC checked (when it has one), and the messages are
handed out as views into that buffer, valid until the next message is asked for.

Messages come in the libraries' order (log time, then chunk position in the file, then position
in the chunk). The plan is made from the summary's chunk indexes and the message index records
before anything is decompressed; anything they cannot vouch for (see io/mcap_index.py), or a
topic whose chunks overlap in time (the order would need a merge), raises IndexUnusable there,
and the caller reads through the library instead. Afterwards, a damaged chunk (it does not
decompress, its size or CRC differ) is an InputError as through the libraries, and so is a
chunk whose records disagree with its message index.
"""

from __future__ import annotations

import io
import os
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO

from mrnc_eval.errors import InputError
from mrnc_eval.io.chunk_prefix import IndexUnusable
from mrnc_eval.io.library_errors import data_errors
from mrnc_eval.io.mcap_index import Index, chunk_indexes, read_chunk_head, read_message_index

_MESSAGE = 0x05
_RECORD_HEAD = 9 + 22  # opcode u8, length u64; channel u16, sequence u32, log time u64, publish time u64
# a zstd frame that does not declare its content size may expand at most this much (float clouds
# compress 2-4x; the bound only keeps a hostile size from allocating gigabytes)
_MAX_UNSIZED_RATIO = 1000


@dataclass(frozen=True, kw_only=True)
class _Chunk:
    """One chunk holding the topic: where its compressed bytes are, and the topic's messages in it."""

    start_s: float  # the chunk's time range, for messages
    end_s: float
    data_at: int  # file position of the compressed data
    compressed_size: int
    size: int
    crc: int  # 0: none written
    compression: str
    entries: list[tuple[int, int]]  # (log time ns, offset in the chunk) of the topic's messages, in order
    channels: frozenset[int]  # the topic's channel ids


class TopicStream:
    """`TopicStream(path, topic)` plans (IndexUnusable when it cannot); `messages()` reads, and
    closes the file when it ends or is closed; `close()` closes it unread."""

    def __init__(self, path: Path, topic: str, *, index: Index | None = None) -> None:
        self.path, self.topic = path, topic
        self._fh: io.BufferedReader = path.open("rb")
        try:
            self._chunks = _plan(self._fh, topic, index)
        except BaseException:
            self._fh.close()
            raise

    def close(self) -> None:
        self._fh.close()

    def messages(self) -> Iterator[tuple[int, memoryview]]:
        """(log time ns, message data) in log order; the view is valid until the next one."""
        packed, plain = _Buffer(), _Buffer()  # reused: fresh 2-6 MB buffers a chunk cost ~2 ms of page faults
        try:
            for chunk in self._chunks:
                data = self._chunk_data(chunk, packed, plain)
                for log_time, offset in chunk.entries:
                    (length,) = struct.unpack_from("<Q", data, offset + 1)
                    yield log_time, data[offset + _RECORD_HEAD:offset + 9 + length]
        finally:
            self._fh.close()

    def _chunk_data(self, chunk: _Chunk, packed: _Buffer, plain: _Buffer) -> memoryview:
        """The chunk's records, decompressed and checked against its size, CRC and message index."""
        self._fh.seek(chunk.data_at)
        source = packed.view(chunk.compressed_size)
        if self._fh.readinto(source) != chunk.compressed_size:
            raise InputError(self.path, "corrupted or truncated data: the file ends inside a chunk", topic=self.topic)
        try:
            data = _decompress(source, chunk, plain)
        except data_errors() as err:
            raise InputError(self.path, f"a chunk is damaged: it does not decompress ({err}); "
                             "mrnc-eval info lists the damaged chunks", topic=self.topic) from None
        if len(data) != chunk.size or (chunk.crc and zlib.crc32(data) != chunk.crc):
            what = "CRC mismatch" if len(data) == chunk.size else f"{len(data)} bytes instead of {chunk.size}"
            raise InputError(self.path, f"a chunk (messages {chunk.start_s:.3f}-{chunk.end_s:.3f} s) is damaged: "
                             f"{what}; its messages cannot be trusted (mrnc-eval info lists the damaged chunks)",
                             topic=self.topic)
        if _topic_records(data, chunk) != sorted(chunk.entries, key=lambda e: e[1]):
            raise InputError(self.path, f"corrupted or truncated data: the chunk of messages {chunk.start_s:.3f}-"
                             f"{chunk.end_s:.3f} s disagrees with its message index", topic=self.topic)
        return data


class _Buffer:
    """A bytearray reused for every chunk, grown when one is larger."""

    def __init__(self) -> None:
        self._buf = bytearray()
        self._zstd: Any = None

    def zstd(self) -> Any:
        """The zstd decompressor writing into this buffer (one context for every chunk)."""
        if self._zstd is None:
            import zstandard

            self._zstd = zstandard.ZstdDecompressor()
        return self._zstd

    def view(self, n: int) -> memoryview:
        if n > len(self._buf):
            self._buf = bytearray(n)  # a new object: views of the old one stay valid
        return memoryview(self._buf)[:n]


def _decompress(source: memoryview, chunk: _Chunk, plain: _Buffer) -> memoryview:
    """The chunk's records (zstd: into `plain`, in one pass, the GIL released; the frame's end and
    checksum are read). rosbags' `backports.zstd.decompress` grows its output in blocks and joins
    them: ~2x the time on a 6.3 MB chunk."""
    if chunk.compression == "zstd":
        import zstandard

        declared = zstandard.frame_content_size(source)  # from the frame's header, before any allocation
        if declared not in (zstandard.CONTENTSIZE_UNKNOWN, chunk.size):
            return source[:0]  # not the size the chunk record says: the caller reports it, nothing allocated
        if declared == zstandard.CONTENTSIZE_UNKNOWN and chunk.size > _MAX_UNSIZED_RATIO * max(len(source), 1):
            return source[:0]
        out = plain.view(chunk.size)
        reader = plain.zstd().stream_reader(source, read_size=len(source))
        filled = 0
        while filled < chunk.size:
            n = reader.readinto(out[filled:])
            if not n:
                return out[:filled]  # too short: the caller reports the size
            filled += n
        extra = len(reader.read(1 << 16))  # none, and the frame's end (checksum) read
        return plain.view(chunk.size + extra) if extra else out  # too long: the caller reports the size
    if chunk.compression == "lz4":
        import lz4.frame

        return memoryview(lz4.frame.decompress(source))
    return source


def _plan(fh: BinaryIO, topic: str, index: Index | None) -> list[_Chunk]:
    """The chunks holding `topic`, in file order, each with the topic's messages in log order
    (`index`: the file's chunk_indexes, read here when not given)."""
    chunks, topics = index if index is not None else chunk_indexes(fh)
    ids = {cid for cid, name in topics.items() if name == topic}
    out: list[_Chunk] = []
    for ci in chunks:
        if not ids & ci.message_index_offsets.keys():
            continue
        entries = sorted((t, o) for c, t, o in read_message_index(fh, ci, topics) if c in ids)
        if not entries:
            continue
        if out and out[-1].entries[-1][0] > entries[0][0]:
            raise IndexUnusable("the topic's chunks overlap in time")  # the libraries would interleave them
        out.append(_chunk(fh, ci, entries, frozenset(ids)))
    return out


def _chunk(fh: BinaryIO, ci: Any, entries: list[tuple[int, int]], channels: frozenset[int]) -> _Chunk:
    """The chunk record's head, checked against its index and the file's length (a size read from the
    file is trusted for an allocation only once the bytes it claims are there)."""
    h = read_chunk_head(fh, ci)
    if h.data_at + h.compressed_size > os.fstat(fh.fileno()).st_size:
        raise IndexUnusable("a chunk runs past the end of the file")
    if not h.compression and h.size != h.compressed_size:
        raise IndexUnusable("an uncompressed chunk whose two sizes differ")
    if h.compression not in ("", "zstd", "lz4"):
        raise IndexUnusable(f"compression {h.compression!r}")
    return _Chunk(start_s=ci.message_start_time / 1e9, end_s=ci.message_end_time / 1e9, data_at=h.data_at,
                  compressed_size=h.compressed_size, size=h.size, crc=h.crc, compression=h.compression,
                  entries=entries, channels=channels)


def _topic_records(data: memoryview, chunk: _Chunk) -> list[tuple[int, int]]:
    """(log time, offset) of the chunk's message records on the topic's channels, by offset: a walk
    over the record heads (tens a chunk), so a message index that leaves one out is caught."""
    out: list[tuple[int, int]] = []
    pos, size = 0, len(data)
    while pos < size:
        if pos + 9 > size:
            return [(-1, pos)]
        opcode, length = struct.unpack_from("<BQ", data, pos)
        if pos + 9 + length > size:
            return [(-1, pos)]
        if opcode == _MESSAGE and length >= 22:
            channel, _seq, log_time = struct.unpack_from("<HIQ", data, pos + 9)
            if channel in chunk.channels:
                out.append((log_time, pos))
        pos += 9 + length
    return out
