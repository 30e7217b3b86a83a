"""Build of the compiled physics kernels (the rest of the metadata is in pyproject.toml).

``pip install .`` compiles ``servo_toolkit/_physics`` (C99 and one Cython module) with the
system's C compiler; ``pip install -e .`` builds it in place, and rebuilding after editing a
kernel is ``pip install -e .`` again (or ``python setup.py build_ext --inplace``).
"""

import sys
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

HERE = Path(__file__).parent
PHYSICS = Path("servo_toolkit") / "_physics"

#: what a machine without a working C compiler is told, in one line
NO_COMPILER = ("servo_toolkit: building the physics kernels needs a C compiler (gcc or clang; on Windows the "
               "MSVC Build Tools): install one and run pip again, or install a prebuilt wheel")

if sys.platform == "win32":
    FLAGS = ["/O2", "/fp:precise"]
else:
    # C99, optimized; errno is never read, so the math library may be inlined; IEEE semantics
    # otherwise (a non-finite state must stay detectable)
    FLAGS = ["-std=c99", "-O3", "-fno-math-errno", "-Wall", "-Wno-unused-function", "-Wno-unreachable-code"]


class BuildKernels(build_ext):
    """build_ext that says in one line what is missing when there is no compiler."""

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
