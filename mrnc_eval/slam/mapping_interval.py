"""Which sweeps the SLAM maps: LIO-SAM's mappingProcessInterval, the one home of the rule.

A sweep is taken when it is at least `interval_s` after the last sweep taken; an empty sweep
takes its slot too (it is then not mapped). The rule is idempotent: a stream already thinned
by it passes it unchanged, so the reader may apply it before decoding (`LogReader.sweeps(keep=
MappingInterval(...).take)`, in its prefetch thread, with its own instance) and the replay again,
and both keep the same sweeps.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(kw_only=True)
class MappingInterval:
    """Which sweeps are mapped: one per interval."""

    interval_s: float  # s; 0 takes every sweep
    last_s: float = float("-inf")  # stamp of the last sweep taken, s

    def take(self, stamp: float) -> bool:
        """True (and the slot is used) when `stamp` is at least interval_s after the last sweep taken."""
        if stamp - self.last_s < self.interval_s:
            return False
        self.last_s = stamp
        return True
