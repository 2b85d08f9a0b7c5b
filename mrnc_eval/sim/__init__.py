"""Synthetic SSWMR recordings with exact ground truth."""
