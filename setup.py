"""The package's one compiled part: the criticality record's per-vehicle arithmetic (sdl_fmu/cosim/_kernel.c),
an optional extension. Everything else is in pyproject.toml.

Optional: where it cannot be built (no C compiler, no Python headers), pip installs the package without it and
sdl_fmu.cosim.extremes runs the same arithmetic in Python, to the same bits (docs/decisions.md: "the criticality
kernel"). -ffp-contract=off: no multiply-add is fused (aarch64's gcc fuses by default), so that every operation
rounds as Python's does."""

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext


class BuildKernel(build_ext):
    def build_extensions(self):
        if self.compiler.compiler_type in ("unix", "mingw32", "cygwin"):
            for extension in self.extensions:
                extension.extra_compile_args = ["-O2", "-ffp-contract=off", "-fno-fast-math"]
        else:  # MSVC: /fp:precise (its default) contracts nothing
            for extension in self.extensions:
                extension.extra_compile_args = ["/O2", "/fp:precise"]
        super().build_extensions()


setup(ext_modules=[Extension("sdl_fmu.cosim._kernel", ["sdl_fmu/cosim/_kernel.c"], optional=True)],
      cmdclass={"build_ext": BuildKernel})
