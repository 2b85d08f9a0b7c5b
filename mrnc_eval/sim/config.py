"""Simulator parameters."""

from __future__ import annotations

from dataclasses import dataclass

from mrnc_eval.params import param


@dataclass(frozen=True)
class SimConfig:
    seed: int = param(0, "random seed; the same seed gives byte-identical logs")
