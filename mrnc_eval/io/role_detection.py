"""Which topic of an open log plays which role: io/roles.py's rule applied to the log.

From message types and the container's index, no scan: only the first message of each
JointState topic is read (its joint names), and, when several topics could be the LiDAR
or the wheel odometry, the first message of each (its fields and frames).
"""

from __future__ import annotations

import logging
from dataclasses import replace

from mrnc_eval.errors import InputError
from mrnc_eval.io.log_source import LogSource
from mrnc_eval.io.roles import Ambiguity, Candidate, TruthExclusion, candidates_by_role, choose_roles

log = logging.getLogger("mrnc_eval.io.reader")  # warnings name the reader, as before the split


def detect_roles(src: LogSource, overrides: dict[str, str]
                 ) -> tuple[dict[str, str], list[Ambiguity | TruthExclusion]]:
    """role -> topic, and the roles chosen among several candidates (each logged as a warning)."""
    joint_names: dict[str, list[str]] = {}
    for topic, ch in src.channels.items():
        if ch.msgtype == "sensor_msgs/msg/JointState" and not ch.problem and ch.count != 0:
            raw = src.first_raw(topic)  # a single MCAP: only its chunk's beginning decompressed
            if raw is not None:
                joint_names[topic] = [str(n) for n in src.decode(raw, topic).name]
    found = candidates_by_role([Candidate(t, ch.msgtype, ch.count) for t, ch in src.channels.items()],
                               joint_names)
    for role in ("lidar", "wheel_odom"):  # several candidates: their first message's fields and frames count
        if len(found.get(role, ())) > 1 and role not in overrides:
            found[role] = [_with_evidence(src, c) for c in found[role]]
    roles, doubts = choose_roles(found, overrides)
    for doubt in doubts:
        log.warning("%s: %s", src.path, doubt.message())
    for role, topic in roles.items():
        if topic not in src.channels:
            raise InputError(src.path, f"topic given for role {role!r} is not in the log", topic=topic)
    return roles, doubts


def _with_evidence(src: LogSource, c: Candidate) -> Candidate:
    """`c` with the field names and frames of its first message (unchanged if it cannot be read)."""
    try:
        raw = src.first_raw(c.topic)
        msg = src.decode(raw, c.topic) if raw is not None else None
    except InputError:
        return c
    if msg is None:
        return c
    fields = tuple(str(f.name) for f in getattr(msg, "fields", ()))
    return replace(c, fields=fields, frame_id=str(msg.header.frame_id),
                   child_frame_id=str(getattr(msg, "child_frame_id", "")))
