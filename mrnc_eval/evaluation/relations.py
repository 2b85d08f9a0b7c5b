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


def error_values(rot: NDArray[np.float64], trans: NDArray[np.float64], relation: str) -> NDArray[np.float64]:
    """Scalar error of each error pose E = [rot, trans] ((N, 3, 3) and (N, 3))."""
    if relation in ("trans", "point"):
        return np.linalg.norm(trans, axis=1)
    if relation == "rot":  # |R_E - I|_F = 2 sqrt(2) sin(theta / 2)
        return np.linalg.norm(rot - np.eye(3), axis=(1, 2))
    if relation == "full":  # |E - I_4|_F: mixes metres and radians, as evo
        d = rot - np.eye(3)
        return np.sqrt(np.einsum("nij,nij->n", d, d) + np.einsum("ni,ni->n", trans, trans))
    angle = lie.rotation_angle(rot)
    return np.degrees(angle) if relation == "angle_deg" else angle
