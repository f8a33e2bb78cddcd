"""Text I/O: our compiled (Cython) table reader/formatter against the well-kept libraries (issue 13).

Reads the shared benchmark's IMU log (302 001 lines x 7 columns, 48 MB of text, 18-digit
numbers) and GNSS log with:
- ours: ``ins.common.textfiles.read_table`` (whole table, blocks of 16 MiB) and ``iter_table``
  (streaming);
- pandas' C engine (``float_precision="round_trip"`` before pandas 3, the default
  since), whole and in chunks;
- ``pyarrow.csv`` (whole, and its streaming reader);
- ``numpy.loadtxt`` (C implementation since numpy 1.23).
For each: the warm wall time (best of N), whether every value is bit-identical to the
correctly rounded value (Python's ``float()`` on the same text), and, on a copy of the log
with one bad field at 80 % of the file, the time to fail and whether the message names the
line.  Writing: our fixed-point formatter against ``numpy.savetxt`` and pandas ``to_csv``
with the same decimals.

Also: each streaming reader in a background thread beside GIL-holding work in the main
thread (the layout of ``ins process``, whose IMU reader thread runs beside the filter),
and with ``--process`` whole ``ins process --no-plots`` runs with our reader and with
pandas' C engine in chunks put in its place.

Measured (issue 13 item 4; pandas 3.1.1, 2 cores shared with other jobs, load ~3, warm,
best of 3; IMU log 47.7 MB, 302 001 x 7):

=================================  ========  =====  ===========================================
reader                             time s    exact  bad field at line 241 601 (80 %)
=================================  ========  =====  ===========================================
ours read_table                    0.121     yes    0.19 s, names the file, line and field
ours iter_table (stream)           0.112     yes    0.15 s, names the file, line and field
pandas C, sep=" "                  0.060     yes    0.45 s, "could not convert string to
                                                    float: '1.2.3'" (no line)
pandas C, whitespace sep, comment  0.131     yes    (``sep=r"\\s+", comment="#"``: the options
                                                    our files need; commas as well need the
                                                    Python engine: ~1.7 s, from 30 000 rows)
pandas C chunks (stream)           0.097     yes    0.21 s, no line
pyarrow.csv                        0.145     yes    0.38 s, ACCEPTED the bad field silently
pyarrow.csv open_csv (stream)      0.146     yes    0.15 s, no line
numpy.loadtxt                      0.888     yes    0.88 s, row and column (blanks only)
=================================  ========  =====  ===========================================

Writing 302 001 x 10 values, decimals per column: ours ``format_fixed`` 0.113 s,
``numpy.savetxt`` 1.165 s (same bytes), pandas ``to_csv`` 2.80 s (one decimals for all
columns only).  ``import pandas`` costs 0.32 s in a fresh process.

Reader thread beside GIL-holding work (main-thread rate against alone): ours 0.57,
pandas chunks 0.67, pyarrow stream 0.67, pandas whole 0.61: about the same with every
reader (on 2 cores loaded by other jobs the loss is mostly CPU contention; our kernel is
``nogil``), so the thread layout gives no library an edge.

Whole ``ins process --no-plots`` on the shared dataset (median of 3 after a warm-up):
ours 2.91 s (min 2.63), pandas chunks 3.08 s (min 3.00).

Decision: keep ours.  Pandas is faster only with a single-space separator and no
comments (0.06 vs 0.12 s, a 0.06 s gain on a 3 s run that reads in a background thread);
with the options our inputs need it is as fast as ours (0.13 s), it names no line (a
second pass would be needed to locate a bad field), pyarrow accepts a bad field, the
formatter has no library match (10x numpy, 25x pandas), and ``ins process`` is not faster
with pandas (its import alone costs 0.32 s).  A new runtime dependency buys nothing
measurable.

Usage: python bench/bench_textio.py [--repeat N] [--process]
(needs the bench extras: pandas, pyarrow)
"""
import argparse
import io
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from benchdata import ensure_bench_data  # noqa: E402


def best_of(fn, repeat):
    times = []
    out = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def exact_reference(path, rows=20000):
    """float() of the text of the first ``rows`` lines: the correctly rounded values."""
    ref = []
    with open(path) as f:
        for i, line in enumerate(f):
            if i >= rows:
                break
            ref.append([float(x) for x in line.split()])
    return np.array(ref)


def readers(ncols):
    import pandas as pd
    import pyarrow.csv as pacsv

    from ins.common import textfiles

    names = [f"c{i}" for i in range(ncols)]

    def ours(p):
        return textfiles.read_table(p, ncols, ncols)[0]

    def ours_stream(p):
        return np.concatenate([v for v, _ in textfiles.iter_table(p, ncols, ncols)])

    exact = {} if int(pd.__version__.split(".")[0]) >= 3 else {"float_precision": "round_trip"}

    def pandas_c(p):          # pandas >= 3: exact by default (float_precision deprecated)
        return pd.read_csv(p, sep=" ", header=None, names=names, engine="c",
                           dtype=np.float64, **exact).to_numpy()

    def pandas_chunks(p):
        with pd.read_csv(p, sep=" ", header=None, names=names, engine="c",
                         dtype=np.float64, chunksize=200_000, **exact) as it:
            return np.concatenate([c.to_numpy() for c in it])

    def arrow(p):
        t = pacsv.read_csv(p, read_options=pacsv.ReadOptions(column_names=names),
                           parse_options=pacsv.ParseOptions(delimiter=" "))
        return np.column_stack([t.column(i).to_numpy() for i in range(ncols)])

    def arrow_stream(p):
        r = pacsv.open_csv(p, read_options=pacsv.ReadOptions(column_names=names,
                                                             block_size=16 << 20),
                           parse_options=pacsv.ParseOptions(delimiter=" "))
        parts = [np.column_stack([b.column(i).to_numpy() for i in range(ncols)]) for b in r]
        return np.concatenate(parts)

    def numpy_loadtxt(p):
        return np.loadtxt(p, dtype=np.float64)

    return [("ours read_table", ours), ("ours iter_table (stream)", ours_stream),
            ("pandas C engine", pandas_c),
            ("pandas C chunks (stream)", pandas_chunks), ("pyarrow.csv", arrow),
            ("pyarrow.csv open_csv (stream)", arrow_stream), ("numpy.loadtxt", numpy_loadtxt)]


def with_bad_line(path, tmpdir):
    """A copy of ``path`` with the third field of the line at 80 % made invalid."""
    data = Path(path).read_bytes()
    lines = data.split(b"\n")
    k = int(0.8 * (len(lines) - 1))
    fields = lines[k].split(b" ")
    fields[2] = b"1.2.3"
    lines[k] = b" ".join(fields)
    out = Path(tmpdir) / ("bad_" + Path(path).name)
    out.write_bytes(b"\n".join(lines))
    return out, k + 1


def bad_line_report(fn, path, line):
    t0 = time.perf_counter()
    try:
        fn(path)
    except Exception as exc:               # noqa: BLE001 - we report whatever it raises
        dt = time.perf_counter() - t0
        text = str(exc)
        named = str(line) in text
        return dt, f"{'names line' if named else 'no line'}: {text[:70]!r}"
    return time.perf_counter() - t0, "accepted the bad field (no error)"


def bench_reads(path, ncols, repeat, tmpdir):
    ref = exact_reference(path)
    bad, bad_line = with_bad_line(path, tmpdir)
    size = os.path.getsize(path) / 1e6
    print(f"\n{path.name}: {size:.1f} MB, {ncols} columns; bad copy: line {bad_line}")
    print(f"{'reader':<32}{'time s':>8}{'MB/s':>8}  {'exact':<7} bad line")
    for name, fn in readers(ncols):
        t, values = best_of(lambda: fn(path), repeat)
        n = min(len(ref), len(values))
        exact = bool(np.array_equal(values[:n].view(np.uint64), ref[:n].view(np.uint64)))
        tb, msg = bad_line_report(fn, bad, bad_line)
        print(f"{name:<32}{t:>8.3f}{size / t:>8.0f}  {'yes' if exact else 'NO':<7} "
              f"{tb:.3f} s, {msg}")


def bench_writes(values, decimals, repeat):
    import pandas as pd

    from ins.common import textformat
    dec = np.array(decimals, dtype=np.int64)
    fmt = " ".join(f"%.{d}f" for d in decimals)
    ours = textformat.format_fixed(values, dec).tobytes()

    def numpy_savetxt():
        b = io.BytesIO()
        np.savetxt(b, values, fmt=fmt)
        return b.getvalue()

    def pandas_to_csv():
        # pandas takes one float_format for all columns: format per column first
        df = pd.DataFrame(values)
        return df.to_csv(sep=" ", header=False, index=False,
                         float_format=f"%.{max(decimals)}f").encode()

    print(f"\nwriting {values.shape[0]} x {values.shape[1]} values, decimals {decimals}")
    print(f"{'writer':<32}{'time s':>8}  same bytes as Python's % formatting")
    t, _ = best_of(lambda: textformat.format_fixed(values, dec).tobytes(), repeat)
    ref_head = "\n".join(fmt % tuple(r) for r in values[:2000]).encode()
    print(f"{'ours format_fixed':<32}{t:>8.3f}  {ours.startswith(ref_head)}")
    t, out = best_of(numpy_savetxt, repeat)
    print(f"{'numpy.savetxt':<32}{t:>8.3f}  {out.startswith(ref_head)}")
    t, out = best_of(pandas_to_csv, repeat)
    print(f"{'pandas to_csv (one format)':<32}{t:>8.3f}  (one decimals for every column)")


def _gil_work(stop):
    """Work that holds the GIL (small numpy products in a Python loop, like the filter's
    per-epoch steps): the number of iterations done until ``stop`` is set."""
    a = np.eye(3)
    b = np.full(3, 0.1)
    n = 0
    while not stop.is_set():
        for _ in range(200):
            b = a @ b + 1e-9
        n += 200
    return n


def bench_gil(path, ncols):
    """The IMU log read in a background thread beside GIL-holding work in the main thread:
    the main thread's work rate against its rate alone (1.00 = the reader never holds the
    GIL), and the reader's own time."""
    import threading
    readers_by_name = dict(readers(ncols))
    stop = threading.Event()
    t0 = time.perf_counter()
    timer = threading.Timer(1.0, stop.set)
    timer.start()
    alone = _gil_work(stop) / (time.perf_counter() - t0)
    print(f"\nreader thread beside GIL-holding work ({path.name}; main-thread rate alone "
          f"{alone / 1e3:.0f} k steps/s)")
    print(f"{'reader (background thread)':<32}{'read s':>8}  main-thread rate meanwhile")
    for name in ("ours iter_table (stream)", "pandas C chunks (stream)",
                 "pyarrow.csv open_csv (stream)", "pandas C engine"):
        fn = readers_by_name[name]
        stop = threading.Event()
        took = {}

        def run():
            t = time.perf_counter()
            fn(path)
            took["s"] = time.perf_counter() - t
            stop.set()

        th = threading.Thread(target=run)
        t0 = time.perf_counter()
        th.start()
        n = _gil_work(stop)
        rate = n / (time.perf_counter() - t0)
        th.join()
        print(f"{name:<32}{took['s']:>8.3f}  {rate / alone:.2f} of alone")


# The child runs ``ins process`` with the IMU text table read by ours or by pandas' C
# engine in chunks (ins.common.textfiles.iter_table replaced; same values, lines approximate).
_PROCESS_CHILD = """
import sys, time
import numpy as np
reader = sys.argv.pop(1)
if reader == "pandas":
    import pandas as pd
    from ins.common import textfiles
    def iter_table(path, ncols_min=1, ncols_max=1 << 30, column_names=None, hint=None,
                   block_bytes=0, skip_header_lines=0):
        line = 1
        with pd.read_csv(path, sep=" ", header=None, engine="c", dtype=np.float64,
                         chunksize=200_000) as it:
            for c in it:
                v = c.to_numpy()
                yield v, np.arange(line, line + len(v))
                line += len(v)
    textfiles.iter_table = iter_table
from ins.cli.main import main
t = time.perf_counter()
code = main(['process'] + sys.argv[1:])
sys.stderr.write(f"{time.perf_counter() - t}\\n")
sys.exit(code)
"""


def bench_process(data, repeat):
    """Whole ``ins process`` (no plots) on the shared dataset with each reader."""
    import subprocess
    cfg = ROOT / "data" / "configs" / "kfgins_like.toml"
    print("\nins process --no-plots on the shared dataset (fresh process)")
    print(f"{'IMU reader':<32}{'wall s':>8}  (median of {repeat}; min)")
    with tempfile.TemporaryDirectory() as tmp:
        for reader in ("ours", "pandas"):
            walls = []
            for _ in range(repeat + 1):
                cmd = [sys.executable, "-c", _PROCESS_CHILD, reader, "--imu",
                       str(data / "imu_noisy.txt"), "--gnss", str(data / "gnss.txt"),
                       "--config", str(cfg), "-q", "--no-plots", "-o", tmp, "--force"]
                t = time.perf_counter()
                proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
                if proc.returncode != 0:
                    print(proc.stderr[-2000:])
                    raise SystemExit("ins process failed")
                walls.append(time.perf_counter() - t)
            walls = walls[1:]                       # the first run warms the caches
            print(f"{reader:<32}{np.median(walls):>8.2f}  ({min(walls):.2f})")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--process", action="store_true",
                    help="also time whole `ins process` runs with ours and with pandas")
    args = ap.parse_args()
    data = ensure_bench_data()
    if data is None:
        print("shared benchmark dataset unavailable (../shared/bench/ins missing)")
        return 0
    from ins.common import textfiles
    textfiles.read_table(data / "gnss.txt", 7, 7)            # compile / warm the kernels
    with tempfile.TemporaryDirectory() as tmpdir:
        bench_reads(data / "imu_noisy.txt", 7, args.repeat, tmpdir)
        bench_reads(data / "gnss.txt", 7, args.repeat, tmpdir)
    nav = textfiles.read_table(data / "truth.nav", 11, 11)[0]
    bench_writes(nav[:, 1:], [3, 9, 9, 4, 4, 4, 4, 6, 6, 6], args.repeat)
    bench_gil(data / "imu_noisy.txt", 7)
    if args.process:
        bench_process(data, args.repeat)
    return 0


if __name__ == "__main__":
    sys.exit(main())
