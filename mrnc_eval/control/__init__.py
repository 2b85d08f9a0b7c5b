"""Control chain: pure pursuit, skid-steer inverse kinematics, per-side controllers, plant."""

from mrnc_eval.control.jit_cache import ensure_consistent_cache

ensure_consistent_cache()
