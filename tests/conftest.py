"""Shared fixtures: the common benchmark dataset (built once, cached)."""
import pytest

from benchdata import SHARED, ensure_bench_data


@pytest.fixture(scope="session")
def bench_data():
    path = ensure_bench_data()
    if path is None:
        pytest.skip(f"shared benchmark script not found under {SHARED} (set INS_SHARED_DIR)")
    return path
