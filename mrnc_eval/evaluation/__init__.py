"""Trajectory and control evaluation (pure numpy)."""
