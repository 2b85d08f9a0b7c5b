"""A recording split into several files, read as one log.

Two pieces: `split_log_paths` turns the command-line form ("run_0.mcap,run_1.mcap") into
paths, and `SplitSource` reads several single-file sources one after the other (a split
recording's files follow each other in time) behind the one-source interface LogReader
uses. ROS 1 bags need neither: rosbags' reader merges split bags itself.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, Protocol

from mrnc_eval.errors import InputError


def split_log_paths(text: str | Path) -> list[Path] | None:
    """The files of a split log written "a.mcap,b.mcap" (None when `text` is one path: an
    existing path wins even if its name has a comma)."""
    text = str(text)
    if "," not in text or Path(text).exists():
        return None
    parts = [p.strip() for p in text.split(",")]
    if any(not p for p in parts):
        raise InputError(text, "empty file name in a comma-separated split log")
    return [Path(p) for p in parts]


class Source(Protocol):
    channels: dict[str, Any]

    def messages(self, topics: list[str]) -> Iterator[tuple[str, int, bytes]]: ...

    def deserialize(self, raw: bytes, topic: str) -> Any: ...

    def close(self) -> None: ...


class SplitSource:
    """Several sources as one: the union of their topics (a topic must keep its type), and
    their messages file after file."""

    def __init__(self, sources: Sequence[Source], paths: Sequence[Path]) -> None:
        self._sources = list(sources)
        self.channels: dict[str, Any] = {}
        self._owner: dict[str, Source] = {}
        for src, path in zip(self._sources, paths, strict=True):
            for topic, ch in src.channels.items():
                known = self.channels.get(topic)
                if known is not None and known.msgtype != ch.msgtype:
                    self.close()
                    raise InputError(path, f"topic has type {ch.msgtype} here but {known.msgtype} in an earlier "
                                           "file of the split log", topic=topic)
                self.channels.setdefault(topic, ch)
                self._owner.setdefault(topic, src)

    def messages(self, topics: list[str]) -> Iterator[tuple[str, int, bytes]]:
        for src in self._sources:
            yield from src.messages([t for t in topics if t in src.channels])

    def deserialize(self, raw: bytes, topic: str) -> Any:
        return self._owner[topic].deserialize(raw, topic)

    def close(self) -> None:
        for src in self._sources:
            src.close()
