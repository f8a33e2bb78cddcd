"""Location and one-time build of the shared GNSS/INS benchmark dataset.

The dataset is made by ``../shared/bench/ins/make_dataset.py`` with pyins's simulator
(an independent implementation; needs the ``test`` or ``bench`` extras) and cached in
``.cache/ins-bench-data`` (about 190 MB, 10 s).  ``INS_SHARED_DIR`` and
``INS_BENCH_DATA`` override the two locations.
"""
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("INS_SHARED_DIR", ROOT.parent / "shared"))
BENCH_DATA = Path(os.environ.get("INS_BENCH_DATA", ROOT / ".cache" / "ins-bench-data"))


def ensure_bench_data():
    """The dataset's folder, built first if needed; None when the shared script is missing."""
    if (BENCH_DATA / "meta.json").exists():
        return BENCH_DATA
    script = SHARED / "bench" / "ins" / "make_dataset.py"
    if not script.exists():
        return None
    BENCH_DATA.parent.mkdir(parents=True, exist_ok=True)
    tmp = BENCH_DATA.with_name(BENCH_DATA.name + ".part")
    subprocess.run([sys.executable, str(script), "--out", str(tmp)], check=True,
                   stdout=subprocess.DEVNULL)
    os.replace(tmp, BENCH_DATA)
    return BENCH_DATA
