"""The names inside a result folder: the keys of `result.json`'s extra and the series of
`series.npz`, one module per domain (`slam`, `control`). The commands write through these names
and the readers (reports/render.py, reports/figures.py, export/topics.py, commands/export.py,
commands/table.py) read through them, so a renamed series is renamed for both;
tests/test_result_schema.py fails when a reader uses a name no command writes."""
