"""Shared test set-up: a check that the compiled kernels are built from the current
sources, and the common benchmark dataset (built once, cached; see ``benchdata.py``)."""
import os

import pytest
from benchdata import SHARED, ensure_bench_data


def pytest_sessionstart(session):
    import photogrammetry
    from ins.common.native_build import stale_kernels
    stale = stale_kernels() + stale_kernels(os.path.dirname(photogrammetry.__file__))
    if stale:
        pytest.exit(f"compiled kernels not built from their current sources: "
                    f"{', '.join(stale)}; rebuild them (make .venv/.test-deps, or "
                    f"pip install -e .)", returncode=2)


@pytest.fixture(scope="session")
def bench_data():
    path = ensure_bench_data()
    if path is None:
        pytest.skip(f"shared benchmark script not found under {SHARED} (set INS_SHARED_DIR)")
    return path
