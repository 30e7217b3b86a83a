"""Build of the compiled physics kernels (the rest of the metadata is in pyproject.toml).

``pip install .`` compiles ``servo_toolkit/_physics`` (C99 and one Cython module) with the
system's C compiler; ``pip install -e .`` builds it in place, and rebuilding after editing a
kernel is ``pip install -e .`` again (or ``python setup.py build_ext --inplace``).
"""

import os
import sys
import tempfile
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

HERE = Path(__file__).parent
PHYSICS = Path("servo_toolkit") / "_physics"

#: what a machine without a working C compiler is told, in one line
NO_COMPILER = ("servo_toolkit: building the physics kernels needs a C compiler (gcc or clang; on Windows the "
               "MSVC Build Tools): install one and run pip again, or install a prebuilt wheel")

if sys.platform == "win32":
    FLAGS = ["/O2", "/fp:fast"]
else:
    # C99, optimized, with the floating-point licence of the right-hand side: sums may be
    # reassociated and contracted, divisions taken as products by a reciprocal, signed zeros
    # ignored, errno never read; NaN and infinity keep their meaning (a non-finite state must
    # stay detectable: -fno-finite-math-only)
    FLAGS = ["-std=c99", "-O3", "-ffast-math", "-fno-finite-math-only", "-Wall", "-Wno-unused-function",
             "-Wno-unreachable-code"]
#: the instruction set: ``native`` (the default) compiles for the building machine's processor, as
#: a just-in-time compiler would; ``portable`` (wheels for a package index: cibuildwheel sets it)
#: for the platform's baseline. Environment variable SERVO_TOOLKIT_CPU.
CPU = os.environ.get("SERVO_TOOLKIT_CPU", "native")


class BuildKernels(build_ext):
    """build_ext that says in one line what is missing when there is no compiler, and compiles
    for the building processor when its compiler can (:data:`CPU`)."""

    def build_extensions(self):
        if self.compiler.compiler_type == "unix":
            # the fixed-step loop is scalar code: packing its pairs of doubles into vectors
            # costs it about 5 % (gcc's straight-line vectorizer)
            wanted = ["-fno-tree-slp-vectorize"] + (["-march=native"] if CPU == "native" else [])
            extra = [flag for flag in wanted if self._accepts(flag)]
            for ext in self.extensions:
                ext.extra_compile_args = [*ext.extra_compile_args, *extra]
        super().build_extensions()

    def _accepts(self, flag: str) -> bool:
        """Whether the compiler compiles an empty C file with ``flag``."""
        with tempfile.TemporaryDirectory() as folder:
            source = Path(folder) / "probe.c"
            source.write_text("int main(void) { return 0; }\n")
            try:
                self.compiler.compile([str(source)], output_dir=folder, extra_postargs=[flag, "-Werror"])
            except Exception:
                return False
        return True

    def run(self):
        try:
            super().run()
        except Exception as exc:  # distutils' CompileError, CCompilerError, PlatformError
            if type(exc).__name__ in ("CompileError", "CCompilerError", "DistutilsPlatformError",
                                      "PlatformError", "DistutilsExecError", "LinkError"):
                raise SystemExit(f"{NO_COMPILER} ({type(exc).__name__}: {exc})") from None
            raise


def kernel_sources():
    sources = [str(PHYSICS / "_kernels.pyx")]
    sources += sorted(str(p.relative_to(HERE)) for p in (HERE / PHYSICS).glob("api_*.c"))
    return sources


setup(
    ext_modules=[Extension(
        "servo_toolkit._physics._kernels",
        sources=kernel_sources(),
        depends=sorted(str(p.relative_to(HERE)) for p in (HERE / PHYSICS).glob("*.[hp]*")),
        include_dirs=[str(PHYSICS)],
        extra_compile_args=FLAGS,
        libraries=[] if sys.platform == "win32" else ["m"],
    )],
    cmdclass={"build_ext": BuildKernels},
)
