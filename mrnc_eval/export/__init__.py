"""Exports of results into files other tools open: MCAP with Foxglove schemas (Foxglove, Lichtblick)."""
