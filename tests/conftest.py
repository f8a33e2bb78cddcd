"""Shared test set-up: numba's cache keyed on the package sources, a check that the compiled
kernels are built from the current sources, and the common benchmark dataset (built once,
cached; see ``benchdata.py``)."""
import os
import re
import sys
from pathlib import Path

import benchdata

# numba's on-disk cache is invalidated only by the timestamp of the file that defines a
# kernel, not by a change in a function or constant it calls from another module: a
# stale cache let a gravity change in ins/nav/earth.py pass the shared-dataset test.  Point
# it at a folder per hash of every ins/ and photogrammetry/ source, before numba is
# imported (subprocesses of the tests inherit the variable).  INS_TEST_NUMBA_CACHE=keep
# leaves numba's own setting alone.
if os.environ.get("INS_TEST_NUMBA_CACHE") != "keep":
    _NUMBA_DIR = str(benchdata.numba_cache_dir())
    os.environ["NUMBA_CACHE_DIR"] = _NUMBA_DIR
    if "numba" in sys.modules:                         # imported early by a plugin
        from numba.core import config as _numba_config
        _numba_config.CACHE_DIR = _NUMBA_DIR

import pytest  # noqa: E402
from benchdata import SHARED, ensure_bench_data  # noqa: E402

_ROOT = Path(__file__).resolve().parents[1]
_CIMPORT = re.compile(r"^\s*(?:from\s+([\w.]+)\s+cimport\s+(\w+)|cimport\s+([\w.]+))", re.M)


def _pxd_deps(path, seen):
    """The ``.pxd`` files that ``path`` cimports from the packages, recursively."""
    for m in _CIMPORT.finditer(path.read_text()):
        for dotted in ((f"{m.group(1)}.{m.group(2)}", m.group(1)) if m.group(1)
                       else (m.group(3),)):
            pxd = _ROOT.joinpath(*dotted.split(".")).with_suffix(".pxd")
            if pxd.is_file() and pxd not in seen:
                seen.add(pxd)
                _pxd_deps(pxd, seen)
                break
    return seen


def stale_kernels():
    """Compiled kernels (``.pyx``) whose built module is missing or older than the
    ``.pyx`` or a ``.pxd`` it cimports: the tests would run old code."""
    stale = []
    for top in ("ins", "photogrammetry"):
        for pyx in sorted((_ROOT / top).rglob("*.pyx")):
            built = sorted(pyx.parent.glob(pyx.stem + ".*.so"))
            newest = max(p.stat().st_mtime for p in _pxd_deps(pyx, {pyx}))
            if not built or built[-1].stat().st_mtime < newest:
                stale.append(pyx.relative_to(_ROOT).as_posix())
    return stale


def pytest_sessionstart(session):
    stale = stale_kernels()
    if stale:
        pytest.exit(f"compiled kernels not built from their current sources: "
                    f"{', '.join(stale)}; rebuild them (make .venv/.test-deps, or "
                    f"pip install -e .)", returncode=2)


def pytest_report_header(config):
    return [f"numba cache: {os.environ.get('NUMBA_CACHE_DIR', '(numba default)')}"]


@pytest.fixture(scope="session")
def bench_data():
    path = ensure_bench_data()
    if path is None:
        pytest.skip(f"shared benchmark script not found under {SHARED} (set INS_SHARED_DIR)")
    return path
