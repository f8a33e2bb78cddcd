"""Build of the compiled kernels (Cython): every ``*.pyx`` under ``ins/`` and
``photogrammetry/`` becomes an extension module of the same dotted name.

Why compiled ahead of time (the kernels were numba until issues 26 and 35): every command
must start and run in a small memory, and its first run must be as fast as the next
(numba and llvmlite alone held about 90 MiB, took about a second to load their cached
machine code, and the first run of the demo spent about 18 s compiling it).  The kernels
of the coplanarity adjustment call scipy's BLAS and LAPACK through
``scipy.linalg.cython_blas`` / ``cython_lapack`` (declarations only: no include path).

Flags: ``-O3``; ``-ffp-contract=off`` keeps every product and sum rounded as written
(no fused multiply-add), which the exact decimal parsing and formatting (Dekker's
two-product) and the reproducibility of the filter rely on.
"""
from pathlib import Path

from Cython.Build import cythonize
from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = Path(__file__).resolve().parent
#: Compiler flags by compiler family: optimized, every product and sum rounded as written.
FLAGS = {"msvc": ["/O2", "/fp:precise"], "other": ["-O3", "-ffp-contract=off"]}
DIRECTIVES = {"language_level": 3, "boundscheck": False, "wraparound": False,
              "cdivision": True, "initializedcheck": False, "embedsignature": True}


def extensions():
    """The extension modules, Cython-translated (paths relative to this folder)."""
    sources = sorted(p.relative_to(ROOT).as_posix()
                     for pkg in ("ins", "photogrammetry") for p in (ROOT / pkg).rglob("*.pyx"))
    exts = [Extension(src[:-len(".pyx")].replace("/", "."), [src]) for src in sources]
    return cythonize(exts, compiler_directives=DIRECTIVES, quiet=True)


class BuildKernels(build_ext):
    """build_ext with :data:`FLAGS` for the compiler in use (gcc/clang or MSVC)."""

    def build_extensions(self):
        flags = FLAGS.get(self.compiler.compiler_type, FLAGS["other"])
        for ext in self.extensions:
            ext.extra_compile_args = list(flags)
        super().build_extensions()


def build_inplace():
    """Build the extensions in place without the package's metadata (tools/mutate.py's
    scratch copies, with whatever setuptools the environment has)."""
    from setuptools import Distribution
    dist = Distribution({"name": "kernels", "ext_modules": extensions(),
                         "cmdclass": {"build_ext": BuildKernels}})
    dist.script_args = ["-q", "build_ext", "--inplace"]
    dist.parse_command_line()
    dist.run_commands()


if __name__ == "__main__":        # also how setuptools' build backend runs this file
    setup(ext_modules=extensions(), cmdclass={"build_ext": BuildKernels})
