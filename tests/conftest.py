"""Shared fixtures: paths and the common benchmark dataset (built once, cached)."""
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("INS_SHARED_DIR", ROOT.parent / "shared"))
BENCH_DATA = Path(os.environ.get("INS_BENCH_DATA", ROOT / ".cache" / "ins-bench-data"))


def ensure_bench_data():
    """Build the shared benchmark dataset with its own (independent) simulator, once."""
    marker = BENCH_DATA / "meta.json"
    if marker.exists():
        return BENCH_DATA
    script = SHARED / "bench" / "ins" / "make_dataset.py"
    if not script.exists():
        pytest.skip(f"shared benchmark script not found at {script} (set INS_SHARED_DIR)")
    BENCH_DATA.parent.mkdir(parents=True, exist_ok=True)
    tmp = BENCH_DATA.with_name(BENCH_DATA.name + ".part")
    subprocess.run([sys.executable, str(script), "--out", str(tmp)], check=True,
                   stdout=subprocess.DEVNULL)
    os.replace(tmp, BENCH_DATA)
    return BENCH_DATA


@pytest.fixture(scope="session")
def bench_data():
    return ensure_bench_data()
