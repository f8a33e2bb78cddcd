"""Shared test set-up: numba's cache keyed on the package sources, a check that the compiled
kernels are built from the current sources, and the common benchmark dataset (built once,
cached; see ``benchdata.py``)."""
import os
import sys

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


def pytest_sessionstart(session):
    import photogrammetry
    from ins.common.native_build import stale_kernels
    stale = stale_kernels() + stale_kernels(os.path.dirname(photogrammetry.__file__))
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
