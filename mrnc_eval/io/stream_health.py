"""How clean each stream of a log was: counts from the overview, notes made while reading.

Streams are sorted by header stamp and exact duplicates dropped (`sort_dedup`), never
silently: the counts go to the ledger, with one note per validation drop (io/validate.py)
or skipped sweep, and come back as a result's warnings (`HealthLedger.notes`).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from mrnc_eval.data import StreamHealth
from mrnc_eval.errors import InputError
from mrnc_eval.io.validate import Mask, ValidationConfig, screen


def sort_dedup(stamps: np.ndarray, topic: str) -> tuple[np.ndarray, StreamHealth]:
    """Indices that sort by stamp and drop exact duplicates; the health of the raw stream."""
    n = stamps.size
    out_of_order = int(np.count_nonzero(np.diff(stamps) < 0)) if n > 1 else 0
    order = np.argsort(stamps, kind="stable")
    s = stamps[order]
    keep = np.ones(n, dtype=bool)
    if n > 1:
        keep[1:] = np.diff(s) > 0
    dup = int(n - keep.sum())
    gaps = np.diff(s[keep])
    health = StreamHealth(topic=topic, count=n, duplicates=dup, out_of_order=out_of_order,
                          max_gap_s=float(gaps.max()) if gaps.size else 0.0)
    return order[keep], health


class HealthLedger:
    """StreamHealth per topic of one log, and the validation policy that adds to it."""

    def __init__(self, path: Path, validation: ValidationConfig) -> None:
        self.path = path
        self.validation = validation
        self._health: dict[str, StreamHealth] = {}

    def get(self, topic: str) -> StreamHealth:
        if topic not in self._health:
            raise InputError(self.path, "topic not in log", topic=topic)
        return self._health[topic]

    def set(self, health: StreamHealth) -> None:
        """Store a stream's counts, keeping notes made while reading it earlier."""
        old = self._health.get(health.topic)
        self._health[health.topic] = replace(health, notes=old.notes) if old and old.notes else health

    def sorted_unique(self, stamps: np.ndarray, topic: str) -> np.ndarray:
        """`sort_dedup`'s indices; the stream's counts recorded."""
        keep, health = sort_dedup(stamps, topic)
        self.set(health)
        return keep

    def note(self, topic: str, note: str) -> None:
        base = self._health.get(topic) or StreamHealth(topic=topic, count=0)
        self._health[topic] = replace(base, notes=(*base.notes, note))

    def screen(self, topic: str, checks: dict[str, Mask]) -> Mask:
        """The validation policy (io/validate.py): mask of valid samples; a note when some
        were dropped; InputError when too many are bad."""
        valid, note = screen(str(self.path), topic, checks, self.validation)
        if note:
            self.note(topic, note)
        return valid

    def notes(self) -> list[str]:
        """One line per problem found in the streams read so far (dropped samples, sorted or
        duplicate stamps, skipped sweeps), for a result's warnings."""
        out = []
        for topic, h in sorted(self._health.items()):
            if h.out_of_order:
                out.append(f"{topic}: {h.out_of_order} out-of-order stamp(s) in the log (sorted when read)")
            if h.duplicates:
                out.append(f"{topic}: {h.duplicates} duplicate stamp(s) dropped")
            out += [f"{topic}: {n}" for n in h.notes]
        return out
