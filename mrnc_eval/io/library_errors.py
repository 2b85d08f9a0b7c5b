"""What the reading libraries raise for a broken, truncated or unexpected file, by type.

Caught at the io boundary (io/log_source.py, io/overview.py, io/containers.py, io/mcap_index.py,
io/chunk_prefix.py, export/log_copy.py) and reported as InputError naming the file and topic
(exit 4). Anything else (AttributeError, TypeError, NameError...) is a bug of ours and reaches
cli.main as one (exit 5), instead of posing as "corrupted or truncated data".
"""

from __future__ import annotations

import contextlib
import functools
import importlib
import sqlite3
import struct
import sys

# raised by the libraries' own parsing on bad bytes: short buffers, bad lengths, bad text; rosbags'
# ROS 1 reader asserts on some corrupt chunks (tests/io/test_io_bad_input.py's fuzzing finds it)
_PARSING = (struct.error, EOFError, OSError, ValueError, KeyError, IndexError, OverflowError, MemoryError,
            AssertionError)


# rosbags' errors, (module, name): in data_errors() once their module is imported (only its own code
# raises them, and it is imported before it runs); importing them for the tuple alone would cost a
# single ROS 2 MCAP file, read without rosbags (io/ros2_mcap.py), ~45 ms
_READER_ERRORS = (("rosbags.highlevel", "AnyReaderError"), ("rosbags.rosbag1", "ReaderError"),
                  ("rosbags.rosbag2", "ReaderError"), ("rosbags.serde", "SerdeError"),
                  ("rosbags.typesys", "TypesysError"))


def data_errors() -> tuple[type[Exception], ...]:
    """The exception types a log library raises for bad data (imported on first use: the
    libraries are heavy and only needed when a log is read; rosbags' once imported, see
    _READER_ERRORS)."""
    readers = tuple(getattr(sys.modules.get(module), name, None) for module, name in _READER_ERRORS)
    return _library_errors() + tuple(err for err in readers if err is not None)


@functools.cache
def _library_errors() -> tuple[type[Exception], ...]:
    """data_errors() without rosbags'."""
    from mcap.exceptions import McapError

    found: list[type[Exception]] = [McapError, sqlite3.Error, *_PARSING]
    for module in ("zstandard", "backports.zstd", "compression.zstd"):  # mcap's, rosbags' (py < 3.14, >= 3.14)
        with contextlib.suppress(ImportError, AttributeError):  # not installed: that library refuses zstd itself
            found.append(importlib.import_module(module).ZstdError)
    try:
        from lz4.block import LZ4BlockError

        found += [LZ4BlockError, RuntimeError]  # lz4.frame reports a corrupt frame as RuntimeError
    except ImportError:
        pass
    return tuple(found)
