"""Pose relations: how an error pose (or a pair of poses) becomes one number."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from mrnc_eval.errors import EvaluationError
from mrnc_eval.evaluation import lie

RELATIONS = ("trans", "rot", "full", "angle_deg", "angle_rad", "point")
UNITS = {"trans": "m", "point": "m", "rot": "", "full": "", "angle_deg": "deg", "angle_rad": "rad"}
TITLES = {"trans": "translation part", "point": "point distance", "rot": "rotation part",
          "full": "full transformation", "angle_deg": "rotation angle in degrees",
          "angle_rad": "rotation angle in radians"}


def check_relation(relation: str) -> None:
    if relation not in RELATIONS:
        raise EvaluationError(f"unknown pose relation {relation!r}; choose one of {', '.join(RELATIONS)}")


def error_values(e: NDArray[np.float64], relation: str) -> NDArray[np.float64]:
    """Scalar error of each (N, 4, 4) error pose E."""
    if relation in ("trans", "point"):
        return np.linalg.norm(e[:, :3, 3], axis=1)
    if relation == "rot":
        return np.linalg.norm(e[:, :3, :3] - np.eye(3), axis=(1, 2))
    if relation == "full":
        return np.linalg.norm(e - np.eye(4), axis=(1, 2))
    angle = lie.rotation_angle(e[:, :3, :3])
    return np.degrees(angle) if relation == "angle_deg" else angle
