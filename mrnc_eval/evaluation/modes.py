"""The named choices of trajectory evaluation, declared once (the CLI, the commands and the
pure functions all use these enums). Import-light on purpose: the CLI loads it for --help."""

from __future__ import annotations

from enum import StrEnum
from typing import TypeVar

from mrnc_eval.errors import EvaluationError

E = TypeVar("E", bound=StrEnum)


class AlignMode(StrEnum):
    """How the estimate is aligned to the reference (positions only, as evo)."""

    se3 = "se3"  # Umeyama, rotation + translation
    sim3 = "sim3"  # Umeyama with scale
    scale = "scale"  # Umeyama with scale, only the scale applied
    origin = "origin"  # first poses coincide
    yaw = "yaw"  # rotation about z + translation (4-DoF)
    none = "none"


class Relation(StrEnum):
    """How an error pose becomes one number."""

    trans = "trans"  # m
    rot = "rot"  # |R - I|_F, unitless
    full = "full"  # |E - I|_F, mixes m and rad
    angle_deg = "angle_deg"
    angle_rad = "angle_rad"
    point = "point"  # m, positions only


class DeltaUnit(StrEnum):
    """Unit of the RPE pair spacing."""

    frames = "frames"
    m = "m"


class SyncMethod(StrEnum):
    """How estimate poses are paired with reference poses."""

    nearest = "nearest"  # closest stamp within max_diff (evo's default)
    interpolate = "interpolate"  # the reference resampled at the estimate's stamps


class PairsFrom(StrEnum):
    """Which path RPE pairs are chosen on."""

    estimate = "estimate"
    reference = "reference"


def parse_choice(kind: type[E], value: str, what: str) -> E:
    """`value` as a member of `kind`, or an EvaluationError listing the choices."""
    try:
        return kind(value)
    except ValueError:
        choices = ", ".join(m.value for m in kind)
        raise EvaluationError(f"unknown {what} {value!r}; choose one of {choices}") from None
