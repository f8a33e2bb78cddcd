"""Build of the compiled kernels (Cython): every ``*.pyx`` under ``ins/`` and
``photogrammetry/`` becomes an extension module of the same dotted name.

Why compiled ahead of time rather than numba for these: ``ins process`` must start
and run in a small memory (numba and llvmlite alone hold about 90 MiB and take about
a second to load their cached machine code), so the kernels on its path are C built
at install time.  numba stays for the kernels of the other commands.

Flags: ``-O3``; ``-ffp-contract=off`` keeps every product and sum rounded as written
(no fused multiply-add), which the exact decimal parsing and formatting (Dekker's
two-product) and the reproducibility of the filter rely on.
"""
from pathlib import Path

from Cython.Build import cythonize
from setuptools import Extension, setup

ROOT = Path(__file__).resolve().parent
SOURCES = sorted(p.relative_to(ROOT).as_posix()
                 for pkg in ("ins", "photogrammetry") for p in (ROOT / pkg).rglob("*.pyx"))
FLAGS = ["-O3", "-ffp-contract=off"]
EXTENSIONS = [Extension(src[:-len(".pyx")].replace("/", "."), [src], extra_compile_args=FLAGS)
              for src in SOURCES]
DIRECTIVES = {"language_level": 3, "boundscheck": False, "wraparound": False,
              "cdivision": True, "initializedcheck": False, "embedsignature": True}

setup(ext_modules=cythonize(EXTENSIONS, compiler_directives=DIRECTIVES, quiet=True))
