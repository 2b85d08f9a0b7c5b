"""Pose relations: how an error pose (or a pair of poses) becomes one number."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from mrnc_eval.evaluation.modes import Relation, parse_choice
from mrnc_eval.geometry import lie

UNITS = {Relation.trans: "m", Relation.point: "m", Relation.rot: "", Relation.full: "",
         Relation.angle_deg: "deg", Relation.angle_rad: "rad"}
TITLES = {Relation.trans: "translation part", Relation.point: "point distance", Relation.rot: "rotation part",
          Relation.full: "full transformation", Relation.angle_deg: "rotation angle in degrees",
          Relation.angle_rad: "rotation angle in radians"}


def check_relation(relation: Relation | str) -> Relation:
    return parse_choice(Relation, relation, "pose relation")


def error_values(rot: NDArray[np.float64], trans: NDArray[np.float64], relation: Relation | str) -> NDArray[np.float64]:
    """Scalar error of each error pose E = [rot, trans] ((N, 3, 3) and (N, 3))."""
    relation = check_relation(relation)
    if relation in (Relation.trans, Relation.point):
        e: NDArray[np.float64] = np.linalg.norm(trans, axis=1)
    elif relation is Relation.rot:  # |R_E - I|_F = 2 sqrt(2) sin(theta / 2)
        e = np.linalg.norm(rot - np.eye(3), axis=(1, 2))
    elif relation is Relation.full:  # |E - I_4|_F: mixes metres and radians, as evo
        d = rot - np.eye(3)
        e = np.sqrt(np.einsum("nij,nij->n", d, d) + np.einsum("ni,ni->n", trans, trans))
    else:
        angle = lie.rotation_angle(rot)
        e = np.degrees(angle) if relation is Relation.angle_deg else angle
    return e
