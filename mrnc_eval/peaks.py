"""Sub-sample refinement of an extremum found on a uniform grid."""

from __future__ import annotations


def parabola_vertex(before: float, at: float, after: float) -> float:
    """Offset of the vertex, in grid steps from the middle sample, of the parabola through three
    equally spaced samples; within +-0.5 when the middle one is the grid's minimum or maximum.
    0 when the three are collinear (no curvature to refine with)."""
    curvature = before - 2.0 * at + after
    return 0.5 * (before - after) / curvature if curvature != 0 else 0.0
