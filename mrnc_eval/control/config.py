"""Control-chain parameters (paper experiment section; resolutions in shared/docs/paper-notes.md)."""

from __future__ import annotations

from dataclasses import dataclass

from mrnc_eval.params import param


@dataclass(frozen=True)
class ControlConfig:
    rate_hz: float = param(1000.0, "control loop rate of the closed-loop simulation", "Hz")
