"""Build the optional C kernels; imupipe falls back to NumPy where no compiler is available."""

import sys

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext


class OptionalBuildExt(build_ext):
    """Compile ``imupipe._kernels`` if possible, warn and go on otherwise."""

    def build_extension(self, ext):
        try:
            super().build_extension(ext)
        except Exception as exc:  # no compiler, no headers: the NumPy path is used
            print(f"WARNING: optional extension {ext.name} not built ({exc}); using the NumPy path", file=sys.stderr)


setup(
    ext_modules=[
        Extension("imupipe._kernels", ["src/imupipe/_kernels.c"], extra_compile_args=["-O3"], optional=True)
    ],
    cmdclass={"build_ext": OptionalBuildExt},
)
