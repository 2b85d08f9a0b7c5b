"""An info result's names (written by commands/log_job.py for the nightly report)."""

from __future__ import annotations

INFO = "info"  # extra: the `info` verb's summary (topics, roles, findings)
