"""The compiled parts of the package: the banded LU of numerics/bordered.py and the direct
count's block work of numerics/stability.py (each C file says why; docs/design.md, "Module
layout"). Everything else is declared in pyproject.toml.

Each is one C file on Python's buffer protocol (no numpy headers at build time), built without fused
multiply-add (``-ffp-contract=off``, gcc and clang) so that its results are the same bits on
every machine."""

import sysconfig

from setuptools import Extension, setup

flags = [] if sysconfig.get_platform().startswith("win") else ["-ffp-contract=off"]

setup(ext_modules=[Extension(f"elastica_auto.numerics.{name}",
                             sources=[f"elastica_auto/numerics/{name}.c"],
                             extra_compile_args=flags)
                   for name in ("_banded", "_blocks")])
