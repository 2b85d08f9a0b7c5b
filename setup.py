"""The C extensions: the fast reader of TUM/KITTI text (mrnc_eval/io/_numtext.c, used by
io/number_table.py) and APE's one-pass loops (mrnc_eval/geometry/_kernels.c, used by
geometry/point_fit.py and evaluation/ape.py). Everything else is declared in pyproject.toml.
Optional: without a C compiler the package installs, reads every text file through the strict
pandas path (2-3x slower) and aligns with numpy (the same bits, ~0.1 s more for 1e6 poses)."""

from setuptools import Extension, setup

setup(ext_modules=[
    Extension("mrnc_eval.io._numtext", ["mrnc_eval/io/_numtext.c"], optional=True),
    # APE's alignment sums and aligned distances in one pass; each operation must round on its own
    Extension("mrnc_eval.geometry._kernels", ["mrnc_eval/geometry/_kernels.c"], optional=True,
              extra_compile_args=["-ffp-contract=off"]),
    # scan-to-map matching's fits and rows (slam/scan_to_map.py), the numba kernels' arithmetic and bits
    Extension("mrnc_eval.slam._match_kernels", ["mrnc_eval/slam/_match_kernels.c"],
              extra_compile_args=["-ffp-contract=off"]),
])
