"""The first bytes of a compressed chunk, decompressed only as far as they are read.

An overview pass that wants the small messages of a chunk and the header stamp of the cloud
closing it stops decompressing there: for MCAP (io/mcap_index.py) and ROS 1 bags
(io/bag_index.py), whose indexes say where each message starts in its chunk.
"""

from __future__ import annotations

import bz2
import os
from typing import Any, BinaryIO

from mrnc_eval.io.library_errors import data_errors

WHOLE = -1  # a `wants` value: the whole message (otherwise: its first so many bytes)
_PIECE = 16384  # compressed bytes fed to the decompressor at a time
# Bytes from each chunk's start an overview asks the kernel for ahead (chunk head and the first pieces
# of compressed data: 32 kB on an OS0-128 x 1024 log, whose small messages sit at the chunk's start).
PREFETCH_BYTES = 64 << 10


class IndexUnusable(Exception):
    """The file's indexes cannot give the overview; read the file in full instead."""


class ChunkPrefix:
    """`ensure(n)` returns a buffer holding at least the first n uncompressed bytes of a chunk
    whose `compressed_size` bytes start at `start` in `fh` (`fh` may be used in between)."""

    def __init__(self, fh: BinaryIO, start: int, compressed_size: int, size: int, compression: str) -> None:
        self._fh, self._start, self._left, self.size = fh, start, compressed_size, size
        self._buf = bytearray()
        self._decompress = _decompressor(compression)

    def ensure(self, n: int) -> bytearray:
        if n > self.size:
            raise IndexUnusable("record beyond the chunk's end")
        while len(self._buf) < n:
            if self._left <= 0:
                raise IndexUnusable("chunk data ends early")
            self._fh.seek(self._start)
            piece = self._fh.read(min(_PIECE, self._left))
            if not piece:
                raise IndexUnusable("truncated chunk data")
            self._start += len(piece)
            self._left -= len(piece)
            try:
                self._buf += self._decompress(piece)
            except data_errors() as err:  # corrupt data: the full read names it
                raise IndexUnusable(str(err)) from err
        return self._buf


def will_read(fh: BinaryIO, ranges: list[tuple[int, int]]) -> None:
    """Tell the kernel which (offset, length) ranges of `fh` are read next, so that from a cold page
    cache their reads are queued together instead of one after the other (forest30's MCAP overview:
    600 ranges, ~0.15 s less waiting). Only advice: nothing happens where it is not supported."""
    if not hasattr(os, "posix_fadvise"):
        return
    try:
        fd = fh.fileno()
        for offset, length in ranges:
            os.posix_fadvise(fd, offset, length, os.POSIX_FADV_WILLNEED)
    except (OSError, ValueError, AttributeError):  # not a real file (a pipe, an in-memory buffer)
        return


def _decompressor(compression: str) -> Any:
    """A function feeding one piece of compressed data and returning what it decompressed
    (MCAP: "", zstd, lz4; ROS 1: none, bz2, lz4 - both lz4 kinds are LZ4 frames)."""
    if compression in ("", "none"):
        return bytes
    if compression == "zstd":
        import zstandard

        # a context of its own (~50 us): decompressobjs of one shared context share its state, so two
        # prefixes read in turn, or from two threads, corrupt each other
        return zstandard.ZstdDecompressor().decompressobj().decompress
    if compression == "lz4":
        import lz4.frame

        return lz4.frame.LZ4FrameDecompressor().decompress
    if compression == "bz2":
        return bz2.BZ2Decompressor().decompress
    raise IndexUnusable(f"compression {compression!r}")
