"""The one C extension: the fast reader of TUM/KITTI text (mrnc_eval/io/_numtext.c, used by
io/number_table.py). Everything else is declared in pyproject.toml. Optional: without a C compiler
the package installs and reads every text file through the strict pandas path (2-3x slower)."""

from setuptools import Extension, setup

setup(ext_modules=[Extension("mrnc_eval.io._numtext", ["mrnc_eval/io/_numtext.c"], optional=True)])
