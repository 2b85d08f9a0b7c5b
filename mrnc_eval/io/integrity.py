"""Chunk checksums of MCAP logs: written by our writer, verified by `info` and by every read.

An MCAP chunk record carries the CRC-32 of its uncompressed records (0: none). rosbags' MCAP
writer leaves it 0, so a flipped byte inside a compressed cloud went unnoticed: `add_chunk_crcs`
fills the field in place after the writer closed (the record keeps its size, so no offset
moves). `verify_chunks` decompresses every chunk and compares; `crc_note` says, cheaply (chunk
headers only), when a log has no checksums at all, so damage inside it cannot be detected.
ROS 1 bags and sqlite3 bags have no per-chunk checksums in their formats.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

from mrnc_eval.io.library_errors import data_errors

_MAGIC = b"\x89MCAP0\r\n"
_CHUNK = 0x06
_MESSAGE_INDEX = 0x07
_CHUNK_HEAD = 28  # start time u64, end time u64, uncompressed size u64, uncompressed crc u32
_CRC_AT = 24  # the CRC field's offset in a chunk record's content


@dataclass(frozen=True, kw_only=True)
class DamagedChunk:
    """A chunk whose data cannot be trusted."""

    offset: int  # byte offset of the chunk record in the file
    start_s: float  # log time of its first and last message, s
    end_s: float
    topics: tuple[str, ...]  # the topics with messages in it (from its message index)
    reason: str

    def message(self) -> str:
        what = ", ".join(self.topics) or "unknown topics"
        return (f"chunk at byte {self.offset} (messages {self.start_s:.3f}-{self.end_s:.3f} s; {what}) is damaged: "
                f"{self.reason}")


@dataclass(kw_only=True)
class ChunkCheck:
    """What checking the chunks of a file found."""

    chunks: int = 0
    with_crc: int = 0
    damaged: list[DamagedChunk] = field(default_factory=list)


@dataclass(frozen=True, kw_only=True)
class _ChunkRecord:
    """Where a chunk record sits in the file and what it covers."""

    offset: int  # of the record (its opcode byte)
    content: int  # of its content
    start_ns: int
    end_ns: int
    size: int
    crc: int
    compression: str
    data_at: int  # offset of the compressed bytes
    data_len: int


def _records(fh: BinaryIO) -> Iterator[tuple[int, int, int]]:
    """(opcode, record offset, content length) of every record of the data section, in order."""
    size = fh.seek(0, 2)
    fh.seek(0)
    if fh.read(8) != _MAGIC:
        return
    pos = 8
    while True:
        head = fh.read(9)
        if len(head) < 9:
            return
        opcode, length = struct.unpack("<BQ", head)
        if length > size - pos - 9:
            raise ValueError(f"record at byte {pos} runs past the end of the file (truncated or damaged)")
        yield opcode, pos, length
        if opcode == 0x0F:  # data end: the summary follows
            return
        pos += 9 + length
        fh.seek(pos)


def _chunk(fh: BinaryIO, offset: int) -> _ChunkRecord:
    fh.seek(offset + 9)
    head = fh.read(_CHUNK_HEAD + 4)
    start, end, size, crc, name_len = struct.unpack("<QQQII", head)
    compression = fh.read(name_len).decode("utf-8", "replace")
    (data_len,) = struct.unpack("<Q", fh.read(8))
    return _ChunkRecord(offset=offset, content=offset + 9, start_ns=start, end_ns=end, size=size, crc=crc,
                        compression=compression, data_at=fh.tell(), data_len=data_len)


def _decompress(data: bytes, compression: str, size: int) -> bytes:
    if compression == "":
        return data
    if compression == "zstd":
        import zstandard

        return zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
    if compression == "lz4":
        import lz4.frame

        return bytes(lz4.frame.decompress(data))
    raise ValueError(f"unknown chunk compression {compression!r}")


def add_chunk_crcs(path: Path) -> int:
    """Fill in the CRC of every chunk of the MCAP file at `path` that has none; returns how many."""
    filled = 0
    with path.open("r+b") as fh:
        chunks = [off for op, off, _n in _records(fh) if op == _CHUNK]
        for off in chunks:
            ch = _chunk(fh, off)
            if ch.crc:
                continue
            fh.seek(ch.data_at)
            crc = zlib.crc32(_decompress(fh.read(ch.data_len), ch.compression, ch.size))
            fh.seek(ch.content + _CRC_AT)
            fh.write(struct.pack("<I", crc))  # (a true CRC of 0 reads as "none": 1 chance in 2^32)
            filled += 1
    return filled


def _topics_after(fh: BinaryIO, records: list[tuple[int, int, int]], k: int, names: dict[int, str]) -> tuple[str, ...]:
    """The topics of the message index records that follow chunk record k."""
    found: list[str] = []
    for opcode, off, _n in records[k + 1:]:
        if opcode != _MESSAGE_INDEX:
            break
        fh.seek(off + 9)
        (channel,) = struct.unpack("<H", fh.read(2))
        found.append(names.get(channel, f"channel {channel}"))
    return tuple(dict.fromkeys(found))


def _channel_names(path: Path) -> dict[int, str]:
    try:
        from mcap.reader import make_reader

        with path.open("rb") as fh:
            summary = make_reader(fh).get_summary()
        return {cid: ch.topic for cid, ch in summary.channels.items()} if summary else {}
    except data_errors():  # a damaged summary: topics unnamed, the check still runs
        return {}


def verify_chunks(path: Path) -> ChunkCheck:
    """Decompress every chunk of the MCAP file and compare with its CRC (where it has one)."""
    check = ChunkCheck()
    names = _channel_names(path)
    with path.open("rb") as fh:
        records: list[tuple[int, int, int]] = []
        try:
            records += _records(fh)
        except (ValueError, struct.error, OSError) as err:  # the records read so far are still checked
            check.damaged.append(DamagedChunk(offset=records[-1][1] if records else 8, start_s=0.0, end_s=0.0,
                                              topics=(), reason=f"unreadable record structure: {err}"))
        for k, (opcode, off, _n) in enumerate(records):
            if opcode != _CHUNK:
                continue
            check.chunks += 1
            try:
                ch = _chunk(fh, off)
            except (ValueError, struct.error, OSError) as err:
                check.damaged.append(DamagedChunk(offset=off, start_s=0.0, end_s=0.0, topics=(),
                                                  reason=f"unreadable chunk header: {err}"))
                continue
            check.with_crc += ch.crc != 0
            if ch.size > 1 << 34 or ch.data_len > 1 << 34:  # 16 GB: a damaged header, not a chunk
                check.damaged.append(DamagedChunk(offset=off, start_s=0.0, end_s=0.0, topics=(),
                                                  reason="implausible chunk sizes in its header"))
                continue
            fh.seek(ch.data_at)
            try:
                data = _decompress(fh.read(ch.data_len), ch.compression, ch.size)
                reason = ("size mismatch" if len(data) != ch.size
                          else "CRC mismatch" if ch.crc and zlib.crc32(data) != ch.crc else "")
            except data_errors() as err:  # the decompressor's own complaint: the data is not what was written
                reason = f"does not decompress ({type(err).__name__}: {err})"
            if reason:
                check.damaged.append(DamagedChunk(offset=off, start_s=ch.start_ns / 1e9, end_s=ch.end_ns / 1e9,
                                                  topics=_topics_after(fh, records, k, names), reason=reason))
    return check


def mcap_files(path: Path) -> list[Path]:
    """The MCAP files of a log: the file itself, or those of a ROS 2 bag folder."""
    if path.is_dir():
        return sorted(path.glob("*.mcap"))
    return [path] if path.suffix.lower() == ".mcap" and path.is_file() else []


def crc_note(path: Path, container: str) -> str | None:
    """A note when the log carries no checksums (damage inside it cannot be detected), else None.
    Reads only the chunk records' heads."""
    if container == "ros1":
        return "ROS 1 bag: the format has no checksums; damage inside a chunk cannot be detected"
    files = mcap_files(path)
    if not files:
        return "sqlite3 bag: no checksums; damage inside a message cannot be detected" if "sqlite" in container \
            else None
    chunks = with_crc = 0
    for f in files:
        with f.open("rb") as fh:
            try:
                for opcode, off, _n in _records(fh):
                    if opcode == _CHUNK:
                        chunks += 1
                        with_crc += _chunk(fh, off).crc != 0
            except (ValueError, struct.error, OSError):
                continue  # a damaged file: verify_chunks and the reader say what is wrong
    if chunks and with_crc < chunks:
        return (f"{chunks - with_crc} of {chunks} MCAP chunks carry no CRC: damage inside them cannot be detected "
                "(logs written before mrnc-eval 0.x, or by a writer without CRCs)")
    return None


def orphan_messages(path: Path) -> tuple[int, int]:
    """(messages whose topic id is not in the topics table, all messages) of a ROS 2 sqlite3 bag:
    its readers drop such messages without a word."""
    import sqlite3

    files = sorted(path.glob("*.db3")) if path.is_dir() else [path] if path.suffix.lower() == ".db3" else []
    orphans = total = 0
    for f in files:
        try:
            db = sqlite3.connect(f"file:{f}?mode=ro", uri=True)
            try:
                total += db.execute("SELECT COUNT(*) FROM messages").fetchone()[0]
                orphans += db.execute("SELECT COUNT(*) FROM messages WHERE topic_id NOT IN "
                                      "(SELECT id FROM topics)").fetchone()[0]
            finally:
                db.close()
        except sqlite3.Error:
            continue  # the reader reports an unreadable file itself
    return orphans, total


def container_notes(path: Path, container: str) -> list[str]:
    """What the container itself says about lost or unverifiable data, for info and results:
    no checksums (MCAP without CRCs, ROS 1, sqlite3), messages of unknown topic ids (sqlite3)."""
    notes = []
    if "sqlite" in container:
        orphans, total = orphan_messages(path)
        if orphans:
            notes.append(f"{orphans} of {total} messages ({100 * orphans / total:.1f} %) have a topic id missing "
                         "from the bag's topics table: dropped (their topic and type are unknown)")
    note = crc_note(path, container)
    if note:
        notes.append(note)
    return notes
