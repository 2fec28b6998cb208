"""The one compiled part of the package, the banded LU of numerics/bordered.py (its C file
says why; docs/design.md, "Module layout"). Everything else is declared in pyproject.toml.

One C file on Python's buffer protocol (no numpy headers at build time), built without fused
multiply-add (``-ffp-contract=off``, gcc and clang) so that its results are the same bits on
every machine."""

import sysconfig

from setuptools import Extension, setup

flags = [] if sysconfig.get_platform().startswith("win") else ["-ffp-contract=off"]

setup(ext_modules=[Extension("elastica_auto.numerics._banded",
                             sources=["elastica_auto/numerics/_banded.c"],
                             extra_compile_args=flags)])
