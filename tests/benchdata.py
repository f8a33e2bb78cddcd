"""Test caches keyed on the code they depend on: the shared GNSS/INS benchmark dataset and
the simulated test flights.

- The shared dataset is made by ``../shared/bench/ins/make_dataset.py`` with pyins's
  simulator (an independent implementation; needs the ``test`` or ``bench`` extras) and
  cached in ``.cache/ins-bench-data`` (about 190 MB, 10 s).  It depends on that script's
  folder and on pyins / numpy / pandas, not on this project: :func:`bench_key` hashes
  those, the key is stored in the folder, and a different key rebuilds it.
  ``INS_SHARED_DIR`` and ``INS_BENCH_DATA`` override the two locations (a dataset given
  by ``INS_BENCH_DATA`` is used as it is when it carries no key).
- A simulated test flight depends on the simulator and everything it imports:
  :func:`source_hash` hashes every ``.py``, ``.pyx`` and ``.pxd`` under ``ins/`` and
  ``photogrammetry/`` (path and bytes) with the numpy/scipy versions, and
  :func:`flight_key` adds the plan text and the seed, so any code change simulates the
  flight again.  (The compiled kernels themselves are checked against their sources by
  ``conftest.py``: :func:`ins.common.native_build.stale_kernels`.)

Old entries are pruned (:func:`prune`): the most recently used few are kept, and none
used within the last hour (another test run may be reading it).
"""
import fcntl
import functools
import hashlib
import os
import shutil
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CACHE = ROOT / ".cache"
SHARED = Path(os.environ.get("INS_SHARED_DIR", ROOT.parent / "shared"))
BENCH_DATA = Path(os.environ.get("INS_BENCH_DATA", CACHE / "ins-bench-data"))
PACKAGES = ("ins", "photogrammetry")
KEY_FILE = "cache-key.txt"
#: Entries used within this many seconds are never pruned.
PRUNE_GRACE_S = 3600.0


def _versions(*modules):
    from importlib import metadata
    out = [f"python={sys.version_info[:3]}"]
    for name in modules:
        try:
            out.append(f"{name}={metadata.version(name)}")
        except metadata.PackageNotFoundError:
            out.append(f"{name}=none")
    return out


@functools.lru_cache(maxsize=1)
def source_hash():
    """sha256 (hex) of every ``.py``, ``.pyx`` and ``.pxd`` under ``ins/`` and
    ``photogrammetry/`` (relative path and bytes, sorted) and the numpy / scipy versions."""
    h = hashlib.sha256()
    for line in _versions("numpy", "scipy"):
        h.update(line.encode() + b"\n")
    for pkg in PACKAGES:
        for path in sorted(p for suffix in ("*.py", "*.pyx", "*.pxd")
                           for p in (ROOT / pkg).rglob(suffix)):
            h.update(path.relative_to(ROOT).as_posix().encode() + b"\0")
            h.update(path.read_bytes() + b"\0")
    return h.hexdigest()


def flight_key(plan_text, seed):
    """Cache key (12 hex) of a simulated flight: plan text, seed and :func:`source_hash`."""
    return hashlib.sha256(f"{plan_text}|{seed}|{source_hash()}".encode()).hexdigest()[:12]


def bench_key(script_dir=None):
    """Key (hex) of the shared dataset: the generator's folder (its ``.py`` files) and the
    versions of the packages it runs on."""
    script_dir = Path(script_dir or SHARED / "bench" / "ins")
    h = hashlib.sha256()
    for line in _versions("python-ins", "numpy", "pandas"):
        h.update(line.encode() + b"\n")
    for path in sorted(script_dir.glob("*.py")):
        h.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()[:16]


@contextmanager
def _locked(path):
    """An exclusive advisory lock on ``path`` (created), for concurrent test runs."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def touch(path):
    """Mark a cache entry as used now (its mtime is the pruning clock)."""
    try:
        os.utime(path)
    except OSError:
        pass


def prune(folder, pattern, keep, exclude=()):
    """Delete the folders ``folder/pattern`` beyond the ``keep`` most recently used ones
    (by mtime), sparing any used within :data:`PRUNE_GRACE_S` and those in ``exclude``."""
    folder = Path(folder)
    if not folder.is_dir():
        return
    entries = sorted((p for p in folder.glob(pattern) if p.is_dir()),
                     key=lambda p: p.stat().st_mtime, reverse=True)
    now = time.time()
    exclude = {Path(p).resolve() for p in exclude}
    for p in entries[keep:]:
        if p.resolve() in exclude or now - p.stat().st_mtime < PRUNE_GRACE_S:
            continue
        shutil.rmtree(p, ignore_errors=True)


def ensure_bench_data():
    """The dataset's folder, built first if missing or made by another generator;
    None when the shared script is missing."""
    key_path = BENCH_DATA / KEY_FILE
    script = SHARED / "bench" / "ins" / "make_dataset.py"

    def current():
        if not (BENCH_DATA / "meta.json").exists():
            return False
        if not key_path.exists():                    # a user-given dataset: as it is
            return "INS_BENCH_DATA" in os.environ
        return not script.exists() or key_path.read_text().strip() == bench_key()

    if current():
        return BENCH_DATA
    if not script.exists():
        return None
    with _locked(BENCH_DATA.with_name(BENCH_DATA.name + ".lock")):
        if current():                                # built meanwhile by another run
            return BENCH_DATA
        key = bench_key()
        tmp = BENCH_DATA.with_name(f"{BENCH_DATA.name}.part{os.getpid()}")
        old = BENCH_DATA.with_name(f"{BENCH_DATA.name}.old{os.getpid()}")
        shutil.rmtree(tmp, ignore_errors=True)
        try:
            subprocess.run([sys.executable, str(script), "--out", str(tmp)], check=True,
                           stdout=subprocess.DEVNULL)
            (tmp / KEY_FILE).write_text(key + "\n")
            if BENCH_DATA.exists():
                os.replace(BENCH_DATA, old)
            os.replace(tmp, BENCH_DATA)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
            shutil.rmtree(old, ignore_errors=True)
    return BENCH_DATA


def cached_flight(folder_base, plan_text, seed, simulate):
    """Folder of a simulated test flight keyed by :func:`flight_key`, simulated with
    ``simulate(plan_path, folder, seed)`` when missing; older flights are pruned.

    Parameters
    ----------
    folder_base : Path
        The cache folder (e.g. ``.cache/ins-test-flights``).
    plan_text : str
        The flight plan (TOML text); written beside the folder as ``short-<key>.toml``.
    seed : int
    simulate : callable
        ``simulate(plan_path, folder, seed)`` writes the flight folder.
    """
    folder_base = Path(folder_base)
    key = flight_key(plan_text, seed)
    folder = folder_base / f"short-{key}"
    if not (folder / "manifest.toml").exists():
        folder_base.mkdir(parents=True, exist_ok=True)
        with _locked(folder_base / f"short-{key}.lock"):
            if not (folder / "manifest.toml").exists():
                plan_path = folder_base / f"short-{key}.toml"
                plan_path.write_text(plan_text)
                simulate(plan_path, folder, seed)
    touch(folder)
    prune(folder_base, "short-*", keep=6, exclude=[folder])
    now = time.time()
    for p in list(folder_base.glob("short-*.toml")) + list(folder_base.glob("short-*.lock")):
        try:                                         # plans and locks of pruned flights
            if (not (folder_base / p.stem).exists()
                    and now - p.stat().st_mtime > PRUNE_GRACE_S):
                p.unlink()
        except OSError:
            pass
    return folder
