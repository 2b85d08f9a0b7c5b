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

import os
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from mrnc_eval.io.chunk_prefix import PREFETCH_BYTES, WHOLE, ChunkPrefix, IndexUnusable, will_read
from mrnc_eval.io.library_errors import data_errors

_MESSAGE = 0x05
_MESSAGE_INDEX = 0x07
_RECORD_HEAD = 9 + 22  # opcode u8, length u64; channel u16, sequence u32, log time u64, publish time u64
HEAD = 12  # bytes of a message kept as its head (ROS 1 and CDR: up to the end of a header stamp)
_BATCH_BYTES = 32 << 20  # decompressed chunk bytes read at a time (what the pass holds at most, with the kept messages)


Index = tuple[list[Any], dict[int, str]]  # chunk_indexes(): the chunk indexes by file position, channel id -> topic


@dataclass(frozen=True, kw_only=True)
class IndexedMessages:
    """Every message of one file, in log order (numpy arrays of one row a message)."""

    topics: list[str]  # the file's topics; `topic` indexes this list
    topic: np.ndarray  # (N,) int
    log_time: np.ndarray  # (N,) uint64, ns
    head: np.ndarray  # (N, HEAD) uint8: the message's first bytes, where any were wanted (else zeros)
    head_len: np.ndarray  # (N,) int: how many of `head` the message has (0 where none were wanted)
    data: list[bytes | None]  # the whole message where wants[topic] == WHOLE (all None when dropped)
    kept: int  # bytes of the whole messages wanted
    dropped: bool  # `kept` is over the budget: `data` holds none of them


@dataclass(frozen=True, kw_only=True)
class _Batch:
    """The messages of a run of chunks, by chunk and position in it (IndexedMessages' columns)."""

    chunk: np.ndarray  # (n,) the chunk's number in the file's chunk list
    channel: np.ndarray
    log_time: np.ndarray
    offset: np.ndarray  # in the uncompressed chunk
    head: np.ndarray
    head_len: np.ndarray
    data: list[bytes | None]
    kept: int


def overview(path: Path, wants: dict[str, int], budget: int, *, index: Index | None = None) -> IndexedMessages:
    """The file's messages in log order: each one's log time, its first HEAD bytes where
    wants[topic] != 0 (HEAD or WHOLE) and the whole of it where wants[topic] == WHOLE, unless the
    whole ones come to more than `budget` bytes (then none is kept). One pass over the chunks
    reads their indexes and decompresses each as far as wanted; the checks and reads of the
    messages are numpy over _BATCH_BYTES of decompressed chunks at a time. `index`: the file's
    `chunk_indexes`, when the caller has them."""
    with path.open("rb") as fh:
        chunks, topics = index if index is not None else chunk_indexes(fh)
        will_read(fh, [(ci.chunk_start_offset, PREFETCH_BYTES) for ci in chunks] +
                  [(ci.chunk_start_offset + ci.chunk_length, ci.message_index_length) for ci in chunks])
        want_of = {cid: wants.get(topic, 0) for cid, topic in topics.items()}
        want_lut = np.zeros(max(topics, default=0) + 1, np.int64)
        want_lut[list(want_of)] = list(want_of.values())
        batches: list[_Batch] = []
        pending: list[tuple[int, list[tuple[int, np.ndarray]], bytes]] = []
        size = 0
        for k, ci in enumerate(chunks):
            pending.append((k, *_chunk_read(fh, ci, topics, want_of)))
            size += len(pending[-1][2])
            if size >= _BATCH_BYTES or k == len(chunks) - 1:  # the prefixes let go once read
                batches.append(_batch(pending, chunks=chunks, want_lut=want_lut, keep=budget >= 0))
                budget -= batches[-1].kept
                pending, size = [], 0
    return _in_log_order(batches, chunks, topics, dropped=budget < 0)


def _batch(pending: list[tuple[int, list[tuple[int, np.ndarray]], bytes]], *, chunks: list[Any],
           want_lut: np.ndarray, keep: bool) -> _Batch:
    """The messages of the chunks in `pending` ((number, index records, decompressed prefix) each),
    their index entries checked against the chunks' time ranges; whole messages only with `keep`."""
    records = [(j, channel, table) for j, (_k, recs, _prefix) in enumerate(pending) for channel, table in recs]
    table = np.concatenate([r[2] for r in records]) if records else np.zeros((0, 2), np.uint64)
    counts = [len(r[2]) for r in records]
    channel = np.repeat(np.array([r[1] for r in records], np.int64), counts)
    local = np.repeat(np.array([r[0] for r in records], np.int64), counts)
    log_time, offset = table[:, 0], table[:, 1].astype(np.int64)
    start = np.array([chunks[k].message_start_time for k, _r, _p in pending], np.uint64)
    end = np.array([chunks[k].message_end_time for k, _r, _p in pending], np.uint64)
    if np.any(log_time < start[local]) or np.any(log_time > end[local]):
        raise IndexUnusable("message outside its chunk's time range")  # rosbags would drop it
    want = want_lut[channel]
    if not keep:
        want[want == WHOLE] = HEAD
    head, head_len, data = _messages([p for _k, _r, p in pending], local=local, channel=channel,
                                     log_time=log_time, offset=offset, want=want)
    return _Batch(chunk=np.array([k for k, _r, _p in pending], np.int64)[local], channel=channel,
                  log_time=log_time, offset=offset, head=head, head_len=head_len, data=data,
                  kept=sum(len(d) for d in data if d is not None))


def _in_log_order(batches: list[_Batch], chunks: list[Any], topics: dict[int, str], *,
                  dropped: bool) -> IndexedMessages:
    """The batches' messages by log time, then chunk position in the file, then in the chunk."""
    names = list(dict.fromkeys(topics.values()))
    topic_lut = np.zeros(max(topics, default=0) + 1, np.int64)
    topic_lut[list(topics)] = [names.index(t) for t in topics.values()]
    if not batches:
        return IndexedMessages(topics=names, topic=np.zeros(0, np.int64), log_time=np.zeros(0, np.uint64),
                               head=np.zeros((0, HEAD), np.uint8), head_len=np.zeros(0, np.int64), data=[],
                               kept=0, dropped=dropped)
    chunk, channel, log_time, offset, head, head_len = (
        np.concatenate([getattr(b, f) for b in batches])
        for f in ("chunk", "channel", "log_time", "offset", "head", "head_len"))
    at = np.array([ci.chunk_start_offset for ci in chunks], np.uint64)
    order = np.lexsort((offset, at[chunk], log_time))
    data = [d for b in batches for d in b.data]
    return IndexedMessages(topics=names, topic=topic_lut[channel[order]], log_time=log_time[order], head=head[order],
                           head_len=head_len[order], kept=sum(b.kept for b in batches), dropped=dropped,
                           data=[None] * len(data) if dropped else [data[i] for i in order.tolist()])


def _messages(prefixes: list[bytes], *, local: np.ndarray, channel: np.ndarray, log_time: np.ndarray,
              offset: np.ndarray, want: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[bytes | None]]:
    """Heads (first HEAD bytes), their lengths and whole messages (want == WHOLE) of the wanted
    messages (want != 0), each record head checked against its index entry, out of the chunks'
    decompressed prefixes laid end to end (`local`: each message's chunk in `prefixes`)."""
    n = offset.size
    head, head_len = np.zeros((n, HEAD), np.uint8), np.zeros(n, np.int64)
    data: list[bytes | None] = [None] * n
    wanted = np.flatnonzero(want != 0)
    if not wanted.size:
        return head, head_len, data
    sizes = np.array([len(prefix) for prefix in prefixes], np.int64)
    base = np.concatenate(([0], np.cumsum(sizes)[:-1])).astype(np.int64)
    joined = b"".join(prefixes)
    buf = np.frombuffer(joined, np.uint8)
    k = local[wanted]
    at = base[k] + offset[wanted]
    rec = buf[at[:, None] + np.arange(_RECORD_HEAD)]  # each chunk's prefix reaches past its last wanted head
    length = rec[:, 1:9].copy().view("<u8").ravel()
    if np.any(rec[:, 0] != _MESSAGE) or np.any(rec[:, 9:11].copy().view("<u2").ravel() != channel[wanted]) or \
            np.any(rec[:, 15:23].copy().view("<u8").ravel() != log_time[wanted]) or np.any(length < 22):
        raise IndexUnusable("message index points at another record")
    size = (length - 22).astype(np.int64)
    begin = at + _RECORD_HEAD
    stop = begin + np.where(want[wanted] == WHOLE, size, np.minimum(size, HEAD))
    if np.any(stop > base[k] + sizes[k]):
        raise IndexUnusable("messages overlap in their chunk")  # the last wanted one ends each prefix
    head_len[wanted] = np.minimum(size, HEAD)
    inside = np.arange(HEAD) < head_len[wanted][:, None]  # a message shorter than HEAD: zeros after it
    head[wanted] = buf[np.minimum(begin[:, None] + np.arange(HEAD), buf.size - 1)] * inside
    whole = want[wanted] == WHOLE
    for i, a, b in zip(wanted[whole].tolist(), begin[whole].tolist(), stop[whole].tolist(), strict=True):
        data[i] = joined[a:b]
    return head, head_len, data


def first_message(path: Path, topic: str, *, index: Index | None = None) -> bytes | None:
    """The topic's first message in log order (the one the full read yields first), its chunk
    decompressed only up to it; None when the topic has none. IndexUnusable as `overview`."""
    with path.open("rb") as fh:
        chunks, topics = index if index is not None else chunk_indexes(fh)
        ids = {cid for cid, name in topics.items() if name == topic}
        best: tuple[int, int, int, int, Any] | None = None  # log time, chunk position, offset, channel, chunk index
        for ci in sorted(chunks, key=lambda c: (c.message_start_time, c.chunk_start_offset)):
            if best is not None and ci.message_start_time > best[0]:
                break  # no earlier message further on
            for channel, table in _index_records(fh, ci, topics) if ids & ci.message_index_offsets.keys() else []:
                if channel not in ids or not table.size:
                    continue
                if table[:, 0].min() < ci.message_start_time or table[:, 0].max() > ci.message_end_time:
                    raise IndexUnusable("message outside its chunk's time range")
                k = int(np.lexsort((table[:, 1], table[:, 0]))[0])
                found = (int(table[k, 0]), ci.chunk_start_offset, int(table[k, 1]), channel, ci)
                best = found if best is None or found[:3] < best[:3] else best
        if best is None:
            return None
        log_time, _at, offset, channel, ci = best
        data = _Prefix(fh, ci).through(offset, WHOLE)
    opcode, _length, rec_channel, _seq, rec_time = struct.unpack_from("<BQHIQ", data, offset)
    if opcode != _MESSAGE or rec_channel != channel or rec_time != log_time:
        raise IndexUnusable("message index points at another record")
    return data[offset + _RECORD_HEAD:]


def chunk_indexes(fh: BinaryIO) -> Index:
    """The chunk indexes (by file position) and channel id -> topic, from the summary section."""
    from mcap.reader import make_reader

    try:
        summary = make_reader(fh).get_summary()
    except data_errors() as err:  # the full read reports what is wrong with the file
        raise IndexUnusable(str(err)) from err
    return summary_indexes(summary)


def summary_indexes(summary: Any) -> Index:
    """`chunk_indexes` from a summary already read (mcap's Summary, or None)."""
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


def _chunk_read(fh: BinaryIO, ci: Any, topics: dict[int, str],
                want_of: dict[int, int]) -> tuple[list[tuple[int, np.ndarray]], bytes]:
    """A chunk's message index records ((channel, entries) each) and its data decompressed up to
    the end of the last wanted bytes: those of the wanted message (want != 0) that starts last."""
    records = _index_records(fh, ci, topics)
    prefix = _Prefix(fh, ci)
    last = max(((int(table[:, 1].max()), want_of[channel]) for channel, table in records
                if want_of[channel] and table.size), default=None)
    return records, b"" if last is None else prefix.through(*last)


def read_message_index(fh: BinaryIO, ci: Any, topics: dict[int, str]) -> list[tuple[int, int, int]]:
    """(channel, log time, offset in the uncompressed chunk) of every message of the chunk."""
    out: list[tuple[int, int, int]] = []
    for channel, table in _index_records(fh, ci, topics):
        out += [(channel, int(t), int(o)) for t, o in table.tolist()]
    if any(not ci.message_start_time <= t <= ci.message_end_time for _c, t, _o in out):
        raise IndexUnusable("message outside its chunk's time range")  # rosbags would drop it
    return out


def _index_records(fh: BinaryIO, ci: Any, topics: dict[int, str]) -> list[tuple[int, np.ndarray]]:
    """(channel, its entries: (n, 2) log time, offset) of each message index record of the chunk."""
    at = ci.chunk_start_offset + ci.chunk_length
    if at + ci.message_index_length > os.fstat(fh.fileno()).st_size:  # checked before reading: a crafted
        raise IndexUnusable("truncated message index")  # length would otherwise be allocated first
    fh.seek(at)
    block = fh.read(ci.message_index_length)
    if len(block) != ci.message_index_length:
        raise IndexUnusable("truncated message index")
    out: list[tuple[int, np.ndarray]] = []
    pos = 0
    while pos < len(block):
        opcode, length = struct.unpack_from("<BQ", block, pos)
        if opcode == _MESSAGE_INDEX:
            channel, size = struct.unpack_from("<HI", block, pos + 9)
            if channel not in topics or size % 16 or 6 + size > length:
                raise IndexUnusable("malformed message index")
            out.append((channel, np.frombuffer(block, "<u8", size // 8, pos + 15).reshape(-1, 2)))
        pos += 9 + length
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
    if name_len != len(ci.compression.encode()):  # before reading it: a crafted length is not allocated
        raise IndexUnusable("chunk record disagrees with its index")
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

    def through(self, offset: int, want: int) -> bytes:
        """The chunk's bytes up to the end of the wanted bytes of the message at `offset`."""
        buf = self._chunk.ensure(offset + _RECORD_HEAD)
        (length,) = struct.unpack_from("<Q", buf, offset + 1)
        if length < 22:
            raise IndexUnusable("message index points at another record")
        end = offset + _RECORD_HEAD + (length - 22 if want == WHOLE else min(HEAD, length - 22))
        return bytes(memoryview(self._chunk.ensure(end))[:end])
