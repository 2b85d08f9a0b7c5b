"""The C extensions: the fast reader of TUM/KITTI text (mrnc_eval/io/_numtext.c, used by
io/number_table.py), APE's one-pass loops (mrnc_eval/geometry/_kernels.c, used by
geometry/point_fit.py and evaluation/ape.py), the SLAM's per-sweep preparation
(mrnc_eval/slam/_prep_kernels.c: range image, deskew, features, gyro track), scan-to-map
(mrnc_eval/slam/_match_kernels.c: map search, fits, rows) and the sweep stream's
point gather (mrnc_eval/io/_cloud.c; numpy gives the same arrays without it). Everything else is
declared in pyproject.toml. Optional: without a C compiler the package installs, reads every text
file through the strict pandas path (2-3x slower) and aligns with numpy (the same bits, ~0.1 s more
for 1e6 poses); `slam` and `nightly` then stop at once and say how to build the SLAM's kernels
(mrnc_eval/extras.py)."""

from setuptools import Extension, setup

setup(ext_modules=[
    Extension("mrnc_eval.io._numtext", ["mrnc_eval/io/_numtext.c"], optional=True),
    # APE's alignment sums and aligned distances in one pass; each operation must round on its own
    Extension("mrnc_eval.geometry._kernels", ["mrnc_eval/geometry/_kernels.c"], optional=True,
              extra_compile_args=["-ffp-contract=off"]),
    # the SLAM's range image, deskew, features and gyro track: numba's arithmetic, operation by operation
    Extension("mrnc_eval.slam._prep_kernels", ["mrnc_eval/slam/_prep_kernels.c"], optional=True,
              extra_compile_args=["-ffp-contract=off"]),
    # scan-to-map's map search, fits and rows (slam/scan_to_map.py), the numba kernels' arithmetic and bits
    Extension("mrnc_eval.slam._match_kernels", ["mrnc_eval/slam/_match_kernels.c"], optional=True,
              extra_compile_args=["-ffp-contract=off"]),
    # the sweep stream's point gather (io/pointcloud.py; without it numpy gives the same arrays)
    Extension("mrnc_eval.io._cloud", ["mrnc_eval/io/_cloud.c"], optional=True,
              extra_compile_args=["-ffp-contract=off"]),
])
