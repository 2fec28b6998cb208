"""The compiled parts of the package: the banded LU of numerics/bordered.py and the direct
count's block work of numerics/stability.py (each C file says why; docs/design.md, "Module
layout"). Everything else is declared in pyproject.toml.

Each is one C file on Python's buffer protocol (no numpy headers at build time; the two that
read float64 arrays share elastica_auto/_buffers.h, a dependency of each, which is also what puts
it in the sdist), built without fused
multiply-add (``-ffp-contract=off``, gcc and clang) so that its results are the same bits on
every machine.

A build that cannot compile or link it (no C compiler, no Python headers) ends with one line
saying what the install needs, after the compiler's own output, instead of only setuptools'
"command ... returned non-zero exit status 1"."""

import sysconfig

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext
from setuptools.errors import CCompilerError, PlatformError

NEEDS = ("elastica-auto: building its C extension ({}) failed: the install needs a C compiler "
         "and Python's headers (on Debian: apt-get install gcc python3-dev); "
         "see docs/getting-started.md, Install")


class BuildExt(build_ext):
    def build_extension(self, ext):
        try:
            super().build_extension(ext)
        except (CCompilerError, PlatformError) as exc:
            raise CCompilerError(f"{exc}\n{NEEDS.format(', '.join(ext.sources))}") from exc


flags = [] if sysconfig.get_platform().startswith("win") else ["-ffp-contract=off"]

setup(ext_modules=[Extension(f"elastica_auto.{package}.{name}",
                             sources=[f"elastica_auto/{package}/{name}.c"],
                             depends=["elastica_auto/_buffers.h"],
                             extra_compile_args=flags)
                   for package, name in (("numerics", "_banded"), ("numerics", "_blocks"),
                                         ("energy", "_frames"))],
      cmdclass={"build_ext": BuildExt})
